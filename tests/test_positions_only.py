"""Positions-only evaluation: `Deformer.deform(..., normals=False)`.

The positions must be bitwise those of the full evaluation (the same float operations in the
same order, with the Jacobians of every sample but the sub-vertices, the normal patches and
the normal tessellation skipped), for both lattice kinds, several levels, smooth and sharp
meshes, vertex weights and knot-box clipping; `corner_normals` is None; `out=` buffers are
reused; bad input still raises. The Blender side (the viewport takes this path) is checked
in tests/blender/check_live.py (test_positions_only_path).
"""

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")

import smoothffd  # noqa: E402
from meshes import (cube_mesh, grid_cube, random_bspline_lattice, sphere_mesh,  # noqa: E402
                    twist_lattice)

LEVELS = (1, 2, 4, 7)


def bits(a):
    """The float32 array's bit patterns: -0.0 != 0.0 and NaN == NaN, unlike ==."""
    a = np.ascontiguousarray(a)
    assert a.dtype == np.float32
    return a.view(np.uint32)


def assert_same_positions(full, pos):
    assert pos.corner_normals is None
    assert full.corner_normals is not None
    assert pos.positions.shape == full.positions.shape and pos.positions.dtype == np.float32
    np.testing.assert_array_equal(bits(pos.positions), bits(full.positions))
    # Everything else of the Result is the plan's, the same either way.
    np.testing.assert_array_equal(pos.triangles, full.triangles)
    np.testing.assert_array_equal(pos.face_index, full.face_index)
    assert set(pos.stats["stage_ms"]) == set(full.stats["stage_ms"]) - {"tessellate_normals"}


def compare(mesh, lattice, level):
    """Full and positions-only on one Deformer (CPU) and on a fresh one; returns the full."""
    d = smoothffd.Deformer(mesh, lattice, level=level, device="cpu")
    full = d.deform()
    assert_same_positions(full, d.deform(normals=False))
    fresh = smoothffd.Deformer(mesh, lattice, level=level, device="cpu")
    assert_same_positions(full, fresh.deform(normals=False))   # nothing left by a full frame
    return full


def weighted(mesh, weights):
    return smoothffd.Mesh(mesh.positions, (mesh.corner_vertices, mesh.face_offsets),
                          corner_normals=mesh.corner_normals, uvs=mesh.uvs,
                          vertex_weights=weights)


def blender_lattice(rng, interp, shape=(4, 3, 5), amount=0.1, strength=1.0):
    """A rotated, scaled Blender lattice: knot planes oblique to the mesh."""
    import reference as ref

    rest = ref.blender_rest(shape)
    pts = rest + rng.uniform(-amount, amount, rest.shape)
    M = ref.affine(2.4 * ref.rotation([1, 2, 3], 0.7), [0.1, -0.2, 0.05])
    return smoothffd.BlenderLattice(rest, pts, (interp,) * 3, M, strength=strength)


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("degree", [1, 2, 3])
def test_bspline_lattices_smooth_sphere(degree, level):
    rng = np.random.default_rng(100 + degree)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.05] * 3, [1.05] * 3, (degree + 3,) * 3, degree, 0.1)
    full = compare(mesh, lat, level)
    assert full.stats["patches"] > 320   # knot planes clipped the triangles
    assert full.stats["sub_vertices"] > full.stats["input_vertices"]


@pytest.mark.parametrize("level", LEVELS)
@pytest.mark.parametrize("interp", ["BSPLINE", "CARDINAL", "CATMULL_ROM", "LINEAR"])
def test_blender_lattices_with_weights(interp, level):
    rng = np.random.default_rng(200 + level)
    base = sphere_mesh(2)
    mesh = weighted(base, rng.uniform(0, 1, len(base.positions)))
    full = compare(mesh, blender_lattice(rng, interp, strength=0.8), level)
    assert full.stats["patches"] > 320


@pytest.mark.parametrize("level", LEVELS)
def test_sharp_meshes(level):
    rng = np.random.default_rng(300 + level)
    lat = twist_lattice(random_bspline_lattice(rng, [-1.3] * 3, [1.3] * 3, (5, 4, 6), (2, 3, 2), 0.15), 40)
    full = compare(cube_mesh(1.0, sharp=True), lat, level)
    assert len(full.sharp_edges) > 0
    compare(cube_mesh(1.0, sharp=False), lat, level)
    compare(grid_cube(3), lat, level)


def test_mixed_degrees_weights_and_polygons():
    rng = np.random.default_rng(4)
    base = grid_cube(4)
    mesh = weighted(base, rng.uniform(0.0, 1.0, len(base.positions)))
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (6, 5, 7), (1, 2, 3), 0.2)
    for level in LEVELS:
        compare(mesh, lat, level)


def test_degenerate_and_non_manifold_mesh():
    """Zero-area triangles, a non-manifold fin (its edges are left as fitted), zero normals,
    reversed winding, a concave polygon: still bitwise."""
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [1e-9, 0.5, 0],
                  [0.5, 0.5, 1], [0.3, 0.2, 0.0], [0.5, 0.5, -1]], float)
    polys = [[0, 1, 3], [1, 2, 4], [0, 1, 2], [0, 5, 3], [1, 4, 3], [1, 3, 6], [3, 1, 8],
             [0, 0, 1], [4, 2, 1], [0, 1, 4, 7, 3]]
    cv = np.concatenate(polys)
    fo = np.concatenate([[0], np.cumsum([len(p) for p in polys])])
    normals = np.zeros((len(cv), 3))
    normals[::2] = [0, 0, 1]
    mesh = smoothffd.Mesh(V, (cv, fo), corner_normals=normals)
    rng = np.random.default_rng(5)
    lat = random_bspline_lattice(rng, [-0.5] * 3, [2.5] * 3, (5, 5, 5), 2, 0.2)
    for level in (1, 3, 5):
        compare(mesh, lat, level)


def test_many_frames_threads_and_one_shot():
    """Frame after frame on one Deformer (buffers of other frames left behind), with 1 and 3
    threads, and the one-shot smoothffd.deform(normals=False)."""
    rng = np.random.default_rng(6)
    mesh = sphere_mesh(3)
    lat = random_bspline_lattice(rng, [-1.1] * 3, [1.1] * 3, (5, 5, 5), 2, 0.05)
    one = smoothffd.Deformer(mesh, lat, level=5, device="cpu", threads=1)
    many = smoothffd.Deformer(mesh, lat, level=5, device="cpu", threads=3)
    for frame in range(4):
        cp = lat.control_points + rng.uniform(-0.08, 0.08, lat.control_points.shape)
        full = one.deform(cp)
        assert_same_positions(full, one.deform(cp, normals=False))
        assert_same_positions(full, many.deform(cp, normals=False))
        if frame % 2:
            many.deform(lat.control_points)   # another frame in between
    full = smoothffd.deform(mesh, lat, level=3, device="cpu")
    assert_same_positions(full, smoothffd.deform(mesh, lat, level=3, device="cpu", normals=False))


def test_out_reuse():
    rng = np.random.default_rng(7)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (4, 4, 4), 2, 0.1)
    d = smoothffd.Deformer(mesh, lat, level=4, device="cpu")
    first = d.deform()
    cp2 = lat.control_points + 0.05
    # Positions-only into a full Result: its positions are overwritten, its normals kept.
    normals_before = first.corner_normals.copy()
    pos = d.deform(cp2, out=first, normals=False)
    assert pos.positions is first.positions and pos.corner_normals is None
    np.testing.assert_array_equal(first.corner_normals, normals_before)
    fresh = smoothffd.deform(mesh, lat.with_control_points(cp2), level=4, device="cpu")
    assert_same_positions(fresh, pos)
    # Positions-only into a positions-only Result.
    cp3 = lat.control_points - 0.03
    again = d.deform(cp3, out=pos, normals=False)
    assert again.positions is first.positions and again.corner_normals is None
    fresh3 = smoothffd.deform(mesh, lat.with_control_points(cp3), level=4, device="cpu")
    assert_same_positions(fresh3, again)
    # Full into a positions-only Result: positions reused, normals allocated, then reused.
    full = d.deform(cp2, out=again)
    assert full.positions is first.positions
    assert full.corner_normals is not None and full.corner_normals is not first.corner_normals
    np.testing.assert_array_equal(bits(full.positions), bits(fresh.positions))
    np.testing.assert_array_equal(bits(full.corner_normals), bits(fresh.corner_normals))
    full2 = d.deform(cp3, out=full)
    assert full2.positions is first.positions and full2.corner_normals is full.corner_normals
    # Another plan (new lattice structure): out's arrays have the wrong shape, fresh ones.
    other = smoothffd.BSplineLattice.identity([-1.2] * 3, [1.2] * 3, shape=(6, 6, 6))
    replanned = d.deform(other, out=full2, normals=False)
    assert replanned.positions is not first.positions and replanned.corner_normals is None
    assert_same_positions(smoothffd.deform(mesh, other, level=4, device="cpu"), replanned)


def test_bad_input_still_raises():
    rng = np.random.default_rng(8)
    mesh = sphere_mesh(1)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (4, 4, 4), 2, 0.1)
    d = smoothffd.Deformer(mesh, lat, level=2, device="cpu")
    with pytest.raises(ValueError, match="control_points"):
        d.deform(np.zeros((3, 3, 3, 3)), normals=False)
    with pytest.raises(ValueError, match="control_points"):
        d.deform(np.full((4, 4, 4, 3), np.nan), normals=False)
    with pytest.raises(ValueError, match="float32 range"):
        d.deform(np.full((4, 4, 4, 3), 1e38), normals=False)
    with pytest.raises(TypeError, match="out"):
        d.deform(out=np.zeros(3), normals=False)
    # An out Result whose positions have the right shape but are unusable.
    res = d.deform(normals=False)
    bad = smoothffd.Result(**{**res.__dict__, "positions": res.positions.astype(np.float64)})
    with pytest.raises(ValueError, match="out: positions"):
        d.deform(out=bad, normals=False)
    ro = res.positions.copy()
    ro.setflags(write=False)
    with pytest.raises(ValueError, match="out: positions"):
        d.deform(out=smoothffd.Result(**{**res.__dict__, "positions": ro}), normals=False)
    # The binding itself validates like evaluate.
    ev = d._evaluator
    with pytest.raises(ValueError, match="control values"):
        ev.evaluate_positions(np.zeros((5, 3), np.float32))
    with pytest.raises(ValueError, match="control values"):
        ev.evaluate_positions(np.zeros((64, 2), np.float32))
    with pytest.raises(ValueError, match="out: positions"):
        ev.evaluate_positions(np.zeros((64, 3), np.float32), positions=np.zeros((2, 3), np.float32))
    # And the Deformer still works afterwards.
    assert_same_positions(d.deform(), d.deform(normals=False))


def test_consumers_of_a_positions_only_result(tmp_path):
    """metrics.reference_errors needs normals: a clear error; the OBJ writer writes no vn."""
    from smoothffd import io as objio
    from smoothffd import metrics

    rng = np.random.default_rng(9)
    mesh = cube_mesh(1.0)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (4, 4, 4), 2, 0.1)
    res = smoothffd.deform(mesh, lat, level=3, device="cpu", normals=False)
    with pytest.raises(ValueError, match="normals=False"):
        metrics.reference_errors(res, lat)
    path = tmp_path / "pos.obj"
    objio.write_result(path, res)
    text = path.read_text()
    assert "\nvn " not in text and "\nv " in text
    back = objio.read_obj(path)
    assert back.corner_normals is None
    np.testing.assert_array_equal(back.positions.astype(np.float32), res.positions)


@pytest.mark.skipif(not smoothffd.cuda_status()[0], reason="no usable CUDA device")
def test_cuda_positions_only_drops_normals():
    rng = np.random.default_rng(10)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (5, 5, 5), 2, 0.1)
    d = smoothffd.Deformer(mesh, lat, level=4, device="cuda")
    full = d.deform()
    pos = d.deform(normals=False, out=full)
    assert pos.corner_normals is None and pos.positions is full.positions
    # The device computes the same frame: the same positions.
    np.testing.assert_array_equal(bits(pos.positions), bits(d.deform().positions))
