"""Error metrics (smoothffd.metrics) against analytic values; pure numpy."""
import pathlib

import numpy as np
import pytest


def _import_pure(name):
    """Pure-Python submodules import without the native core (smoothffd/__init__.py)."""
    import importlib

    return importlib.import_module(f"smoothffd.{name}")


metrics = _import_pure("metrics")


def unit_cube():
    """8 vertices, 12 outward (counter-clockwise from outside) triangles."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    # index = 4x + 2y + z
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tri = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(tri)


def test_cube_and_tetrahedron_volumes():
    v, t = unit_cube()
    assert metrics.signed_volume(v, t) == pytest.approx(1.0, abs=1e-15)
    assert metrics.signed_volume(v * [2, 3, 4] + 1e6, t) == pytest.approx(24.0, rel=1e-12)
    assert metrics.signed_volume(v, t[:, ::-1]) == pytest.approx(-1.0, abs=1e-15)
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tt = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert metrics.signed_volume(tet, tt) == pytest.approx(1 / 6, abs=1e-15)
    assert metrics.volume_error(1.01, 1.0) == pytest.approx(0.01)


def test_volume_of_fine_sphere_approaches_analytic():
    # UV sphere of radius 2: inscribed polyhedron volume converges to 4/3 pi r^3 from below
    n = 200
    th, ph = np.meshgrid(np.linspace(0, np.pi, n + 1)[1:-1], np.linspace(0, 2 * np.pi, 2 * n, endpoint=False), indexing="ij")
    ring = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1).reshape(-1, 3)
    v = 2 * np.vstack([ring, [[0, 0, 1], [0, 0, -1]]])
    m = 2 * n
    top, bot = len(v) - 2, len(v) - 1
    tri = []
    for i in range(n - 2):
        for j in range(m):
            a, b = i * m + j, i * m + (j + 1) % m
            c, d = a + m, b + m
            tri += [(a, c, b), (b, c, d)]
    for j in range(m):
        tri += [(top, j, (j + 1) % m), (bot, (n - 2) * m + (j + 1) % m, (n - 2) * m + j)]
    tri = np.array(tri)
    assert metrics.is_watertight(tri)
    vol = metrics.signed_volume(v, tri)
    exact = 4 / 3 * np.pi * 8
    assert vol < exact and metrics.volume_error(vol, exact) < 1e-3


def test_edge_report():
    v, t = unit_cube()
    r = metrics.edge_report(t)
    assert r == (18, 0, 0, 0, 0) and r.watertight
    r = metrics.edge_report(t[1:])  # hole: one triangle missing
    assert r.boundary == 3 and not r.watertight
    flipped = t.copy()
    flipped[0] = flipped[0, ::-1]
    r = metrics.edge_report(flipped)
    assert r.boundary == 0 and r.misoriented == 3 and not r.watertight
    r = metrics.edge_report(np.vstack([t, t[:1]]))  # a duplicated face
    assert r.non_manifold == 3
    r = metrics.edge_report(np.array([[0, 1, 1], [0, 1, 2]]))
    assert r.degenerate == 1
    assert metrics.edge_report(np.zeros((0, 3), int)).edges == 0
    with pytest.raises(ValueError, match="triangles"):
        metrics.edge_report(np.zeros((3, 4), int))


def test_normal_angles_analytic():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(100, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    # rotate each normal by a known angle about an axis perpendicular to it
    perp = np.cross(n, rng.normal(size=(100, 3)))
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    ang = np.linspace(0, 179, 100)
    rad = np.radians(ang)[:, None]
    m = n * np.cos(rad) + perp * np.sin(rad)
    np.testing.assert_allclose(metrics.normal_angles(m * 3.0, n), ang, atol=1e-10)
    s = metrics.normal_angle_error(m, n)
    assert s.mean == pytest.approx(ang.mean()) and s.max == pytest.approx(179)
    # tiny angles keep their accuracy (acos would give ~1e-6 deg noise here)
    tiny = n * np.cos(1e-9) + perp * np.sin(1e-9)
    np.testing.assert_allclose(metrics.normal_angles(tiny, n), np.degrees(1e-9), rtol=1e-6)
    # (T, 3, 3) corner-normal layout is accepted
    assert metrics.normal_angle_error(m[:99].reshape(33, 3, 3), n[:99].reshape(33, 3, 3)).max > 0
    with pytest.raises(ValueError):
        metrics.normal_angle_error(n[:5], n[:6])


def test_geometry_and_radial_error():
    rng = np.random.default_rng(1)
    p = rng.normal(size=(50, 3))
    d = rng.normal(size=(50, 3))
    d *= (np.arange(50) / 49.0)[:, None] / np.linalg.norm(d, axis=1, keepdims=True)
    s = metrics.geometry_error(p + d, p)
    assert s.mean == pytest.approx(0.5) and s.max == pytest.approx(1.0)
    assert s.rms == pytest.approx(np.sqrt(np.mean((np.arange(50) / 49.0) ** 2)))
    u = p / np.linalg.norm(p, axis=1, keepdims=True)
    c = np.array([1.0, -2.0, 3.0])
    r = metrics.radial_error(c + u * (2 + np.linspace(-0.1, 0.1, 50))[:, None], c, 2.0)
    assert r.max == pytest.approx(0.1) and r.mean == pytest.approx(np.abs(np.linspace(-0.1, 0.1, 50)).mean())


class AffineLattice:
    """Stand-in lattice F(p) = A p + b with the evaluate() contract of docs/api.md."""

    def __init__(self, a, b):
        self.a, self.b = np.asarray(a, float), np.asarray(b, float)

    def evaluate(self, points):
        p = np.asarray(points, float)
        return p @ self.a.T + self.b, np.broadcast_to(self.a, (len(p), 3, 3)).copy()


def test_dense_reference_affine_matches_transformed_geometry():
    rng = np.random.default_rng(2)
    a = rng.normal(size=(3, 3)) + 3 * np.eye(3)
    lat = AffineLattice(a, [1, 2, 3])
    v, t = unit_cube()
    pos, nrm = metrics.dense_reference(lat, v, t)
    np.testing.assert_allclose(pos, v @ a.T + [1, 2, 3])
    # under an affine map the deformed flat face's geometric normal is exact
    q = pos[t]
    geo = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    geo /= np.linalg.norm(geo, axis=1, keepdims=True)
    sign = np.sign(np.linalg.det(a))
    for k in range(3):
        np.testing.assert_allclose(nrm[:, k], sign * geo, atol=1e-12)


def test_cofactor_is_det_times_inverse_transpose():
    j = np.random.default_rng(3).normal(size=(20, 3, 3))
    want = np.linalg.det(j)[:, None, None] * np.linalg.inv(j).transpose(0, 2, 1)
    np.testing.assert_allclose(metrics._cofactor(j), want, atol=1e-12)


def test_dense_reference_with_core_identity():
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    import smoothffd

    lat = smoothffd.BSplineLattice.identity([-0.1] * 3, [1.1] * 3, shape=(4, 4, 4))
    v, t = unit_cube()
    pos, nrm = metrics.dense_reference(lat, v, t)
    np.testing.assert_allclose(pos, v, atol=1e-12)
    q = v[t]
    geo = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    np.testing.assert_allclose(nrm[:, 0], geo / np.linalg.norm(geo, axis=1, keepdims=True), atol=1e-12)


def test_reference_errors_of_an_exact_result_are_zero():
    # a fake Result: the affine image of a cube is exactly what smooth FFD should produce
    from types import SimpleNamespace

    a = np.diag([2.0, 1.0, 0.5])
    lat = AffineLattice(a, [0, 0, 1])
    v, t = unit_cube()
    pos, nrm = metrics.dense_reference(lat, v, t)
    res = SimpleNamespace(positions=pos.astype(np.float32), triangles=t.astype(np.int32),
                          corner_normals=nrm.astype(np.float32), rest_positions=v.astype(np.float32))
    e = metrics.reference_errors(res, lat)
    assert e["geometry"].max < 1e-6 and e["normal"].max < 1e-4
    assert e["reference_volume"] == pytest.approx(1.0) and e["volume_error"] < 1e-6


def test_reference_errors_with_core_cube():
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    import smoothffd

    v, t = unit_cube()
    v = v * 2 - 1  # the paper's cube in [-1, 1]^3
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(4, 4, 4))
    cp = lat.control_points.copy()
    cp[..., 0] *= 1 + 0.3 * cp[..., 2]  # taper along z
    lat = lat.with_control_points(cp)
    # flat (split) corner normals: a sharp cube, as in the paper; without them the cube would
    # be smoothed into a rounded blob
    q = v[t]
    fn = np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    mesh = smoothffd.Mesh(v, t, corner_normals=np.repeat(fn, 3, axis=0))
    res = smoothffd.deform(mesh, lat, level=4, device="cpu")
    e = metrics.reference_errors(res, lat)
    # The corners: measured 4.8e-8 (half a float32 step at 1), bound two steps.
    assert metrics.geometry_error(res.positions[:8], lat.evaluate(v)[0]).max < 2.4e-7
    # A taper is quadratic, so on each flat face the exact FFD is a quadratic patch that the
    # cubic patches reproduce: only float32 rounding remains. Measured: geometry 1.31e-7,
    # normals 5.3e-6 degrees (3.0e-6 on the x86-64-v2 path), volume 1.7e-8; bounds 3x, the
    # normals' 10x (float rounding of a unit vector, 1e-7 rad, is 6e-6 degrees).
    assert e["geometry"].max < 4e-7, e["geometry"]
    assert e["normal"].max < 5e-5, e["normal"]
    assert e["volume_error"] < 5e-8, e["volume_error"]
