"""smoothffd.BlenderLattice / smoothffd.BSplineLattice against the independent references in
tests/reference.py (positions, Jacobians, knot planes, identity, outside behaviour, bad input).

Tolerances: positions 1e-9 relative to the scene scale (the core evaluates in double),
Jacobians 1e-6 relative to max(1, |J|).
"""

import zlib

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
import smoothffd  # noqa: E402

import reference as ref  # noqa: E402

TYPES = ref.BLENDER_TYPES
POS_RTOL = 1e-9
JAC_TOL = 1e-6


def assert_positions(actual, expected, scale):
    actual = np.asarray(actual)
    assert actual.dtype == np.float64
    assert actual.shape == np.shape(expected)
    err = np.max(np.abs(actual - expected)) if actual.size else 0.0
    assert err <= POS_RTOL * max(1.0, scale), f"max position error {err:.3e} (scale {scale:.3g})"


def assert_jacobians(actual, expected, tol=JAC_TOL):
    actual = np.asarray(actual)
    assert actual.dtype == np.float64
    assert actual.shape == np.shape(expected)
    if not actual.size:
        return
    size = np.maximum(1.0, np.abs(expected).max(axis=(-2, -1)))
    err = (np.abs(actual - expected).max(axis=(-2, -1)) / size).max()
    assert err <= tol, f"max Jacobian error {err:.3e}"


def seed(*key):
    """Deterministic seed (str hashes are salted per process)."""
    return zlib.crc32(repr(key).encode())


def core_fd(lattice, p, h):
    return ref.jacobian_fd(lambda x: lattice.evaluate(x)[0], p, h)


# =============================================================================================
# BlenderLattice
# =============================================================================================

BLENDER_SHAPES = [(2, 2, 2), (3, 4, 5), (1, 3, 4), (2, 1, 1), (1, 1, 1), (5, 2, 3), (6, 6, 6),
                  (4, 1, 2)]
BLENDER_KINDS = [(k,) * 3 for k in TYPES] + [("LINEAR", "CARDINAL", "BSPLINE"),
                                             ("CATMULL_ROM", "BSPLINE", "LINEAR")]


def random_blender_case(rng, shape, kinds):
    """(kwargs for BlenderLattice, inside points, far-outside points, scale)."""
    spans = [(-0.5, 0.5), None, (-1.0, 1.0), tuple(np.sort(rng.uniform(-2, 2, 2)))]
    choice = spans[rng.integers(len(spans))]
    if choice is None:  # lattice resized while unused: unit spacing
        lo = np.array([-(n - 1) / 2 for n in shape])
        hi = -lo
    else:
        lo, hi = np.full(3, choice[0]), np.full(3, choice[1])
        if hi[0] - lo[0] < 0.3:
            hi = lo + 1.0
    rest = ref.blender_rest(shape, lo, hi)
    size = float(np.max(hi - lo)) if np.any(np.array(shape) > 1) else 1.0
    size = max(size, 1e-3)
    points = rest + rng.normal(0, 0.15 * size, rest.shape)
    A = ref.rotation(rng.normal(size=3), rng.uniform(0, np.pi)) @ np.diag(rng.uniform(0.5, 2.0, 3))
    l2o = ref.affine(A, rng.uniform(-2, 2, 3))
    strength = float(rng.choice([1.0, 0.35, 1.6]))
    qlo = np.where(np.array(shape) > 1, lo, -0.5) - 0.1 * size
    qhi = np.where(np.array(shape) > 1, hi, 0.5) + 0.1 * size
    q_in = rng.uniform(qlo, qhi, (40, 3))
    q_out = rng.uniform(-10 * size, 10 * size, (20, 3))
    q_out[:5] = q_in[:5]
    q_out[np.arange(5), rng.integers(0, 3, 5)] = 6 * size * rng.choice([-1, 1], 5)  # one axis out
    to_obj = lambda q: q @ l2o[:3, :3].T + l2o[:3, 3]  # noqa: E731
    kwargs = dict(rest_points=rest, points=points, interpolation=kinds,
                  lattice_to_object=l2o, strength=strength)
    p_in, p_out = to_obj(q_in), to_obj(q_out)
    scale = float(max(np.abs(p_out).max(), np.abs(l2o).max() * (size + np.abs(points).max())))
    return kwargs, p_in, p_out, scale


def reference_eval(kwargs, p):
    return ref.blender_lattice_jacobian_reference(
        kwargs["rest_points"], kwargs["points"], kwargs["interpolation"],
        kwargs["lattice_to_object"], kwargs["strength"], p)


@pytest.mark.parametrize("kinds", BLENDER_KINDS, ids=lambda k: "-".join(k))
@pytest.mark.parametrize("shape", BLENDER_SHAPES, ids=lambda s: "x".join(map(str, s)))
def test_blender_matches_reference(kinds, shape):
    rng = np.random.default_rng(seed(kinds, shape))
    kwargs, p_in, p_out, scale = random_blender_case(rng, shape, kinds)
    lat = smoothffd.BlenderLattice(**kwargs)
    for p in (p_in, p_out):
        pos, jac = lat.evaluate(p)
        rpos, rjac = reference_eval(kwargs, p)
        assert_positions(pos, rpos, scale)
        assert_jacobians(jac, rjac)


@pytest.mark.parametrize("kinds", BLENDER_KINDS, ids=lambda k: "-".join(k))
def test_blender_jacobian_vs_finite_differences(kinds):
    rng = np.random.default_rng(42)
    kwargs, p_in, p_out, scale = random_blender_case(rng, (4, 3, 5), kinds)
    lat = smoothffd.BlenderLattice(**kwargs)
    p = np.concatenate([p_in[:20], p_out[:10]])
    _, jac = lat.evaluate(p)
    fd = core_fd(lat, p, 1e-6 * max(1.0, scale))
    assert_jacobians(jac, fd)


@pytest.mark.parametrize("kind", TYPES)
@pytest.mark.parametrize("shape", [(1, 1, 1), (2, 3, 1), (4, 4, 4)])
def test_blender_undeformed_is_identity(kind, shape):
    rng = np.random.default_rng(3)
    rest = ref.blender_rest(shape)
    l2o = ref.affine(ref.rotation([1, 2, 3], 0.4) * 1.3, [1, -1, 0.5])
    lat = smoothffd.BlenderLattice(rest, rest.copy(), (kind,) * 3, l2o, 0.7)
    p = rng.uniform(-4, 4, (50, 3))
    pos, jac = lat.evaluate(p)
    np.testing.assert_allclose(pos, p, rtol=0, atol=1e-12 * 4)
    np.testing.assert_allclose(jac, np.broadcast_to(np.eye(3), jac.shape), rtol=0, atol=1e-12)


def test_blender_defaults_are_bspline_identity_strength_one():
    rng = np.random.default_rng(4)
    rest = ref.blender_rest((3, 3, 3))
    pts = rest + rng.normal(0, 0.1, rest.shape)
    p = rng.uniform(-1, 1, (30, 3))
    pos, _ = smoothffd.BlenderLattice(rest, pts).evaluate(p)
    expect = ref.blender_lattice_reference(rest, pts, "BSPLINE", np.eye(4), 1.0, p)
    assert_positions(pos, expect, 1.0)


@pytest.mark.parametrize("strength", [0.0, 0.5, 2.0, -1.0])
def test_blender_strength_scales_displacement(strength):
    rng = np.random.default_rng(5)
    rest = ref.blender_rest((3, 2, 4))
    pts = rest + rng.normal(0, 0.1, rest.shape)
    p = rng.uniform(-1, 1, (30, 3))
    one, _ = smoothffd.BlenderLattice(rest, pts, ("CARDINAL",) * 3, np.eye(4), 1.0).evaluate(p)
    s, _ = smoothffd.BlenderLattice(rest, pts, ("CARDINAL",) * 3, np.eye(4), strength).evaluate(p)
    assert_positions(s, p + strength * (one - p), 1.0)


def test_blender_far_outside_translated_by_boundary_blend():
    # far outside on +u, the displacement does not depend on how far out
    rng = np.random.default_rng(6)
    rest = ref.blender_rest((3, 4, 3))
    pts = rest + rng.normal(0, 0.1, rest.shape)
    lat = smoothffd.BlenderLattice(rest, pts, ("BSPLINE",) * 3)
    base = np.array([[0.1, -0.2, 0.3], [-0.3, 0.4, 0.0]])
    d = []
    for x in (3.0, 10.0, 1000.0):
        p = base + [x, 0, 0]
        d.append(lat.evaluate(p)[0] - p)
    np.testing.assert_allclose(d[0], d[1], atol=1e-12)
    np.testing.assert_allclose(d[0], d[2], atol=1e-9)


def test_blender_accepts_other_dtypes_and_empty():
    rest = ref.blender_rest((2, 2, 2)).astype(np.float32)
    pts = (rest * 1.5).astype(np.float32)
    lat = smoothffd.BlenderLattice(rest, pts, ["LINEAR", "LINEAR", "LINEAR"],
                                   np.eye(4, dtype=np.int64), 1)
    pos, jac = lat.evaluate(np.array([[0, 0, 0], [1, 0, 0]], dtype=np.int32))
    assert pos.dtype == np.float64 and jac.dtype == np.float64
    assert pos.shape == (2, 3) and jac.shape == (2, 3, 3)
    expect = ref.blender_lattice_reference(rest.astype(float), pts.astype(float), "LINEAR",
                                           np.eye(4), 1.0, np.array([[0.0, 0, 0], [1, 0, 0]]))
    assert_positions(pos, expect, 1.0)
    pos, jac = lat.evaluate(np.zeros((0, 3)))
    assert pos.shape == (0, 3) and jac.shape == (0, 3, 3)


def test_blender_with_points_and_structure_key():
    rng = np.random.default_rng(7)
    rest = ref.blender_rest((3, 4, 2))
    l2o = ref.affine(ref.rotation([0, 1, 1], 0.3), [0, 0, 1])
    a = rest + rng.normal(0, 0.1, rest.shape)
    b = rest + rng.normal(0, 0.1, rest.shape)
    kinds = ("CATMULL_ROM", "BSPLINE", "LINEAR")
    lat_a = smoothffd.BlenderLattice(rest, a, kinds, l2o, 0.9)
    lat_b = lat_a.with_points(b)
    fresh_b = smoothffd.BlenderLattice(rest, b, kinds, l2o, 0.9)
    p = rng.uniform(-1, 1, (20, 3))
    np.testing.assert_array_equal(lat_b.evaluate(p)[0], fresh_b.evaluate(p)[0])
    np.testing.assert_array_equal(lat_a.evaluate(p)[0],
                                  smoothffd.BlenderLattice(rest, a, kinds, l2o, 0.9).evaluate(p)[0])
    assert lat_a.structure_key() == lat_b.structure_key()
    hash(lat_a.structure_key())
    other = smoothffd.BlenderLattice(rest, a, ("BSPLINE",) * 3, l2o, 0.9)
    assert other.structure_key() != lat_a.structure_key()
    cv = lat_a.control_values()
    assert cv.shape == (3, 4, 2, 3) and cv.dtype == np.float64


@pytest.mark.parametrize("shape", [(2, 3, 5), (1, 4, 2), (6, 1, 1)])
def test_blender_object_to_param_is_index_space(shape):
    rng = np.random.default_rng(8)
    rest = ref.blender_rest(shape, [-1.0, 0.0, 2.0], [1.0, 3.0, 2.5])
    l2o = ref.affine(ref.rotation([1, 1, 0], 0.8) @ np.diag([2.0, 0.5, 1.0]), [3, 2, 1])
    lat = smoothffd.BlenderLattice(rest, rest, ("BSPLINE",) * 3, l2o, 1.0)
    o2p = np.asarray(lat.object_to_param, dtype=np.float64)
    assert o2p.shape == (3, 4)
    p = rng.uniform(-3, 3, (10, 3))
    q = p @ np.linalg.inv(l2o)[:3, :3].T + np.linalg.inv(l2o)[:3, 3]
    s = p @ o2p[:, :3].T + o2p[:, 3]
    for a in range(3):
        if shape[a] > 1:
            f = rest[0, 0, 0, a]
            d = (rest[(-1 if a == 0 else 0, -1 if a == 1 else 0, -1 if a == 2 else 0)][a] - f) / (
                shape[a] - 1)
            np.testing.assert_allclose(s[:, a], (q[:, a] - f) / d, atol=1e-10)


def _param_to_object(lat):
    o2p = np.asarray(lat.object_to_param, dtype=np.float64)
    A_inv = np.linalg.inv(o2p[:, :3])
    return lambda s: (np.atleast_2d(s) - o2p[:, 3]) @ A_inv.T


def _check_piecewise_polynomial(lat, axis, planes, degree, base_s, to_obj, scale):
    """Along a line where only s_axis varies, F is a polynomial of <= degree between planes.

    ``to_obj`` maps parameter-space points (N, 3) to object space."""
    edges = np.concatenate([[planes[0] - 1.5], planes, [planes[-1] + 1.5]])
    for lo, hi in zip(edges[:-1], edges[1:]):
        if hi - lo < 1e-9:
            continue
        t = np.linspace(lo, hi, 13)[1:-1]
        s = np.repeat(np.asarray(base_s, dtype=np.float64)[None], len(t), axis=0)
        s[:, axis] = t
        pos, _ = lat.evaluate(to_obj(s))
        x = (t - (lo + hi) / 2) / (hi - lo)
        V = np.vander(x, degree + 1)
        coef, *_ = np.linalg.lstsq(V, pos, rcond=None)
        resid = np.abs(V @ coef - pos).max()
        assert resid < 1e-9 * max(1.0, scale), (
            f"axis {axis}: not polynomial of degree {degree} on [{lo}, {hi}] (residual {resid:.2e})")


@pytest.mark.parametrize("n", range(2, 13))
def test_blender_jacobian_on_lattice_boundary_is_inner(n):
    """A mesh fitted to a Blender lattice (vertices on the lattice's outer faces, q = +-0.5)
    must get the one-sided inner Jacobian there, whatever the rounding of s = (q - f) / d.
    Only LINEAR has a kink there (the other types are C1 across s = 0 and s = n - 1)."""
    rest = ref.blender_rest((n, 3, 2))
    pts = rest.copy()
    pts[..., 1] += rest[..., 0] ** 2 + rest[..., 0] + 0.3 * rest[..., 2]
    pts[..., 2] += 0.5 * rest[..., 1] ** 2 - 0.2 * rest[..., 0]
    lat = smoothffd.BlenderLattice(rest, pts, ("LINEAR",) * 3)
    # Interior coordinates stay off the interior knot planes: there LINEAR's Jacobian jumps and
    # which side s = (q - f) / d lands on is a matter of rounding (both sides are right).
    g = np.array([-0.5, -0.33, 0.13, 0.5])
    p = np.array([[x, y, z] for x in (-0.5, 0.5) for y in g for z in g])  # on the u faces
    p = np.concatenate([p, p[:, [1, 0, 2]], p[:, [1, 2, 0]]])              # v and w faces
    _, jac = lat.evaluate(p)
    _, rjac = ref.blender_lattice_jacobian_reference(rest, pts, "LINEAR", np.eye(4), 1.0, p)
    assert_jacobians(jac, rjac)


@pytest.mark.parametrize("seed_", range(6))
def test_bspline_jacobian_on_box_faces_is_inner(seed_):
    """Vertices exactly on the box faces (a mesh whose bounds are the box, as in the cube
    tests) get the one-sided inner Jacobian, whatever the rounding of s = A p + b."""
    rng = np.random.default_rng(seed("box faces", seed_))
    degree = tuple(int(d) for d in rng.integers(1, 6, 3))
    kwargs, *_ = random_bspline_case(rng, degree, ["default", "clamped", "unclamped"][seed_ % 3])
    lat = smoothffd.BSplineLattice(**kwargs)
    bmin, bmax = kwargs["box_min"], kwargs["box_max"]
    p = rng.uniform(bmin, bmax, (60, 3))
    which = rng.integers(0, 3, (60, 3))
    p = np.where(which == 1, bmin, np.where(which == 2, bmax, p))
    _, jac = lat.evaluate(p)
    _, rjac = ref.bspline_volume_reference(**kwargs, p=p, with_jacobian=True)
    assert_jacobians(jac, rjac)


@pytest.mark.parametrize("kind", TYPES)
@pytest.mark.parametrize("shape", [(2, 3, 5), (4, 1, 2)])
def test_blender_knot_planes(kind, shape):
    rng = np.random.default_rng(9)
    rest = ref.blender_rest(shape)
    pts = rest + rng.normal(0, 0.15, rest.shape)
    l2o = ref.affine(ref.rotation([1, 2, 0.5], 0.6) * 1.5, [0.5, 0, -1])
    lat = smoothffd.BlenderLattice(rest, pts, (kind,) * 3, l2o, 1.0)
    planes = lat.knot_planes()
    assert len(planes) == 3
    for a in range(3):
        pl = np.asarray(planes[a])
        assert pl.dtype == np.float64 and pl.ndim == 1
        assert np.all(np.isfinite(pl))
        assert np.all(np.diff(pl) > 0), "knot planes must be sorted and distinct"
        n = shape[a]
        if n == 1:
            continue
        needed = np.arange(0, n) if kind == "LINEAR" else np.arange(-1, n + 1)
        for c in needed:
            assert np.min(np.abs(pl - c)) < 1e-12, f"axis {a}: plane {c} missing from {pl}"
        # index space -> lattice space (q = f + s d, from the rest points) -> object space
        f = rest[0, 0, 0]
        d = np.array([(rest[-1, -1, -1, b] - f[b]) / (m - 1) if m > 1 else 0.0
                      for b, m in enumerate(shape)])
        to_obj = lambda s: (f + s * d) @ l2o[:3, :3].T + l2o[:3, 3]  # noqa: E731
        base = np.array([0.37 * (m - 1) if m > 1 else 0.0 for m in shape])
        _check_piecewise_polynomial(lat, a, pl, 3, base, to_obj, 3.0)


# =============================================================================================
# BSplineLattice
# =============================================================================================

DEGREES = [(1, 1, 1), (2, 2, 2), (3, 3, 3), (4, 4, 4), (5, 5, 5), (1, 3, 5), (5, 2, 1),
           (2, 4, 3)]


def random_knots(rng, n, d, kind):
    if kind == "clamped":
        m = n - d - 1
        inner = np.sort(rng.uniform(0.05, 0.95, m))
        if m >= 2 and d >= 2:
            j = rng.integers(0, m - 1)
            inner[j + 1] = inner[j]  # double interior knot
        if m >= 3 and d >= 3:
            inner[m - 1] = inner[m - 2] = inner[m - 3]  # triple knot
            inner = np.sort(inner)
        a, b = sorted(rng.uniform(-3, 3, 2))
        b = max(b, a + 0.5)
        return a + (b - a) * np.concatenate([[0.0] * (d + 1), inner, [1.0] * (d + 1)])
    # unclamped: strictly increasing except one double knot inside the domain when d >= 2
    k = np.cumsum(rng.uniform(0.2, 1.0, n + d + 1)) - 3.0
    if d >= 2 and n - d >= 3:
        k[d + 1] = k[d + 2] = (k[d + 1] + k[d + 2]) / 2
    return k


def random_bspline_case(rng, degree, knot_kind):
    shape = tuple(int(d + 1 + rng.integers(0, 4)) for d in degree)
    if knot_kind == "default":
        knots = None
    else:
        knots = [random_knots(rng, n, d, knot_kind) for n, d in zip(shape, degree)]
    bmin = rng.uniform(-2, 1, 3)
    bmax = bmin + rng.uniform(0.5, 3, 3)
    ident = ref.identity_control_points(bmin, bmax, shape, degree, knots)
    size = float(np.max(bmax - bmin))
    cp = ident + rng.normal(0, 0.1 * size, ident.shape)
    p_in = rng.uniform(bmin, bmax, (30, 3))
    p_out = rng.uniform(bmin - 3 * size, bmax + 3 * size, (20, 3))
    p_out[:6] = p_in[:6]
    p_out[np.arange(6), np.arange(6) % 3] += np.where(np.arange(6) < 3, -1, 1) * 2 * size
    return dict(control_points=cp, degree=degree, knots=knots, box_min=bmin, box_max=bmax), \
        p_in, p_out, float(np.abs(p_out).max() + np.abs(cp).max())


@pytest.mark.parametrize("knot_kind", ["default", "clamped", "unclamped"])
@pytest.mark.parametrize("degree", DEGREES, ids=lambda d: "deg" + "".join(map(str, d)))
def test_bspline_matches_reference(degree, knot_kind):
    rng = np.random.default_rng(seed(degree, knot_kind))
    kwargs, p_in, p_out, scale = random_bspline_case(rng, degree, knot_kind)
    lat = smoothffd.BSplineLattice(**kwargs)
    rlat = ref.BSplineReference(**kwargs)
    for p in (p_in, p_out):
        pos, jac = lat.evaluate(p)
        rpos, rjac = rlat.evaluate(p)
        assert_positions(pos, rpos, scale)
        assert_jacobians(jac, rjac)


@pytest.mark.parametrize("knot_kind", ["default", "clamped"])
@pytest.mark.parametrize("degree", [(2, 2, 2), (1, 3, 5), (4, 1, 2)],
                         ids=lambda d: "deg" + "".join(map(str, d)))
def test_bspline_jacobian_vs_finite_differences(degree, knot_kind):
    rng = np.random.default_rng(11)
    kwargs, p_in, p_out, scale = random_bspline_case(rng, degree, knot_kind)
    lat = smoothffd.BSplineLattice(**kwargs)
    p = np.concatenate([p_in[:20], p_out[6:16]])
    _, jac = lat.evaluate(p)
    fd = core_fd(lat, p, 1e-6 * max(1.0, scale))
    assert_jacobians(jac, fd)


@pytest.mark.parametrize("knot_kind", ["default", "clamped", "unclamped"])
@pytest.mark.parametrize("degree", DEGREES, ids=lambda d: "deg" + "".join(map(str, d)))
def test_bspline_identity_reproduces_p(degree, knot_kind):
    rng = np.random.default_rng(seed(degree, knot_kind, 1))
    shape = tuple(int(d + 1 + rng.integers(0, 4)) for d in degree)
    knots = None if knot_kind == "default" else [
        random_knots(rng, n, d, knot_kind) for n, d in zip(shape, degree)]
    bmin = rng.uniform(-2, 1, 3)
    bmax = bmin + rng.uniform(0.5, 3, 3)
    lat = smoothffd.BSplineLattice.identity(bmin, bmax, shape=shape, degree=degree, knots=knots)
    p = np.concatenate([rng.uniform(bmin, bmax, (40, 3)), rng.uniform(bmin - 5, bmax + 5, (20, 3))])
    pos, jac = lat.evaluate(p)
    np.testing.assert_allclose(pos, p, rtol=0, atol=1e-12 * max(1.0, np.abs(p).max()))
    np.testing.assert_allclose(jac, np.broadcast_to(np.eye(3), jac.shape), rtol=0, atol=1e-10)
    # the displacements of the identity are all zero (F = p + sum W D, W independent)
    np.testing.assert_allclose(lat.control_values(), 0.0, atol=1e-12 * max(1.0, np.abs(p).max()))
    # and our Greville control points give the identity through the plain constructor too
    cp = ref.identity_control_points(bmin, bmax, shape, degree, knots)
    pos2, _ = smoothffd.BSplineLattice(cp, degree, knots, bmin, bmax).evaluate(p)
    np.testing.assert_allclose(pos2, p, rtol=0, atol=1e-12 * max(1.0, np.abs(p).max()))


def test_bspline_identity_defaults():
    lat = smoothffd.BSplineLattice.identity([-1, -1, -1], [1, 1, 1])
    p = np.random.default_rng(0).uniform(-3, 3, (50, 3))
    pos, _ = lat.evaluate(p)
    np.testing.assert_allclose(pos, p, rtol=0, atol=1e-12 * 3)
    assert lat.control_values().shape == (5, 5, 5, 3)


@pytest.mark.parametrize("degree", [(2, 2, 2), (3, 1, 4)], ids=str)
def test_bspline_control_values_are_offsets_from_greville(degree):
    rng = np.random.default_rng(12)
    kwargs, *_ = random_bspline_case(rng, degree, "clamped")
    lat = smoothffd.BSplineLattice(**kwargs)
    g = ref.identity_control_points(kwargs["box_min"], kwargs["box_max"],
                                    kwargs["control_points"].shape[:3], degree, kwargs["knots"])
    np.testing.assert_allclose(lat.control_values(), kwargs["control_points"] - g, atol=1e-12)


def test_bspline_default_box_is_control_point_bounds():
    rng = np.random.default_rng(15)
    kwargs, p_in, p_out, scale = random_bspline_case(rng, (2, 1, 3), "clamped")
    cp = kwargs["control_points"]
    flat = cp.reshape(-1, 3)
    lat = smoothffd.BSplineLattice(cp, kwargs["degree"], kwargs["knots"])
    rlat = ref.BSplineReference(cp, kwargs["degree"], kwargs["knots"], flat.min(0), flat.max(0))
    for p in (p_in, p_out):
        pos, jac = lat.evaluate(p)
        rpos, rjac = rlat.evaluate(p)
        assert_positions(pos, rpos, scale)
        assert_jacobians(jac, rjac)


def test_bspline_outside_continues_nearest_box_displacement():
    rng = np.random.default_rng(13)
    kwargs, p_in, p_out, scale = random_bspline_case(rng, (2, 3, 2), "default")
    lat = smoothffd.BSplineLattice(**kwargs)
    bmin, bmax = kwargs["box_min"], kwargs["box_max"]
    p = rng.uniform(bmin - 10, bmax + 10, (60, 3))
    c = np.clip(p, bmin, bmax)
    fp, jp = lat.evaluate(p)
    fc, _ = lat.evaluate(c)
    assert_positions(fp - p, fc - c, scale + 10)
    # derivative along a clamped axis is that of the identity
    out = (p < bmin) | (p > bmax)
    for n in range(len(p)):
        for a in np.nonzero(out[n])[0]:
            e = np.zeros(3)
            e[a] = 1
            np.testing.assert_allclose(jp[n][:, a], e, atol=1e-12)


def test_bspline_with_control_points_and_structure_key():
    rng = np.random.default_rng(14)
    kwargs, p_in, p_out, scale = random_bspline_case(rng, (2, 3, 1), "clamped")
    lat = smoothffd.BSplineLattice(**kwargs)
    cp2 = kwargs["control_points"] + rng.normal(0, 0.1, kwargs["control_points"].shape)
    lat2 = lat.with_control_points(cp2)
    fresh = smoothffd.BSplineLattice(**{**kwargs, "control_points": cp2})
    np.testing.assert_array_equal(lat2.evaluate(p_in)[0], fresh.evaluate(p_in)[0])
    assert lat.structure_key() == lat2.structure_key()
    hash(lat.structure_key())
    other = smoothffd.BSplineLattice(**{**kwargs, "degree": (1, 3, 1), "knots": None})
    assert other.structure_key() != lat.structure_key()


@pytest.mark.parametrize("knot_kind", ["default", "clamped", "unclamped"])
@pytest.mark.parametrize("degree", [(1, 2, 3), (5, 4, 2), (3, 3, 3)], ids=str)
def test_bspline_knot_planes(degree, knot_kind):
    rng = np.random.default_rng(seed(degree, knot_kind, 2))
    kwargs, *_ = random_bspline_case(rng, degree, knot_kind)
    lat = smoothffd.BSplineLattice(**kwargs)
    shape = kwargs["control_points"].shape[:3]
    bmin, bmax = kwargs["box_min"], kwargs["box_max"]
    knots = kwargs["knots"] or [ref.clamped_knots(n, d) for n, d in zip(shape, degree)]
    o2p = np.asarray(lat.object_to_param, dtype=np.float64)
    assert o2p.shape == (3, 4)
    # the embedding is axis-aligned
    np.testing.assert_allclose(o2p[:, :3] - np.diag(np.diag(o2p[:, :3])), 0, atol=1e-15)
    planes = lat.knot_planes()
    assert len(planes) == 3
    for a in range(3):
        pl = np.asarray(planes[a])
        assert pl.dtype == np.float64 and pl.ndim == 1 and np.all(np.diff(pl) > 0)
        # compare in object space: independent of how the core scales its parameter space
        x_core = (pl - o2p[a, 3]) / o2p[a, a]
        kv = np.asarray(knots[a], dtype=np.float64)
        n, d = shape[a], degree[a]
        dom = np.unique(kv[d:n + 1])
        x_ref = bmin[a] + (dom - kv[d]) / (kv[n] - kv[d]) * (bmax[a] - bmin[a])
        np.testing.assert_allclose(x_core, x_ref, atol=1e-12 * max(1, np.abs(x_ref).max()))
        base = (np.array([bmin, bmax]).mean(axis=0) + 0.13) @ o2p[:, :3].T + o2p[:, 3]
        _check_piecewise_polynomial(lat, a, pl, d, base, _param_to_object(lat),
                                    float(np.abs(kwargs["control_points"]).max()))


# =============================================================================================
# bad input
# =============================================================================================


def raises_naming(fn, *names):
    with pytest.raises((ValueError, TypeError)) as info:
        fn()
    msg = str(info.value)
    assert any(n in msg for n in names), f"message {msg!r} names none of {names}"


GOOD_CP = ref.identity_control_points([0, 0, 0], [1, 1, 1], (4, 4, 4), (2, 2, 2))


def bs(**over):
    kw = dict(control_points=GOOD_CP, degree=(2, 2, 2), knots=None, box_min=[0, 0, 0],
              box_max=[1, 1, 1])
    kw.update(over)
    return lambda: smoothffd.BSplineLattice(**kw)


def test_bspline_good_baseline_constructs():
    bs()()
    smoothffd.BSplineLattice(GOOD_CP, (2, 2, 2), [ref.clamped_knots(4, 2)] * 3, [0, 0, 0],
                             [1, 1, 1])


@pytest.mark.parametrize("cp", [
    GOOD_CP[..., :2],            # 2 coordinates
    GOOD_CP[0],                  # 3-D array
    GOOD_CP.reshape(-1, 3),      # flat
    GOOD_CP[None],               # 5-D
], ids=["coords2", "ndim4-missing", "flat", "ndim5"])
def test_bspline_bad_control_points_shape(cp):
    raises_naming(bs(control_points=cp), "control_points")


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_bspline_nonfinite_control_points(bad):
    cp = GOOD_CP.copy()
    cp[1, 2, 3, 1] = bad
    raises_naming(bs(control_points=cp), "control_points")


def test_bspline_non_numeric_control_points():
    raises_naming(bs(control_points=np.full((4, 4, 4, 3), "x")), "control_points")


@pytest.mark.parametrize("degree", [(0, 2, 2), (2, 6, 2), (2, 2, -1), (2, 2), (2, 2, 2, 2),
                                    (2.5, 2, 2)], ids=str)
def test_bspline_bad_degree(degree):
    raises_naming(bs(degree=degree), "degree")


def test_bspline_too_few_control_points_for_degree():
    cp = ref.identity_control_points([0, 0, 0], [1, 1, 1], (3, 4, 4), (2, 2, 2))
    raises_naming(bs(control_points=cp, degree=(3, 2, 2)), "control_points", "degree")
    cp = np.zeros((1, 4, 4, 3))
    raises_naming(bs(control_points=cp, degree=(1, 2, 2)), "control_points", "degree")


def test_bspline_bad_knots():
    good = ref.clamped_knots(4, 2)
    nonmono = good.copy()
    nonmono[3], nonmono[4] = 0.8, 0.2
    raises_naming(bs(knots=[good, nonmono, good]), "knots")
    raises_naming(bs(knots=[good, good, good[:-1]]), "knots")       # wrong count
    raises_naming(bs(knots=[good, good, np.append(good, 1.0)]), "knots")
    raises_naming(bs(knots=[good, good]), "knots")                   # only two axes
    withnan = good.copy()
    withnan[3] = np.nan
    raises_naming(bs(knots=[withnan, good, good]), "knots")
    raises_naming(bs(knots=[np.zeros(7), good, good]), "knots")      # empty domain


@pytest.mark.parametrize("bmin,bmax", [
    ([0, 0, 0], [1, 0, 1]),        # singular on y
    ([0, 0, 0], [1, 1, -1]),       # inverted on z
    ([0, 0], [1, 1, 1]),           # wrong shape
    ([0, np.nan, 0], [1, 1, 1]),
    ([0, 0, 0], [1, np.inf, 1]),
], ids=["singular", "inverted", "shape", "nan", "inf"])
def test_bspline_bad_box(bmin, bmax):
    raises_naming(bs(box_min=bmin, box_max=bmax), "box")


def test_bspline_identity_bad_input():
    raises_naming(lambda: smoothffd.BSplineLattice.identity([0, 0, 0], [1, 1, 0]), "box")
    raises_naming(lambda: smoothffd.BSplineLattice.identity([0, 0, 0], [1, 1, 1], shape=(2, 5, 5),
                                                            degree=(2, 2, 2)), "shape", "degree")
    raises_naming(lambda: smoothffd.BSplineLattice.identity([0, 0, 0], [1, 1, 1],
                                                            degree=(2, 0, 2)), "degree")


def test_bspline_evaluate_bad_points():
    lat = bs()()
    raises_naming(lambda: lat.evaluate(np.zeros((4, 2))), "points")
    raises_naming(lambda: lat.evaluate(np.array([[0.0, np.nan, 0.0]])), "points")


REST = ref.blender_rest((3, 3, 2))


def bl(**over):
    kw = dict(rest_points=REST, points=REST * 1.1, interpolation=("BSPLINE",) * 3,
              lattice_to_object=np.eye(4), strength=1.0)
    kw.update(over)
    return lambda: smoothffd.BlenderLattice(**kw)


def test_blender_good_baseline_constructs():
    bl()()


@pytest.mark.parametrize("arr", [REST[..., :2], REST[0], REST.reshape(-1, 3)],
                         ids=["coords2", "ndim3", "flat"])
def test_blender_bad_rest_shape(arr):
    raises_naming(bl(rest_points=arr, points=arr), "rest_points", "points")


def test_blender_points_shape_mismatch():
    raises_naming(bl(points=ref.blender_rest((3, 3, 3))), "points")
    raises_naming(bl(points=REST[..., :2]), "points")


@pytest.mark.parametrize("which", ["rest_points", "points"])
def test_blender_nonfinite_points(which):
    arr = REST.copy()
    arr[1, 1, 1, 2] = np.nan
    raises_naming(bl(**{which: arr}), which)


def test_blender_degenerate_rest_grid():
    rest = REST.copy()
    rest[..., 0] = 0.25  # three points along u, all at the same place: spacing 0
    raises_naming(bl(rest_points=rest, points=rest), "rest_points")


@pytest.mark.parametrize("interp", [("BSPLINE", "BSPLINE", "CUBIC"), ("",) * 3,
                                    ("BSPLINE", "BSPLINE"), ("LINEAR",) * 4, (1, 2, 3)], ids=str)
def test_blender_bad_interpolation(interp):
    raises_naming(bl(interpolation=interp), "interpolation")


@pytest.mark.parametrize("m", [
    np.zeros((4, 4)),
    np.diag([1.0, 1.0, 0.0, 1.0]),
    ref.affine(np.array([[1.0, 2, 3], [2, 4, 6], [0, 0, 1]]), [0, 0, 0]),  # rank 2
    np.eye(3),
    np.eye(4)[:3],
    np.full((4, 4), np.nan),
], ids=["zeros", "flat-z", "rank2", "3x3", "3x4", "nan"])
def test_blender_bad_lattice_to_object(m):
    raises_naming(bl(lattice_to_object=m), "lattice_to_object")


def test_is_singular_is_relative_to_the_matrix_scale():
    """smoothffd.lattice.is_singular, the one singular-placement check (BlenderLattice and the
    Blender add-on): the determinant of the matrix scaled by its largest entry against 1e-12,
    so a uniform scale of 1e-20 or 1e200 is regular, one axis 1e-13 of the others is not."""
    is_singular = smoothffd.lattice.is_singular
    for scale in (1e-20, 1.0, 1e200):
        assert not is_singular(np.diag([scale, scale, scale, 1.0]))
    assert not is_singular(np.diag([1.0, 1.0, 1e-4, 1.0]))          # det(m / 1) = 1e-4
    for m in (np.zeros((4, 4)), np.diag([1.0, 1.0, 1e-13, 1.0]), np.full((4, 4), np.nan)):
        assert is_singular(m)
    raises_naming(bl(lattice_to_object=np.diag([1.0, 1.0, 1e-13, 1.0])), "lattice_to_object")


@pytest.mark.parametrize("s", [np.nan, np.inf, "strong", [1.0, 2.0]], ids=str)
def test_blender_bad_strength(s):
    raises_naming(bl(strength=s), "strength")


def test_blender_evaluate_bad_points():
    lat = bl()()
    raises_naming(lambda: lat.evaluate(np.zeros((4, 2))), "points")
    raises_naming(lambda: lat.evaluate(np.array([[0.0, np.inf, 0.0]])), "points")
    raises_naming(lambda: lat.with_points(REST[:2]), "points")
