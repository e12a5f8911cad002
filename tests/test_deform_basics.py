"""API shape, identity, planarity, plan reuse, similarity invariance, determinism."""

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")

import reference as ref  # noqa: E402
import smoothffd  # noqa: E402
from meshes import cube_mesh, edge_counts, random_bspline_lattice, sphere_mesh, twist_lattice  # noqa: E402


def test_result_layout_and_counts():
    mesh = sphere_mesh(1)  # 80 faces, 42 vertices, 120 edges
    lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3, shape=(3, 3, 3))
    for L in (1, 2, 5):
        r = smoothffd.deform(mesh, lat, level=L)
        V, E, F = 42, 120, 80
        assert r.positions.shape == (V + E * (L - 1) + F * (L - 1) * (L - 2) // 2, 3)
        assert r.triangles.shape == (F * L * L, 3)
        assert r.corner_normals.shape == (F * L * L, 3, 3)
        assert r.positions.dtype == np.float32 and r.triangles.dtype == np.int32
        assert r.uvs is None and r.face_index.shape == (F * L * L,)
        np.testing.assert_allclose(np.linalg.norm(r.corner_normals, axis=2), 1.0, atol=1e-6)
        assert np.bincount(r.face_index).tolist() == [L * L] * F


def test_identity_keeps_vertices_and_plane_normals():
    rng = np.random.default_rng(1)
    # A planar, irregular polygon mesh in z = 0.3 with plane normals, crossing knot planes.
    pts = np.c_[rng.uniform(-1, 1, (30, 2)), np.full(30, 0.3)]
    from scipy_free_delaunay import delaunay  # local helper below
    tris = delaunay(pts[:, :2])
    normals = np.tile([0.0, 0.0, 1.0], (tris.size, 1))
    mesh = smoothffd.Mesh(pts, tris, corner_normals=normals)
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(6, 5, 4), degree=(2, 3, 1))
    r = smoothffd.deform(mesh, lat, level=6)
    assert r.stats["patches"] > len(tris)  # the knot planes clipped the triangles
    np.testing.assert_allclose(r.positions[:30], pts, atol=2e-7)
    np.testing.assert_allclose(r.positions[:, 2], 0.3, atol=1e-6)
    np.testing.assert_allclose(r.corner_normals.reshape(-1, 3), np.tile([0, 0, 1.0], (r.corner_normals.size // 3, 1)), atol=1e-6)


def test_input_vertices_follow_the_lattice_exactly():
    rng = np.random.default_rng(2)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (5, 4, 6), (2, 2, 3), 0.15)
    r = smoothffd.deform(mesh, lat, level=4)
    exact = ref.BSplineReference(lat.control_points, lat.degree, lat.knots, lat.box_min,
                                 lat.box_max)(mesh.positions.astype(np.float64))
    # Measured 5.8e-8: the float32 rounding of coordinates up to 1.01; bound two float32 steps.
    np.testing.assert_allclose(r.positions[:len(mesh.positions)], exact, rtol=0, atol=2.4e-7)


def test_deformer_reuses_plan_and_replans_on_structure_change():
    rng = np.random.default_rng(3)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (4, 4, 4), 2, 0.1)
    d = smoothffd.Deformer(mesh, lat, level=3, device="cpu")
    plan = d.plan
    lat2 = lat.with_control_points(lat.control_points + rng.uniform(-0.1, 0.1, lat.control_points.shape))
    r_points = d.deform(lat2.control_points)
    assert d.plan is plan
    fresh = smoothffd.deform(mesh, lat2, level=3, device="cpu")
    np.testing.assert_array_equal(r_points.positions, fresh.positions)
    np.testing.assert_array_equal(r_points.corner_normals, fresh.corner_normals)
    other = smoothffd.BSplineLattice.identity([-1.2] * 3, [1.2] * 3, shape=(5, 5, 5))
    r_other = d.deform(other)
    assert d.plan is not plan
    np.testing.assert_allclose(r_other.positions[:len(mesh.positions)], mesh.positions, atol=1e-6)


def test_similarity_invariance():
    """Rotating, scaling and translating mesh and lattice together transforms the result."""
    rng = np.random.default_rng(4)
    base_mesh = sphere_mesh(2)
    mesh = smoothffd.Mesh(0.8 * base_mesh.positions, (base_mesh.corner_vertices, base_mesh.face_offsets),
                          corner_normals=base_mesh.corner_normals)
    # One knot box per axis: no clipping, so both runs share the same sub-triangles and
    # numbering (clipping itself is covered by the watertightness test).
    lat = random_bspline_lattice(rng, [-1] * 3, [1] * 3, (3, 4, 3), (2, 3, 2), 0.2)
    base = smoothffd.deform(mesh, lat, level=5)
    # Boxes stay axis-aligned under a signed axis permutation, a scale and a translation.
    R = np.array([[0, -1, 0], [0, 0, 1], [-1, 0, 0]], float)
    s, t = 2.5, np.array([3.0, -1.0, 0.5])
    f = lambda x: s * np.asarray(x) @ R.T + t  # noqa: E731
    m2 = smoothffd.Mesh(f(mesh.positions), (mesh.corner_vertices, mesh.face_offsets),
                        corner_normals=mesh.corner_normals @ R.T)
    # New axis b is old axis a = perm[b], flipped where R's entry is negative.
    perm = [int(np.argmax(np.abs(R[b]))) for b in range(3)]
    cp = f(lat.control_points.reshape(-1, 3)).reshape(lat.control_points.shape)
    cp = np.transpose(cp, perm + [3])
    for b in range(3):
        if R[b, perm[b]] < 0:
            cp = np.flip(cp, axis=b)
    ends = np.sort(np.stack([f([-1, -1, -1]), f([1, 1, 1])]), axis=0)
    lat2 = smoothffd.BSplineLattice(cp, degree=[lat.degree[a] for a in perm], box_min=ends[0], box_max=ends[1])
    moved = smoothffd.deform(m2, lat2, level=5)
    assert moved.triangles.shape == base.triangles.shape
    # Same topology; match output vertices through their rest points.
    np.testing.assert_allclose(moved.rest_positions, f(base.rest_positions), atol=1e-5 * s)
    np.testing.assert_array_equal(moved.triangles, base.triangles)
    np.testing.assert_allclose(moved.positions, f(base.positions), atol=1e-5 * s)
    np.testing.assert_allclose(moved.corner_normals, base.corner_normals @ R.T, atol=1e-4)


def test_threads_give_bitwise_identical_results():
    rng = np.random.default_rng(5)
    mesh = sphere_mesh(3)
    lat = twist_lattice(random_bspline_lattice(rng, [-1.1] * 3, [1.1] * 3, (5, 5, 5), 2, 0.05), 60)
    one = smoothffd.Deformer(mesh, lat, level=6, device="cpu", threads=1).deform()
    many = smoothffd.Deformer(mesh, lat, level=6, device="cpu", threads=7).deform()
    np.testing.assert_array_equal(one.positions, many.positions)
    np.testing.assert_array_equal(one.corner_normals, many.corner_normals)


def test_watertight_at_every_level_with_clipping():
    rng = np.random.default_rng(6)
    mesh = sphere_mesh(2)
    for shape, degree in [((3, 3, 3), 1), ((6, 5, 7), 2), ((7, 7, 7), 3)]:
        lat = random_bspline_lattice(rng, [-1.05] * 3, [1.05] * 3, shape, degree, 0.08)
        for L in range(1, 7):
            r = smoothffd.deform(mesh, lat, level=L)
            assert r.stats["patches"] > 320
            counts = edge_counts(r.triangles)
            assert np.all(counts == 2), (shape, L)
            # Euler characteristic of a sphere, and every vertex used.
            V = len(r.positions)
            assert V - len(counts) + len(r.triangles) == 2
            assert len(np.unique(r.triangles)) == V


@pytest.mark.parametrize("interp", ["BSPLINE", "CARDINAL", "CATMULL_ROM", "LINEAR"])
def test_blender_lattice_rotated_watertight_and_exact_at_vertices(interp):
    """A rotated, scaled Blender lattice (knot planes oblique to the mesh), with strength and
    per-vertex weights: input vertices land exactly where the lattice formula puts them and the
    clipped result stays watertight at every level."""
    import reference as ref

    rng = np.random.default_rng(8)
    mesh0 = sphere_mesh(2)
    w = rng.uniform(0, 1, len(mesh0.positions))
    mesh = smoothffd.Mesh(mesh0.positions, (mesh0.corner_vertices, mesh0.face_offsets),
                          corner_normals=mesh0.corner_normals, vertex_weights=w)
    shape = (4, 3, 5)
    rest = ref.blender_rest(shape)
    pts = rest + rng.uniform(-0.08, 0.08, rest.shape)
    M = ref.affine(2.4 * ref.rotation([1, 2, 3], 0.7), [0.1, -0.2, 0.05])
    lat = smoothffd.BlenderLattice(rest, pts, (interp,) * 3, M, strength=0.8)
    exact = ref.blender_lattice_reference(rest, pts, interp, M, 0.8, mesh0.positions)
    expected = mesh0.positions + w[:, None] * (exact - mesh0.positions)
    for L in (1, 3, 6):
        r = smoothffd.deform(mesh, lat, level=L)
        assert r.stats["patches"] > 320
        np.testing.assert_allclose(r.positions[:len(w)], expected, atol=1e-5 * 2.4)
        assert np.all(edge_counts(r.triangles) == 2)
        assert np.all(np.isfinite(r.corner_normals))


def test_float32_vertices_near_knot_planes_make_no_slivers():
    """A float32 UV sphere in a centred lattice: meridian vertices lie within float32 noise of
    the x = 0 and y = 0 knot planes. They count as on the planes: no zero-area triangles, no
    duplicate output positions (Blender 3.4 would split its smooth shading at them)."""
    import reference as ref
    from meshes import uv_sphere

    V, F = uv_sphere()
    rest = ref.blender_rest((3, 3, 3), -1.01, 1.01)
    pts = rest + 0.05 * np.random.default_rng(9).normal(size=rest.shape)
    for L in (1, 3):
        r = smoothffd.deform(smoothffd.Mesh(V, F), smoothffd.BlenderLattice(rest, pts), level=L)
        P = r.positions[r.triangles]
        area = np.linalg.norm(np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), axis=1) / 2
        assert area.min() > 1e-5
        assert len(np.unique(np.round(r.positions, 6), axis=0)) == len(r.positions)
        assert np.all(edge_counts(r.triangles) == 2)


def test_out_reuses_the_previous_result():
    rng = np.random.default_rng(10)
    mesh = sphere_mesh(2)
    lat = random_bspline_lattice(rng, [-1.2] * 3, [1.2] * 3, (4, 4, 4), 2, 0.1)
    d = smoothffd.Deformer(mesh, lat, level=4, device="cpu")
    first = d.deform()
    lat2 = lat.with_control_points(lat.control_points + 0.05)
    again = d.deform(lat2.control_points, out=first)
    assert again.positions is first.positions and again.corner_normals is first.corner_normals
    fresh = smoothffd.deform(mesh, lat2, level=4, device="cpu")
    np.testing.assert_array_equal(again.positions, fresh.positions)
    np.testing.assert_array_equal(again.corner_normals, fresh.corner_normals)
    with pytest.raises(TypeError, match="out"):
        d.deform(out=np.zeros(3))


def test_core_limits_and_names_are_the_packages():
    """The maximum level and the device names are the core's (smoothffd._core), and every
    layer takes the same: the package, the Deformer, build_plan."""
    from smoothffd import _core
    assert smoothffd.MAX_LEVEL == _core.MAX_LEVEL == 64
    assert smoothffd.DEVICES == _core.DEVICES == ("auto", "cpu", "cuda")
    tri = smoothffd.Mesh(np.array([[0, 0, 0], [0.5, 0, 0], [0, 0.5, 0.0]]), np.array([[0, 1, 2]]))
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(2, 2, 2), degree=(1, 1, 1))
    top = smoothffd.Deformer(tri, lat, level=smoothffd.MAX_LEVEL, device="cpu")
    assert top.deform().triangles.shape == (smoothffd.MAX_LEVEL ** 2, 3)
    with pytest.raises(ValueError, match="level"):
        smoothffd.Deformer(tri, lat, level=smoothffd.MAX_LEVEL + 1, device="cpu")
    with pytest.raises(ValueError, match="device"):
        smoothffd.Deformer(tri, lat, level=2, device="gpu")
