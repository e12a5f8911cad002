"""The compact output layout (`deform(..., layout="compact")`): positions per welded output
vertex, normals once per render vertex (an output vertex duplicated where normals split).

The reference is the per-corner layout, computed by the other code path (each patch writes its
own normal to every corner of its triangles): positions must be bitwise the same, and every
corner's normal equal to its render vertex's normal, exactly where the corner's patch is the
render vertex's owner and within the plan's one normal class (well under a degree) elsewhere.
The CUDA half runs where a GPU is (e.g. an H100)."""

import numpy as np
import pytest

import agreement
import meshes
import smoothffd
from smoothffd import _core

SIZE = 2.0  # lattice size of the cases below


def angles(a, b):
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def cases():
    """(name, mesh, lattice, level): a smooth sphere clipped by a bent B-spline lattice, a
    sharp cube (every edge split), and a Blender lattice (cubic axes)."""
    rng = np.random.default_rng(7)
    out = []
    sph = meshes.sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-1, -1, -1], [1, 1, 1], shape=(4, 4, 4), degree=(2, 2, 2))
    lat = lat.with_points(lat.control_points + rng.normal(0, 0.06, lat.control_points.shape))
    out.append(("sphere-bspline", sph, lat, 5))
    cube = meshes.grid_cube(2, size=0.8)
    lat2 = smoothffd.BSplineLattice.identity([-1, -1, -1], [1, 1, 1], shape=(3, 3, 3), degree=(1, 1, 1))
    lat2 = lat2.with_points(lat2.control_points + rng.normal(0, 0.05, lat2.control_points.shape))
    out.append(("cube-sharp", cube, lat2, 4))
    g = np.linspace(-1.0, 1.0, 3)
    rest = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1)  # lattice space = object space
    bl = smoothffd.BlenderLattice(rest, rest + rng.normal(0, 0.05, rest.shape), "BSPLINE")
    out.append(("sphere-blender", sph, bl, 3))
    return out


def check_against_corners(compact, corners, plan, level):
    np.testing.assert_array_equal(compact.positions, corners.positions)
    rtri = compact.render_triangles
    assert compact.normals.shape == (plan.render_vertex_count, 3)
    assert compact.normals.dtype == np.float32
    np.testing.assert_allclose(np.linalg.norm(compact.normals, axis=1), 1.0, atol=2e-6)
    np.testing.assert_array_equal(compact.render_vertex[rtri], compact.triangles)
    gathered = compact.corner_normals()
    assert gathered.shape == corners.corner_normals.shape
    # Corners whose patch owns their render vertex: the same arithmetic, bitwise.
    owner = plan.render_owner()[:, 0]
    patch_of_triangle = np.arange(plan.output_triangles) // (level * level)
    own = owner[rtri] == patch_of_triangle[:, None]
    assert own.any()
    np.testing.assert_array_equal(gathered[own], corners.corner_normals[own])
    # Other corners: the same normal class (plan's sharp angle, 1 degree), in practice far closer.
    ang = angles(gathered, corners.corner_normals).max()
    assert ang <= np.radians(1.0), f"corner normals differ from their render vertex by {ang:.2e} rad"


@pytest.mark.parametrize("name,mesh,lat,level", cases(), ids=[c[0] for c in cases()])
def test_cpu_compact_matches_corners(name, mesh, lat, level):
    d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    corners = d.deform()
    compact = d.deform(layout="compact")
    assert isinstance(compact, smoothffd.CompactResult)
    check_against_corners(compact, corners, d.plan, level)
    if name == "cube-sharp":
        assert d.plan.render_vertex_count > d.plan.output_vertices  # splits were exercised
    for a in ("render_vertex", "render_triangles", "triangles", "face_index"):
        assert not getattr(compact, a).flags.writeable, f"{a}: static topology must be read-only"
    np.testing.assert_array_equal(compact.face_index, corners.face_index)
    assert compact.stats["layout"] == "compact" and corners.stats["layout"] == "corners"


def test_compact_out_reuse_and_positions_only():
    name, mesh, lat, level = cases()[0]
    d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    first = d.deform(layout="compact")
    moved = lat.with_points(lat.control_points * 1.1)
    again = d.deform(moved, out=first, layout="compact")
    assert again.positions is first.positions and again.normals is first.normals
    fresh = smoothffd.Deformer(mesh, moved, level=level, device="cpu").deform(layout="compact")
    np.testing.assert_array_equal(again.positions, fresh.positions)
    np.testing.assert_array_equal(again.normals, fresh.normals)
    # The topology is shared, not copied, from frame to frame.
    assert again.render_triangles is fresh.render_triangles or np.array_equal(again.render_triangles,
                                                                               fresh.render_triangles)
    pos_only = d.deform(layout="compact", normals=False)
    assert pos_only.normals is None and pos_only.corner_normals() is None
    np.testing.assert_array_equal(pos_only.positions, fresh.positions)


def test_compact_bad_arguments():
    name, mesh, lat, level = cases()[0]
    d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    with pytest.raises(ValueError, match="layout"):
        d.deform(layout="per-vertex")
    corners = d.deform()
    with pytest.raises(TypeError, match="CompactResult"):
        d.deform(out=corners, layout="compact")
    compact = d.deform(layout="compact")
    with pytest.raises(TypeError, match="Result"):
        d.deform(out=compact)
    compact.normals = compact.positions[: compact.normals.shape[0]]
    if compact.normals.shape == (d.plan.render_vertex_count, 3):
        with pytest.raises(ValueError, match="share memory"):
            d.deform(out=compact, layout="compact")
    with pytest.raises(ValueError, match="normals"):
        _core.CpuEvaluator(d.plan).evaluate_compact(
            np.zeros((lat.control_points.size // 3, 3), np.float32),
            normals=np.zeros((3, 3), np.float32))


def test_one_shot_deform_compact():
    name, mesh, lat, level = cases()[1]
    r = smoothffd.deform(mesh, lat, level=level, device="cpu", layout="compact")
    assert r.normals.shape[0] == r.render_vertex.shape[0] > r.positions.shape[0]


_USABLE, _WHY = smoothffd.cuda_status()


@pytest.mark.skipif(not _USABLE, reason=f"no usable CUDA device: {_WHY}")
@pytest.mark.parametrize("name,mesh,lat,level", cases(), ids=[c[0] for c in cases()])
def test_cuda_compact_matches_corners_and_cpu(name, mesh, lat, level):
    d = smoothffd.Deformer(mesh, lat, level=level, device="cuda")
    corners = d.deform()
    compact = d.deform(layout="compact")
    # The CUDA per-corner normals are gathered from the same compact device output: exact.
    np.testing.assert_array_equal(compact.positions, corners.positions)
    np.testing.assert_array_equal(compact.corner_normals(), corners.corner_normals)
    cpu = smoothffd.Deformer(mesh, lat, level=level, device="cpu").deform(layout="compact")
    assert agreement.positions(compact.positions, cpu.positions, SIZE) <= agreement.POSITIONS
    assert agreement.normals(compact.normals, cpu.normals) <= agreement.NORMALS


@pytest.mark.skipif(not _USABLE, reason=f"no usable CUDA device: {_WHY}")
def test_cuda_compact_large_output_in_chunks():
    """Many 1 MiB staging chunks, into fresh and into reused (pageable) arrays."""
    mesh = meshes.sphere_mesh(4)
    lat = smoothffd.BSplineLattice.identity([-1, -1, -1], [1, 1, 1], shape=(4, 4, 4), degree=(2, 2, 2))
    lat = lat.with_points(lat.control_points * 1.05)
    d = smoothffd.Deformer(mesh, lat, level=16, device="cuda")
    plan = d.plan
    assert 12 * (plan.output_vertices + plan.render_vertex_count) > 5 * (1 << 20)
    corners = d.deform()
    first = d.deform(layout="compact")
    first.positions[:] = np.nan
    first.normals[:] = np.nan
    again = d.deform(out=first, layout="compact")
    np.testing.assert_array_equal(again.positions, corners.positions)
    np.testing.assert_array_equal(again.corner_normals(), corners.corner_normals)


def test_compact_result_writes_the_same_obj(tmp_path):
    from smoothffd import io

    name, mesh, lat, level = cases()[1]
    d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    io.write_result(tmp_path / "corners.obj", d.deform())
    io.write_result(tmp_path / "compact.obj", d.deform(layout="compact"))
    a = io.read_obj(tmp_path / "corners.obj")
    b = io.read_obj(tmp_path / "compact.obj")
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.corner_vertices, b.corner_vertices)
    assert len(b.positions) == d.plan.output_vertices
    # Normals: the two layouts agree within the normal class (exactly at owned corners).
    assert angles(a.corner_normals, b.corner_normals).max() <= np.radians(1.0)
