"""Every kind of bad input raises a clear error naming the argument, or works without NaN."""

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")

import smoothffd  # noqa: E402
from meshes import sphere_mesh  # noqa: E402

TRI_V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.2]], float)
TRI_F = np.array([[0, 1, 2], [1, 3, 2]])
LAT = smoothffd.BSplineLattice.identity([-1] * 3, [2] * 3, shape=(4, 4, 4))

MESH_CASES = [
    ("positions", dict(positions=np.zeros((4, 2))), ValueError),
    ("positions", dict(positions=np.array([[0, 0, np.nan]] * 4)), ValueError),
    ("positions", dict(positions="abc"), TypeError),
    ("faces", dict(faces=np.array([[0, 1, 7]])), ValueError),
    ("faces", dict(faces=np.array([[0, -1, 2]])), ValueError),
    ("faces", dict(faces=np.array([[0, 1]])), ValueError),
    ("faces", dict(faces=np.array([[0.5, 1, 2]])), ValueError),
    ("faces", dict(faces=np.zeros((0, 3), int)), ValueError),
    ("faces", dict(faces=(np.array([0, 1, 2, 3]), np.array([0, 2, 4]))), ValueError),
    ("face_offsets", dict(faces=(np.array([0, 1, 2]), np.array([1, 3]))), ValueError),
    ("corner_normals", dict(corner_normals=np.zeros((5, 3))), ValueError),
    ("corner_normals", dict(corner_normals=np.full((6, 3), np.inf)), ValueError),
    ("uvs", dict(uvs=np.zeros((6, 3))), ValueError),
    ("vertex_weights", dict(vertex_weights=np.ones(3)), ValueError),
]


@pytest.mark.parametrize("name,kwargs,exc", MESH_CASES)
def test_mesh_rejects(name, kwargs, exc):
    args = dict(positions=TRI_V, faces=TRI_F)
    args.update(kwargs)
    with pytest.raises(exc, match=name.split("[")[0].split(" ")[0]):
        smoothffd.Mesh(**args)


@pytest.mark.parametrize("kwargs,exc,word", [
    (dict(level=0), ValueError, "level"),
    (dict(level=1000), ValueError, "level"),
    (dict(level=2.5), TypeError, "level"),
    (dict(device="tpu"), ValueError, "device"),
    (dict(device="cuda"), RuntimeError, "cuda"),
])
def test_deformer_rejects(kwargs, exc, word):
    if kwargs.get("device") == "cuda" and smoothffd.cuda_status()[0]:
        pytest.skip("a usable CUDA device exists, so device='cuda' is valid here")
    with pytest.raises(exc, match=word):
        smoothffd.Deformer(smoothffd.Mesh(TRI_V, TRI_F), LAT, **kwargs)


def test_deformer_rejects_wrong_types_and_points():
    m = smoothffd.Mesh(TRI_V, TRI_F)
    with pytest.raises(TypeError, match="mesh"):
        smoothffd.Deformer(TRI_V, LAT)
    with pytest.raises(TypeError, match="lattice"):
        smoothffd.Deformer(m, np.zeros((4, 4, 4, 3)))
    d = smoothffd.Deformer(m, LAT, level=2)
    with pytest.raises(ValueError, match="control_points"):
        d.deform(np.zeros((3, 3, 3, 3)))
    with pytest.raises(ValueError, match="control_points"):
        d.deform(np.full((4, 4, 4, 3), np.nan))
    # A rejected call leaves the Deformer's lattice as it was (points beyond the float32 range
    # used to stay, and every later deform() raised).
    with pytest.raises(ValueError, match="float32"):
        d.deform(np.full((4, 4, 4, 3), 1e38))
    assert np.array_equal(d.deform().positions, smoothffd.deform(m, LAT, level=2).positions)


def test_degenerate_geometry_gives_no_nan():
    """Zero-area and sliver triangles, repeated vertices, zero normals, a non-manifold fin,
    inconsistent winding and a concave polygon: all deform without NaN."""
    V = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [1, 1, 0], [1e-9, 0.5, 0],
                  [0.5, 0.5, 1], [0.3, 0.2, 0.0], [0.5, 0.5, -1]], float)
    polys = [[0, 1, 3], [1, 2, 4], [0, 1, 2],          # a zero-area triangle (collinear)
             [0, 5, 3], [1, 4, 3], [1, 3, 6], [3, 1, 8],  # fin: edge 1-3 has 3+ faces
             [0, 0, 1], [4, 2, 1],                     # repeated vertex; reversed winding
             [0, 1, 4, 7, 3]]                           # concave pentagon
    cv = np.concatenate(polys)
    fo = np.concatenate([[0], np.cumsum([len(p) for p in polys])])
    normals = np.zeros((len(cv), 3))
    normals[::2] = [0, 0, 1]  # half the corners have zero normals
    mesh = smoothffd.Mesh(V, (cv, fo), corner_normals=normals)
    rng = np.random.default_rng(0)
    lat = smoothffd.BSplineLattice.identity([-0.5] * 3, [2.5] * 3, shape=(5, 5, 5))
    lat = lat.with_control_points(lat.control_points + rng.uniform(-0.2, 0.2, lat.control_points.shape))
    for L in (1, 3, 7):
        r = smoothffd.deform(mesh, lat, level=L)
        assert np.all(np.isfinite(r.positions)) and np.all(np.isfinite(r.corner_normals))
        np.testing.assert_allclose(np.linalg.norm(r.corner_normals, axis=2), 1, atol=1e-5)
        assert set(np.unique(r.face_index)) <= set(range(len(polys)))


def test_concave_polygon_triangulation_stays_inside():
    """An L-shaped hexagon: every triangle is inside the polygon (positive area, same normal)."""
    V = np.array([[0, 0, 0], [2, 0, 0], [2, 1, 0], [1, 1, 0], [1, 2, 0], [0, 2, 0]], float)
    mesh = smoothffd.Mesh(V, (np.arange(6), np.array([0, 6])))
    r = smoothffd.deform(mesh, smoothffd.BSplineLattice.identity([-1] * 3, [3] * 3, (3, 3, 3)), level=1)
    P = r.positions[r.triangles]
    z = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])[:, 2]
    assert len(r.triangles) == 4 and np.all(z > 0)
    assert np.isclose(z.sum() / 2, 3.0)


def test_lattice_far_from_mesh_and_huge_values():
    mesh = sphere_mesh(1)
    lat = smoothffd.BSplineLattice.identity([10] * 3, [11] * 3, shape=(3, 3, 3))
    lat = lat.with_control_points(lat.control_points * 1.5)
    r = smoothffd.deform(mesh, lat, level=3)  # everything outside the box: a translation
    assert np.all(np.isfinite(r.positions))
    shift = r.positions[:42] - mesh.positions
    np.testing.assert_allclose(shift, np.broadcast_to(shift[0], shift.shape), atol=1e-4)


@pytest.mark.parametrize("bad", ["degree", "knots", "counts"])
def test_private_module_refuses_short_per_axis_lists(bad):
    """The add-on calls _core directly: one value where three (one an axis) are needed was a
    segfault; it is a ValueError naming the argument."""
    from smoothffd import _core
    args = {"degree": [2, 2, 2], "knots": [np.arange(6.0)] * 3, "counts": [3, 3, 3]}
    args[bad] = args[bad][:1]
    with pytest.raises(ValueError, match=rf"{bad}: expected 3 values \(one per axis\), got 1"):
        _core.LatticeSpec.bspline(args["degree"], args["knots"], args["counts"], np.eye(3, 4))
    with pytest.raises(ValueError, match=r"interpolation: expected 3 values"):
        _core.LatticeSpec.blender(["BSPLINE"], [3, 3, 3], np.eye(3, 4))


def _tri_mesh(**kw):
    return smoothffd.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]], **kw)


def _box():
    return smoothffd.BSplineLattice.identity([-0.1, -0.1, -0.1], [1.1, 1.1, 0.1], shape=(3, 3, 3),
                                             degree=(2, 2, 2))


@pytest.mark.parametrize("positions", [
    np.zeros((3, 3), dtype=complex), np.zeros((3, 3), dtype=bool),
    np.zeros((3, 3), dtype="datetime64[s]"), np.zeros((3, 3), dtype="timedelta64[s]"),
    [["0", "0", "0"], ["1", "0", "0"], ["0", "1", "0"]]])
def test_positions_of_other_kinds_are_refused(positions):
    with pytest.raises(TypeError, match="positions: expected real numbers"):
        smoothffd.Mesh(positions, [[0, 1, 2]])


@pytest.mark.parametrize("level", [True, False, np.bool_(True)])
def test_level_must_not_be_a_bool(level):
    with pytest.raises(TypeError, match="level: expected an integer"):
        smoothffd.Deformer(_tri_mesh(), _box(), level=level)


@pytest.mark.parametrize("normals", ["no", 0, 1, None])
def test_normals_flag_must_be_a_bool(normals):
    d = smoothffd.Deformer(_tri_mesh(), _box(), level=2, device="cpu")
    with pytest.raises(TypeError, match="normals: expected True or False"):
        d.deform(normals=normals)


@pytest.mark.parametrize("w", [[0.5, 1.5, 0.0], [-0.1, 0.5, 0.5]])
def test_vertex_weights_outside_0_1(w):
    with pytest.raises(ValueError, match=r"vertex_weights: must lie in \[0, 1\]"):
        _tri_mesh(vertex_weights=w)


def test_out_arrays_that_alias_are_refused():
    d = smoothffd.Deformer(_tri_mesh(), _box(), level=2, device="cpu")
    res = d.deform()
    P, T = len(res.positions), len(res.corner_normals)
    shared = np.zeros(max(3 * P, 9 * T), dtype=np.float32)
    alias = res._replace(positions=shared[: 3 * P].reshape(P, 3),
                         corner_normals=shared[: 9 * T].reshape(T, 3, 3)) \
        if hasattr(res, "_replace") else None
    if alias is None:
        import dataclasses
        alias = dataclasses.replace(res, positions=shared[: 3 * P].reshape(P, 3),
                                    corner_normals=shared[: 9 * T].reshape(T, 3, 3))
    with pytest.raises(ValueError, match="out: its positions and corner_normals share memory"):
        d.deform(out=alias)
