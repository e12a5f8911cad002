"""Self-checks of the independent references in tests/reference.py (no native code needed)."""

import itertools
import math

import numpy as np
import pytest

import reference as ref


rotation = ref.rotation
affine = ref.affine
blender_rest = ref.blender_rest


# ------------------------------------------------------------------------------ weights tables


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
def test_blender_weights_partition_of_unity(kind):
    for t in np.linspace(0, 1, 11):
        assert sum(ref.blender_weights(t, kind)) == pytest.approx(1.0, abs=1e-15)
        assert sum(ref.blender_weights_derivative(t, kind)) == pytest.approx(0.0, abs=1e-14)


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
def test_blender_weights_derivative_fd(kind):
    h = 1e-6
    for t in np.linspace(0.05, 0.95, 7):
        fd = (np.array(ref.blender_weights(t + h, kind)) - ref.blender_weights(t - h, kind)) / (2 * h)
        np.testing.assert_allclose(ref.blender_weights_derivative(t, kind), fd, atol=1e-8)


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
def test_blender_weights_continuity_across_cells(kind):
    # the stencil of cell i at t=1 equals the stencil of cell i+1 at t=0 shifted by one
    w1 = ref.blender_weights(1.0, kind)
    w0 = ref.blender_weights(0.0, kind)
    np.testing.assert_allclose(w1[1:], w0[:3], atol=1e-15)
    assert w1[0] == pytest.approx(0.0, abs=1e-15) and w0[3] == pytest.approx(0.0, abs=1e-15)


def test_blender_weights_known_values():
    assert ref.blender_weights(0.0, "BSPLINE") == pytest.approx((1 / 6, 2 / 3, 1 / 6, 0))
    assert ref.blender_weights(0.5, "CATMULL_ROM") == pytest.approx((-0.0625, 0.5625, 0.5625, -0.0625))
    # cardinal with fc = 0.71 interpolates: t=0 -> weight 1 on i0
    assert ref.blender_weights(0.0, "CARDINAL") == pytest.approx((0, 1, 0, 0))
    with pytest.raises(ValueError):
        ref.blender_weights(0.3, "CUBIC")


# ------------------------------------------------------------------------------ Blender lattice


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
@pytest.mark.parametrize("shape", [(2, 3, 4), (1, 2, 5), (1, 1, 1), (4, 1, 3)])
def test_blender_undeformed_is_identity(kind, shape):
    rng = np.random.default_rng(1)
    rest = blender_rest(shape)
    l2o = affine(rotation([1, 2, 3], 0.7) * 1.7, [0.3, -1, 2])
    p = rng.uniform(-3, 3, (20, 3))
    out, J = ref.blender_lattice_jacobian_reference(rest, rest, kind, l2o, 0.8, p)
    np.testing.assert_array_equal(out, p)
    np.testing.assert_allclose(J, np.broadcast_to(np.eye(3), J.shape), atol=1e-15)


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
def test_blender_translation_of_all_points(kind):
    # moving every point by the same offset moves every vertex by R3 offset * strength
    rest = blender_rest((3, 4, 2))
    off = np.array([0.1, -0.2, 0.3])
    R = rotation([0, 0, 1], 0.5) * 2.0
    l2o = affine(R, [1, 2, 3])
    p = np.random.default_rng(2).uniform(-5, 5, (15, 3))
    out = ref.blender_lattice_reference(rest, rest + off, kind, l2o, 0.5, p)
    np.testing.assert_allclose(out, p + 0.5 * (R @ off), atol=1e-14)


@pytest.mark.parametrize("kind", ["LINEAR", "CARDINAL", "CATMULL_ROM"])
def test_blender_interpolating_types_hit_points(kind):
    # LINEAR/CARDINAL/CATMULL_ROM interpolate: a rest point maps to its deformed point
    rng = np.random.default_rng(3)
    rest = blender_rest((3, 4, 3))
    pts = rest + rng.normal(0, 0.05, rest.shape)
    for idx in [(0, 0, 0), (1, 2, 1), (2, 3, 2), (1, 1, 0)]:
        out = ref.blender_lattice_reference(rest, pts, kind, np.eye(4), 1.0, rest[idx])
        np.testing.assert_allclose(out, pts[idx], atol=1e-14)


def test_blender_bspline_single_cell_value():
    # one axis deformed, point exactly on a rest point of the interior: B-spline weights 1/6 2/3 1/6
    rest = blender_rest((5, 1, 1))
    pts = rest.copy()
    pts[2, 0, 0, 1] = 0.6  # move the middle point in y
    out = ref.blender_lattice_reference(rest, pts, "BSPLINE", np.eye(4), 1.0, rest[2, 0, 0])
    np.testing.assert_allclose(out, rest[2, 0, 0] + [0, 0.6 * 2 / 3, 0], atol=1e-15)
    out = ref.blender_lattice_reference(rest, pts, "BSPLINE", np.eye(4), 1.0, rest[1, 0, 0])
    np.testing.assert_allclose(out, rest[1, 0, 0] + [0, 0.6 / 6, 0], atol=1e-15)


def test_blender_far_outside_constant_and_clamped():
    rng = np.random.default_rng(4)
    rest = blender_rest((3, 3, 3))
    pts = rest + rng.normal(0, 0.1, rest.shape)
    # far beyond +u: all u indices clamp to n-1, so the displacement is the 2-D blend of the
    # u = n-1 face, independent of how far out
    a = ref.blender_lattice_reference(rest, pts, "BSPLINE", np.eye(4), 1.0, [5.0, 0.1, -0.2])
    b = ref.blender_lattice_reference(rest, pts, "BSPLINE", np.eye(4), 1.0, [50.0, 0.1, -0.2])
    np.testing.assert_allclose(a - [5.0, 0.1, -0.2], b - [50.0, 0.1, -0.2], atol=1e-14)
    face = pts[2:3] - rest[2:3] + rest[0:1] * 0  # only the u = n-1 layer moved matters
    rest1 = blender_rest((1, 3, 3))
    rest1[..., 0] = 0.0
    c = ref.blender_lattice_reference(rest1, rest1 + face, "BSPLINE", np.eye(4), 1.0,
                                      [0.0, 0.1, -0.2])
    np.testing.assert_allclose(a - [5.0, 0.1, -0.2], c - [0.0, 0.1, -0.2], atol=1e-14)


@pytest.mark.parametrize("kind", ref.BLENDER_TYPES)
def test_blender_jacobian_matches_fd(kind):
    rng = np.random.default_rng(5)
    shape = (3, 4, 5)
    rest = blender_rest(shape, -1.0, 1.0)
    pts = rest + rng.normal(0, 0.2, rest.shape)
    l2o = affine(rotation([1, -1, 0.5], 1.1) @ np.diag([1.5, 0.7, 2.0]), [0.2, 0.1, -0.3])
    args = (rest, pts, kind, l2o, 0.7)
    p = (l2o[:3, :3] @ rng.uniform(-2.5, 2.5, (25, 3)).T).T + l2o[:3, 3]
    _, J = ref.blender_lattice_jacobian_reference(*args, p)
    fd = ref.jacobian_fd(lambda x: ref.blender_lattice_reference(*args, x), p, 1e-6)
    np.testing.assert_allclose(J, fd, atol=1e-6)


def test_blender_reference_single_point_shape():
    rest = blender_rest((2, 2, 2))
    out = ref.blender_lattice_reference(rest, rest, "LINEAR", np.eye(4), 1.0, [0.1, 0.2, 0.3])
    assert out.shape == (3,)


# ------------------------------------------------------------------------------ B-spline


@pytest.mark.parametrize("n,deg", [(2, 1), (3, 2), (7, 3), (6, 5), (9, 4)])
def test_clamped_knots(n, deg):
    k = ref.clamped_knots(n, deg)
    assert len(k) == n + deg + 1
    assert np.all(k[: deg + 1] == 0) and np.all(k[-deg - 1:] == 1)
    assert np.all(np.diff(k) >= 0)


CUSTOM_KNOTS = [
    (6, 2, [0, 0, 0, 0.3, 0.3, 0.8, 1, 1, 1]),  # interior double knot
    (7, 3, [-1, -0.5, 0, 0.5, 1.5, 1.5, 2.5, 3, 3.5, 4, 4.5]),  # unclamped, double knot
    (5, 1, [0, 0, 0.1, 0.5, 0.6, 1.0, 1.0]),
    (8, 4, [0, 0, 0, 0, 0, 0.2, 0.2, 0.2, 0.7, 1, 1, 1, 1, 1]),  # triple knot, degree 4
    (6, 5, [0, 0.5, 1, 1.5, 2, 2.5, 3.5, 4, 4.5, 5, 5.5, 6]),
]


@pytest.mark.parametrize("n,deg,knots", CUSTOM_KNOTS + [(n, d, None) for n, d in
                                                        [(2, 1), (4, 2), (6, 3), (5, 4), (8, 5)]])
def test_basis_partition_of_unity_and_derivative(n, deg, knots):
    kv = ref.clamped_knots(n, deg) if knots is None else np.asarray(knots, float)
    lo, hi = kv[deg], kv[n]
    us = np.concatenate([np.linspace(lo, hi, 37), [lo, hi]])
    for u in us:
        N = ref.bspline_basis(kv, n, deg, u)
        assert N.sum() == pytest.approx(1.0, abs=1e-14)
        assert np.all(N >= -1e-15)
        assert np.count_nonzero(np.abs(N) > 0) <= deg + 1
        assert ref.bspline_basis_derivative(kv, n, deg, u).sum() == pytest.approx(0, abs=1e-10)
    h = 1e-6
    interior = np.linspace(lo, hi, 41)[1:-1] + 1e-4 * (hi - lo)  # avoid knots
    for u in interior:
        if np.min(np.abs(kv - u)) < 10 * h:
            continue
        fd = (ref.bspline_basis(kv, n, deg, u + h) - ref.bspline_basis(kv, n, deg, u - h)) / (2 * h)
        np.testing.assert_allclose(ref.bspline_basis_derivative(kv, n, deg, u), fd, atol=1e-6)


def test_basis_clamped_endpoint_interpolation():
    kv = ref.clamped_knots(5, 3)
    np.testing.assert_allclose(ref.bspline_basis(kv, 5, 3, 0.0), [1, 0, 0, 0, 0])
    np.testing.assert_allclose(ref.bspline_basis(kv, 5, 3, 1.0), [0, 0, 0, 0, 1])


def test_basis_degree1_is_hat():
    kv = ref.clamped_knots(4, 1)  # knots 0 0 1/3 2/3 1 1
    np.testing.assert_allclose(ref.bspline_basis(kv, 4, 1, 0.5), [0, 0.5, 0.5, 0], atol=1e-15)


def test_basis_uniform_cubic_matches_blender_bspline_weights():
    # a uniform cubic B-spline basis is exactly Blender's BSPLINE weight table
    kv = np.arange(12, dtype=float)  # n = 8, degree 3, domain [3, 8]
    for s in [3.0, 3.25, 4.5, 6.9]:
        N = ref.bspline_basis(kv, 8, 3, s)
        i = int(math.floor(s))
        t = s - i
        w = ref.blender_weights(t, "BSPLINE")
        np.testing.assert_allclose(N[i - 3:i + 1], w, atol=1e-14)


DEGREES = [(1, 1, 1), (2, 2, 2), (3, 1, 2), (5, 4, 3), (1, 5, 2)]


@pytest.mark.parametrize("degree", DEGREES)
@pytest.mark.parametrize("custom", [False, True])
def test_identity_control_points_reproduce_p(degree, custom):
    rng = np.random.default_rng(sum(degree))
    shape = tuple(d + 1 + int(e) for d, e in zip(degree, rng.integers(0, 3, 3)))
    knots = None
    if custom:
        knots = []
        for n, d in zip(shape, degree):
            inner = np.sort(rng.uniform(0.1, 0.9, n - d - 1))
            knots.append(np.concatenate([[0] * (d + 1), inner, [1] * (d + 1)]) * 3 - 1)
    bmin, bmax = np.array([-1.0, 0.5, 2.0]), np.array([2.0, 1.0, 5.0])
    cp = ref.identity_control_points(bmin, bmax, shape, degree, knots)
    assert cp.shape == shape + (3,)
    p = np.concatenate([rng.uniform(bmin, bmax, (20, 3)), rng.uniform(bmin - 3, bmax + 3, (20, 3)),
                        [bmin, bmax]])
    out, J = ref.bspline_volume_reference(cp, degree, knots, bmin, bmax, p, with_jacobian=True)
    np.testing.assert_allclose(out, p, atol=1e-12)
    np.testing.assert_allclose(J, np.broadcast_to(np.eye(3), J.shape), atol=1e-12)


def test_identity_unclamped_knots():
    kv = [np.arange(8.0), np.arange(7.0) * 0.5, np.array([0, 0, 1, 2, 2.5, 4, 4.0])]
    degree = (3, 2, 1)
    shape = (4, 4, 5)
    bmin, bmax = np.zeros(3), np.ones(3)
    cp = ref.identity_control_points(bmin, bmax, shape, degree, kv)
    p = np.random.default_rng(0).uniform(-0.5, 1.5, (30, 3))
    np.testing.assert_allclose(ref.bspline_volume_reference(cp, degree, kv, bmin, bmax, p), p,
                               atol=1e-12)


def test_bspline_trilinear_known_value():
    # degree 1, 2x2x2: trilinear interpolation of the corners
    rng = np.random.default_rng(7)
    cp = rng.normal(size=(2, 2, 2, 3))
    p = np.array([0.25, 0.5, 0.75])
    u, v, w = p
    expect = sum(cp[i, j, k] * (u if i else 1 - u) * (v if j else 1 - v) * (w if k else 1 - w)
                 for i, j, k in itertools.product((0, 1), repeat=3))
    out = ref.bspline_volume_reference(cp, 1, None, [0, 0, 0], [1, 1, 1], p)
    np.testing.assert_allclose(out, expect, atol=1e-15)


def test_bspline_outside_continues_boundary_displacement():
    rng = np.random.default_rng(8)
    degree = (2, 3, 1)
    shape = (4, 5, 3)
    bmin, bmax = np.array([-1.0, -1, -1]), np.array([1.0, 2, 1])
    cp = ref.identity_control_points(bmin, bmax, shape, degree) + rng.normal(0, 0.1, shape + (3,))
    args = (cp, degree, None, bmin, bmax)
    for _ in range(20):
        p = rng.uniform(bmin - 4, bmax + 4)
        c = np.clip(p, bmin, bmax)
        np.testing.assert_allclose(ref.bspline_volume_reference(*args, p) - p,
                                   ref.bspline_volume_reference(*args, c) - c, atol=1e-14)


@pytest.mark.parametrize("degree", DEGREES)
def test_bspline_jacobian_matches_fd(degree):
    rng = np.random.default_rng(10 + sum(degree))
    shape = tuple(d + 2 for d in degree)
    bmin, bmax = np.array([-1.0, 0.0, 1.0]), np.array([1.0, 3.0, 1.5])
    cp = ref.identity_control_points(bmin, bmax, shape, degree) + rng.normal(0, 0.2, shape + (3,))
    args = (cp, degree, None, bmin, bmax)
    p = np.concatenate([rng.uniform(bmin, bmax, (15, 3)), rng.uniform(bmin - 2, bmax + 2, (15, 3))])
    _, J = ref.bspline_volume_reference(*args, p, with_jacobian=True)
    fd = ref.jacobian_fd(lambda x: ref.bspline_volume_reference(*args, x), p, 1e-6)
    np.testing.assert_allclose(J, fd, atol=1e-6)


# ------------------------------------------------------------------------------ misc helpers


def test_jacobian_fd_linear_map_exact():
    A = np.array([[1.0, 2, 3], [0, -1, 4], [2, 2, 0.5]])
    b = np.array([1.0, -2, 3])
    p = np.random.default_rng(0).normal(size=(5, 3))
    J = ref.jacobian_fd(lambda x: x @ A.T + b, p, 1e-3)
    np.testing.assert_allclose(J, np.broadcast_to(A, (5, 3, 3)), atol=1e-10)
    J1 = ref.jacobian_fd(lambda x: (A @ x + b, None), p[0], 1e-3)
    np.testing.assert_allclose(J1, A, atol=1e-10)


def test_cofactor():
    rng = np.random.default_rng(11)
    for _ in range(5):
        J = rng.normal(size=(3, 3))
        np.testing.assert_allclose(ref.cofactor(J), np.linalg.det(J) * np.linalg.inv(J).T,
                                   atol=1e-12)
        # normals stay orthogonal to mapped tangents
        t = rng.normal(size=3)
        n = rng.normal(size=3)
        n -= n.dot(t) / t.dot(t) * t
        assert abs((J @ t).dot(ref.cofactor(J) @ n)) < 1e-12


@pytest.mark.parametrize("L", [1, 2, 3, 10])
def test_barycentric_grid(L):
    bary, sub = ref.barycentric_grid(L)
    assert bary.shape == ((L + 1) * (L + 2) // 2, 3)
    assert sub.shape == (L * L, 3)
    np.testing.assert_allclose(bary.sum(axis=1), 1.0)
    # sub-triangles tile the parent triangle with the same orientation
    P = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    x = bary @ P
    areas = np.cross(x[sub[:, 1]] - x[sub[:, 0]], x[sub[:, 2]] - x[sub[:, 0]])[:, 2] / 2
    np.testing.assert_allclose(areas, 0.5 / L**2)


cube_triangles = ref.cube_triangles


def test_cube_triangles_oriented_outward():
    tri = cube_triangles()
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    centre = tri.mean(axis=1)
    assert np.all(np.einsum("nd,nd->n", n, centre) > 0)


def test_dense_exact_identity_and_affine():
    tri = cube_triangles()
    ident = ref.BSplineReference(ref.identity_control_points([-1] * 3, [1] * 3, (3, 3, 3), (2, 2, 2)),
                                 (2, 2, 2), None, [-1] * 3, [1] * 3)
    d = ref.dense_exact_ffd(tri, ident.evaluate, 4)
    np.testing.assert_allclose(d.positions, d.rest, atol=1e-12)
    np.testing.assert_allclose(d.normals, np.repeat(d.face_normals[:, None], d.bary.shape[0], 1),
                               atol=1e-12)
    assert d.volume == pytest.approx(8.0, abs=1e-12)
    # an affine lattice (control points = A g + b) is exactly affine: volume scales by det A
    A = np.array([[1.2, 0.3, 0], [0, 0.9, 0.1], [0.2, 0, 1.1]])
    g = ref.identity_control_points([-1] * 3, [1] * 3, (3, 4, 3), (2, 3, 1))
    aff = ref.BSplineReference(g @ A.T + [0.1, 0.2, 0.3], (2, 3, 1), None, [-1] * 3, [1] * 3)
    d = ref.dense_exact_ffd(tri, aff.evaluate, 3)
    assert d.volume == pytest.approx(8.0 * np.linalg.det(A), rel=1e-12)
    expect_n = (np.linalg.inv(A).T @ d.face_normals.T).T
    expect_n /= np.linalg.norm(expect_n, axis=1, keepdims=True)
    np.testing.assert_allclose(d.normals, np.repeat(expect_n[:, None], d.bary.shape[0], 1),
                               atol=1e-12)


def test_dense_exact_normals_orthogonal_to_deformed_surface():
    rng = np.random.default_rng(12)
    tri = cube_triangles()
    g = ref.identity_control_points([-1] * 3, [1] * 3, (3, 3, 3), (2, 2, 2))
    lat = ref.BSplineReference(g + rng.normal(0, 0.2, g.shape), (2, 2, 2), None, [-1] * 3, [1] * 3)
    L = 24
    d = ref.dense_exact_ffd(tri[:2], lat.evaluate, L)
    # the deformed grid's tangents (finite differences along the grid) are orthogonal to n'
    bary, _ = ref.barycentric_grid(L)
    key = {(round(b[1] * L), round(b[2] * L)): i for i, b in enumerate(bary)}
    for t in range(2):
        for (j, k), i in key.items():
            if (j + 1, k) in key and (j - 1, k) in key:
                tang = d.positions[t, key[(j + 1, k)]] - d.positions[t, key[(j - 1, k)]]
                tang /= np.linalg.norm(tang)
                assert abs(tang.dot(d.normals[t, i])) < 5e-3


def test_dense_volume_converges_with_level():
    rng = np.random.default_rng(13)
    tri = cube_triangles()
    g = ref.identity_control_points([-1] * 3, [1] * 3, (2, 2, 2), (1, 1, 1))
    lat = ref.BSplineReference(g + rng.normal(0, 0.3, g.shape), 1, None, [-1] * 3, [1] * 3)
    v = [ref.dense_exact_ffd(tri, lat.evaluate, L).volume for L in (4, 8, 16)]
    # trilinear map: error shrinks ~4x per doubling
    assert abs(v[2] - v[1]) < 0.5 * abs(v[1] - v[0]) + 1e-12


def test_mesh_volume_tetrahedron():
    P = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert ref.mesh_volume(P, T) == pytest.approx(1 / 6)


def test_face_normals_of_polygons():
    P = np.array([[0.0, 0, 0], [2, 0, 0], [2, 1, 0], [0, 1, 0], [1, 0.5, 1]])
    n = ref.face_normals_of_polygons(P, (np.array([0, 1, 2, 3, 0, 1, 4]), np.array([0, 4, 7])))
    np.testing.assert_allclose(n[0], [0, 0, 1])
    np.testing.assert_allclose(n, ref.face_normals_of_polygons(P, np.array([[0, 1, 2], [0, 1, 4]])))


def test_smooth_ffd_errors_zero_for_exact_result():
    # a fake "result" made of the dense exact FFD itself has zero error
    from types import SimpleNamespace

    tri = cube_triangles()
    g = ref.identity_control_points([-1] * 3, [1] * 3, (3, 3, 3), (2, 2, 2))
    rng = np.random.default_rng(14)
    lat = ref.BSplineReference(g + rng.normal(0, 0.1, g.shape), (2, 2, 2), None, [-1] * 3, [1] * 3)
    d = ref.dense_exact_ffd(tri, lat.evaluate, 3)
    M = d.bary.shape[0]
    tris = np.concatenate([d.sub_triangles + t * M for t in range(len(tri))])
    normals = d.normals.reshape(-1, 3)
    res = SimpleNamespace(positions=d.positions.reshape(-1, 3), rest_positions=d.rest.reshape(-1, 3),
                          triangles=tris, face_index=np.repeat(np.arange(len(tri)), len(d.sub_triangles)),
                          corner_normals=normals[tris])
    e = ref.smooth_ffd_errors(res, d.face_normals, lat.evaluate)
    assert e["geometry_max"] < 1e-12 and e["normal_max_deg"] < 1e-4
    assert e["volume"] == pytest.approx(d.volume, rel=1e-12)
