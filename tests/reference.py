"""Independent plain-Python / numpy references for the smoothffd lattices.

Written from the formulas (docs/api.md; docs/algorithm.md, "Blender's Lattice modifier,
exactly" and "Normals under a deformation"; the paper's Eq. (1)), deliberately NOT from the core's code, so the tests in
``test_lattices.py`` compare two independent implementations.  Everything is float64 and
deliberately slow and literal (scalar loops); keep point counts modest.

Contents
--------
* :func:`blender_lattice_reference`   -- Blender's Lattice modifier, transcribed literally.
* :func:`blender_lattice_jacobian_reference` -- its analytic Jacobian (chain rule).
* :func:`bspline_volume_reference`    -- B-spline volume (Cox-de Boor) with box embedding,
  displacement continued outside the box; ``with_jacobian=True`` adds the analytic Jacobian.
* :func:`identity_control_points`     -- control points at the Greville abscissae.
* :func:`jacobian_fd`                 -- central finite differences.
* :func:`dense_exact_ffd`             -- exact FFD of flat triangles on a dense barycentric
  grid, exact normals via the cofactor of the Jacobian.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np

__all__ = [
    "BLENDER_TYPES",
    "blender_weights",
    "blender_weights_derivative",
    "blender_lattice_reference",
    "blender_lattice_jacobian_reference",
    "BlenderReference",
    "clamped_knots",
    "bspline_basis",
    "bspline_basis_derivative",
    "bspline_volume_reference",
    "BSplineReference",
    "greville_abscissae",
    "identity_control_points",
    "jacobian_fd",
    "cofactor",
    "barycentric_grid",
    "exact_at",
    "dense_exact_ffd",
    "mesh_volume",
    "face_normals_of_polygons",
    "smooth_ffd_errors",
    "rotation",
    "affine",
    "blender_rest",
    "cube_triangles",
]

# ---------------------------------------------------------------------------------------------
# (a) Blender's Lattice modifier (docs/algorithm.md, "Blender's Lattice modifier, exactly")
# ---------------------------------------------------------------------------------------------

BLENDER_TYPES = ("LINEAR", "CARDINAL", "CATMULL_ROM", "BSPLINE")

# Points within this relative distance of a lattice's outer boundary count as on it (for the
# choice of one-sided Jacobian only; positions are continuous there).
BOUNDARY_EPS = 1e-12


def _cardinal(t, fc):
    return (
        -fc * t**3 + 2 * fc * t**2 - fc * t,
        (2 - fc) * t**3 + (fc - 3) * t**2 + 1,
        (fc - 2) * t**3 + (3 - 2 * fc) * t**2 + fc * t,
        fc * t**3 - fc * t**2,
    )


def _cardinal_dt(t, fc):
    return (
        -3 * fc * t**2 + 4 * fc * t - fc,
        3 * (2 - fc) * t**2 + 2 * (fc - 3) * t,
        3 * (fc - 2) * t**2 + 2 * (3 - 2 * fc) * t + fc,
        3 * fc * t**2 - 2 * fc * t,
    )


def blender_weights(t, kind):
    """The table ``key_curve_position_weights(t, type)``: weights for i0-1, i0, i0+1, i0+2."""
    t = float(t)
    if kind == "LINEAR":
        return (0.0, 1.0 - t, t, 0.0)
    if kind == "CARDINAL":
        return _cardinal(t, 0.71)
    if kind == "CATMULL_ROM":
        return _cardinal(t, 0.5)
    if kind == "BSPLINE":
        return (
            -t**3 / 6 + t**2 / 2 - t / 2 + 1.0 / 6,
            t**3 / 2 - t**2 + 2.0 / 3,
            -t**3 / 2 + t**2 / 2 + t / 2 + 1.0 / 6,
            t**3 / 6,
        )
    raise ValueError(f"interpolation: unknown type {kind!r}")


def blender_weights_derivative(t, kind):
    """d/dt of :func:`blender_weights`."""
    t = float(t)
    if kind == "LINEAR":
        return (0.0, -1.0, 1.0, 0.0)
    if kind == "CARDINAL":
        return _cardinal_dt(t, 0.71)
    if kind == "CATMULL_ROM":
        return _cardinal_dt(t, 0.5)
    if kind == "BSPLINE":
        return (
            -t**2 / 2 + t - 0.5,
            3 * t**2 / 2 - 2 * t,
            -3 * t**2 / 2 + t + 0.5,
            t**2 / 2,
        )
    raise ValueError(f"interpolation: unknown type {kind!r}")


def _blender_axis_frames(rest_points):
    """Per axis (f, d, n) read from the rest points ``co`` (one point: f = d = 0)."""
    rest = np.asarray(rest_points, dtype=np.float64)
    n = rest.shape[:3]
    frames = []
    for a in range(3):
        if n[a] == 1:
            frames.append((0.0, 0.0, 1))
            continue
        idx_first = [0, 0, 0]
        idx_last = [0, 0, 0]
        idx_last[a] = n[a] - 1
        f = rest[tuple(idx_first)][a]
        d = (rest[tuple(idx_last)][a] - f) / (n[a] - 1)
        frames.append((float(f), float(d), n[a]))
    return frames


def _normalize_interp(interpolation):
    if isinstance(interpolation, str):
        interpolation = (interpolation,) * 3
    interpolation = tuple(interpolation)
    assert len(interpolation) == 3
    return interpolation


def _blender_axis_stencil(q_a, frame, kind):
    """(indices[4], weights[4], dweights_dq[4]) for one axis, literally as in the formula."""
    f, d, n = frame
    if n == 1:  # one point: weights (0, 1, 0, 0) applied to i0-1..i0+2 with i0 = 0
        i0 = 0
        w = (0.0, 1.0, 0.0, 0.0)
        dw = (0.0, 0.0, 0.0, 0.0)
    else:
        s = (q_a - f) / d
        # Closed lattice: a point on (or within rounding of) the first or last lattice plane
        # s = 0, s = n-1 takes the cell inside the lattice, so the Jacobian there is the
        # one-sided inner one.  Positions are the same either way (the weights are continuous);
        # this only matters for LINEAR, the other types are C1.
        eps = BOUNDARY_EPS * max(1.0, float(n))
        if -eps < s < 0.0:
            s = 0.0
        i0 = int(math.floor(s))
        if abs(s - (n - 1)) < eps:
            s, i0 = float(n - 1), n - 2
        t = s - i0
        w = blender_weights(t, kind)
        dw = tuple(x / d for x in blender_weights_derivative(t, kind))
    idx = []
    for k in range(i0 - 1, i0 + 3):
        idx.append(min(max(k, 0), n - 1))  # clamped, boundary points repeated
    return idx, w, dw


def _blender_core(rest_points, points, interpolation, lattice_to_object, strength, p, jac,
                  point_weights=None):
    rest = np.asarray(rest_points, dtype=np.float64)
    lw = None if point_weights is None else np.asarray(point_weights, dtype=np.float64)
    pts = np.asarray(points, dtype=np.float64)
    l2o = np.asarray(lattice_to_object, dtype=np.float64)
    interp = _normalize_interp(interpolation)
    o2l = np.linalg.inv(l2o)
    r3 = l2o[:3, :3]
    disp = (pts - rest) @ r3.T  # D = R3 (points - rest), shape (nu, nv, nw, 3)
    frames = _blender_axis_frames(rest)
    p = np.asarray(p, dtype=np.float64)
    single = p.ndim == 1
    P = np.atleast_2d(p)
    out = np.empty_like(P)
    jout = np.empty((P.shape[0], 3, 3))
    for n_, x in enumerate(P):
        q = o2l[:3, :3] @ x + o2l[:3, 3]
        st = [_blender_axis_stencil(q[a], frames[a], interp[a]) for a in range(3)]
        (iu, wu, du), (iv, wv, dv), (iw, ww, dw) = st
        acc = np.zeros(3)
        dacc_dq = np.zeros((3, 3))  # d(sum)/dq
        sacc = 0.0                  # lattice vertex group: sum of W * point weight
        dsacc_dq = np.zeros(3)
        for a in range(4):
            for b in range(4):
                for c in range(4):
                    D = disp[iu[a], iv[b], iw[c]]
                    acc += wu[a] * wv[b] * ww[c] * D
                    if lw is not None:
                        L = lw[iu[a], iv[b], iw[c]]
                        sacc += wu[a] * wv[b] * ww[c] * L
                    if jac:
                        dacc_dq[:, 0] += du[a] * wv[b] * ww[c] * D
                        dacc_dq[:, 1] += wu[a] * dv[b] * ww[c] * D
                        dacc_dq[:, 2] += wu[a] * wv[b] * dw[c] * D
                        if lw is not None:
                            dsacc_dq += np.array([du[a] * wv[b] * ww[c], wu[a] * dv[b] * ww[c],
                                                  wu[a] * wv[b] * dw[c]]) * L
        if lw is None:
            out[n_] = x + strength * acc
            if jac:
                jout[n_] = np.eye(3) + strength * dacc_dq @ o2l[:3, :3]
            continue
        # BKE_lattice_deform_data_eval_co with lattice_weights: co accumulates
        # u * latticedata and weight_blend u * lattice_weights, u carrying the factor
        # (strength); then co = interp(co_prev, co, weight_blend).
        co = x + strength * acc
        weight_blend = strength * sacc
        out[n_] = x + weight_blend * (co - x)
        if jac:
            dq_dp = o2l[:3, :3]
            jout[n_] = np.eye(3) + strength ** 2 * (sacc * dacc_dq @ dq_dp
                                                    + np.outer(acc, dsacc_dq @ dq_dp))
    if single:
        return (out[0], jout[0]) if jac else out[0]
    return (out, jout) if jac else out


def blender_lattice_reference(rest_points, points, interpolation, lattice_to_object, strength, p,
                              point_weights=None):
    """p' for points p (3,) or (N, 3) in the deformed object's local space.

    ``lattice_to_object`` is M^-1 L; q = inverse(lattice_to_object) p.  Arrays are
    (nu, nv, nw, 3) indexed [u, v, w]; ``interpolation`` a type name or a triple of them.
    ``point_weights``: None or (nu, nv, nw), the lattice's vertex group (Blender's
    lattice_deform.cc: weight_blend, then interp_v3_v3v3).
    """
    return _blender_core(rest_points, points, interpolation, lattice_to_object, strength, p,
                         jac=False, point_weights=point_weights)


def blender_lattice_jacobian_reference(rest_points, points, interpolation, lattice_to_object,
                                       strength, p, point_weights=None):
    """(p', J) with the analytic Jacobian J = I + strength * dD/dq * dq/dp (with point weights
    the product rule on strength^2 s(q) D(q))."""
    return _blender_core(rest_points, points, interpolation, lattice_to_object, strength, p,
                         jac=True, point_weights=point_weights)


class BlenderReference:
    """Object wrapper: ``evaluate(p) -> (positions, jacobians)`` like the core's lattices."""

    def __init__(self, rest_points, points, interpolation=("BSPLINE",) * 3,
                 lattice_to_object=np.eye(4), strength=1.0, point_weights=None):
        self.args = (rest_points, points, interpolation, lattice_to_object, strength)
        self.point_weights = point_weights

    def __call__(self, p):
        return blender_lattice_reference(*self.args, p, point_weights=self.point_weights)

    def evaluate(self, p):
        pos, jac = blender_lattice_jacobian_reference(*self.args, np.atleast_2d(p),
                                                      point_weights=self.point_weights)
        return pos, jac


# ---------------------------------------------------------------------------------------------
# (b) B-spline volume, Eq. (1), Cox-de Boor
# ---------------------------------------------------------------------------------------------


def clamped_knots(n, degree):
    """Open-uniform (clamped) knot vector on [0, 1] for n control points."""
    if n < degree + 1:
        raise ValueError("too few control points for the degree")
    inner = [i / (n - degree) for i in range(1, n - degree)]
    return np.array([0.0] * (degree + 1) + inner + [1.0] * (degree + 1))


def _span(knots, n, degree, u):
    """Index k in [degree, n-1] with knots[k] <= u < knots[k+1] (last non-empty span at the end)."""
    lo, hi = knots[degree], knots[n]
    if u >= hi:
        k = n - 1
        while knots[k] >= knots[k + 1]:
            k -= 1
        return k
    if u < lo:
        u = lo
    for k in range(n - 1, degree - 1, -1):
        if knots[k] <= u and knots[k] < knots[k + 1]:
            return k
    raise AssertionError("no span")  # pragma: no cover


def _basis_table(knots, n, degree, u):
    """N[p][i] for p = 0..degree, i = 0..(len(knots)-p-2), scalar Cox-de Boor recursion."""
    m = len(knots)
    k = _span(knots, n, degree, u)
    table = [[1.0 if i == k else 0.0 for i in range(m - 1)]]
    for p in range(1, degree + 1):
        prev = table[-1]
        row = []
        for i in range(m - p - 1):
            val = 0.0
            den = knots[i + p] - knots[i]
            if den > 0.0:
                val += (u - knots[i]) / den * prev[i]
            den = knots[i + p + 1] - knots[i + 1]
            if den > 0.0:
                val += (knots[i + p + 1] - u) / den * prev[i + 1]
            row.append(val)
        table.append(row)
    return table


def bspline_basis(knots, n, degree, u):
    """[N_{i,degree}(u) for i in range(n)]."""
    knots = [float(x) for x in knots]
    return np.array(_basis_table(knots, n, degree, float(u))[degree][:n])


def bspline_basis_derivative(knots, n, degree, u):
    """[N'_{i,degree}(u) for i in range(n)] via N' = p/(t_{i+p}-t_i) N_{i,p-1} - ..."""
    knots = [float(x) for x in knots]
    table = _basis_table(knots, n, degree, float(u))
    prev = table[degree - 1]
    p = degree
    out = []
    for i in range(n):
        val = 0.0
        den = knots[i + p] - knots[i]
        if den > 0.0:
            val += p / den * prev[i]
        den = knots[i + p + 1] - knots[i + 1]
        if den > 0.0:
            val -= p / den * prev[i + 1]
        out.append(val)
    return np.array(out)


def _check_knots(knots, shape, degree):
    deg = tuple(int(d) for d in np.broadcast_to(np.asarray(degree), (3,)))
    if knots is None:
        kv = [clamped_knots(shape[a], deg[a]) for a in range(3)]
    else:
        kv = [np.asarray(k, dtype=np.float64) for k in knots]
    for a in range(3):
        assert len(kv[a]) == shape[a] + deg[a] + 1, "wrong knot count"
        assert np.all(np.diff(kv[a]) >= 0), "knots must be non-decreasing"
        assert kv[a][shape[a]] > kv[a][deg[a]], "empty knot domain"
    return deg, kv


def _bspline_core(control_points, degree, knots, box_min, box_max, p, jac):
    cp = np.asarray(control_points, dtype=np.float64)
    shape = cp.shape[:3]
    deg, kv = _check_knots(knots, shape, degree)
    bmin = np.asarray(box_min, dtype=np.float64)
    bmax = np.asarray(box_max, dtype=np.float64)
    ext = bmax - bmin
    lo = np.array([kv[a][deg[a]] for a in range(3)])
    hi = np.array([kv[a][shape[a]] for a in range(3)])
    scale = (hi - lo) / ext  # ds/dp per axis
    p = np.asarray(p, dtype=np.float64)
    single = p.ndim == 1
    P = np.atleast_2d(p)
    out = np.empty_like(P)
    jout = np.empty((P.shape[0], 3, 3))
    for n_, x in enumerate(P):
        c = np.minimum(np.maximum(x, bmin), bmax)  # nearest box point
        # closed box: on the boundary (or within rounding of it) the one-sided derivative from
        # inside is used, so the tangential derivatives on a face lying on the box boundary are
        # the in-box ones
        tol = BOUNDARY_EPS * np.maximum(ext, np.maximum(np.abs(bmin), np.abs(bmax)))
        inside = (x >= bmin - tol) & (x <= bmax + tol)
        s = lo + (c - bmin) * scale
        N = [bspline_basis(kv[a], shape[a], deg[a], s[a]) for a in range(3)]
        R = np.einsum("i,j,k,ijkd->d", N[0], N[1], N[2], cp)
        out[n_] = x + (R - c)
        if jac:
            dN = [bspline_basis_derivative(kv[a], shape[a], deg[a], s[a]) for a in range(3)]
            JR = np.empty((3, 3))
            JR[:, 0] = np.einsum("i,j,k,ijkd->d", dN[0], N[1], N[2], cp) * scale[0]
            JR[:, 1] = np.einsum("i,j,k,ijkd->d", N[0], dN[1], N[2], cp) * scale[1]
            JR[:, 2] = np.einsum("i,j,k,ijkd->d", N[0], N[1], dN[2], cp) * scale[2]
            # F = p + R(c) - c, dc/dp = diag(inside)
            jout[n_] = np.eye(3) + (JR - np.eye(3)) * inside[None, :].astype(float)
    if single:
        return (out[0], jout[0]) if jac else out[0]
    return (out, jout) if jac else out


def bspline_volume_reference(control_points, degree, knots, box_min, box_max, p,
                             with_jacobian=False):
    """F(p) of the B-spline volume R (Eq. 1), box [box_min, box_max] mapped affinely onto the
    knot domain [knots[deg], knots[n]] per axis; ``knots=None``: clamped open-uniform.

    Outside the box: F(p) = p + (R(c) - c) with c = p clamped to the box.
    ``with_jacobian``: return (F, dF/dp) with the analytic Jacobian.
    """
    return _bspline_core(control_points, degree, knots, box_min, box_max, p, with_jacobian)


class BSplineReference:
    def __init__(self, control_points, degree=(2, 2, 2), knots=None, box_min=None, box_max=None):
        self.args = (control_points, degree, knots, box_min, box_max)

    def __call__(self, p):
        return bspline_volume_reference(*self.args, p)

    def evaluate(self, p):
        return bspline_volume_reference(*self.args, np.atleast_2d(p), with_jacobian=True)


def greville_abscissae(knots, n, degree):
    knots = np.asarray(knots, dtype=np.float64)
    return np.array([knots[i + 1:i + degree + 1].sum() / degree for i in range(n)])


def identity_control_points(box_min, box_max, shape=(5, 5, 5), degree=(2, 2, 2), knots=None):
    """Control points at the Greville abscissae mapped into the box: R(s(p)) == p."""
    shape = tuple(int(s) for s in shape)
    deg, kv = _check_knots(knots, shape, degree)
    bmin = np.asarray(box_min, dtype=np.float64)
    bmax = np.asarray(box_max, dtype=np.float64)
    coords = []
    for a in range(3):
        g = greville_abscissae(kv[a], shape[a], deg[a])
        lo, hi = kv[a][deg[a]], kv[a][shape[a]]
        coords.append(bmin[a] + (g - lo) / (hi - lo) * (bmax[a] - bmin[a]))
    U, V, W = np.meshgrid(*coords, indexing="ij")
    return np.stack([U, V, W], axis=-1)


# ---------------------------------------------------------------------------------------------
# (c) finite differences
# ---------------------------------------------------------------------------------------------


def jacobian_fd(f, p, h=1e-5):
    """Central differences: J[..., r, c] = (f(p + h e_c) - f(p - h e_c))_r / 2h.

    ``f`` maps (3,) -> (3,) or (N, 3) -> (N, 3) (it may also return a tuple whose first item is
    the positions, as ``evaluate`` does).
    """
    p = np.asarray(p, dtype=np.float64)

    def call(x):
        y = f(x)
        if isinstance(y, tuple):
            y = y[0]
        return np.asarray(y, dtype=np.float64)

    cols = []
    for c in range(3):
        e = np.zeros(3)
        e[c] = h
        cols.append((call(p + e) - call(p - e)) / (2 * h))
    return np.stack(cols, axis=-1)


# ---------------------------------------------------------------------------------------------
# (d) dense exact FFD of flat triangles
# ---------------------------------------------------------------------------------------------


def cofactor(J):
    """cof(J) = det(J) J^-T, columns (J2 x J3, J3 x J1, J1 x J2); works on (..., 3, 3)."""
    J = np.asarray(J, dtype=np.float64)
    c1, c2, c3 = J[..., :, 0], J[..., :, 1], J[..., :, 2]
    return np.stack([np.cross(c2, c3), np.cross(c3, c1), np.cross(c1, c2)], axis=-1)


def barycentric_grid(level):
    """Uniform barycentric samples (i/L, j/L, k/L), i+j+k = L, and the L^2 sub-triangles.

    Returns (bary (M, 3), sub_triangles (L^2, 3) indices into bary), M = (L+1)(L+2)/2.
    Sub-triangles are oriented like the parent (corners 0, 1, 2 = weights on P0, P1, P2).
    """
    L = int(level)
    if L < 1:
        raise ValueError("level must be >= 1")
    index = {}
    bary = []
    for j in range(L + 1):  # weight on P1
        for k in range(L + 1 - j):  # weight on P2
            i = L - j - k
            index[(j, k)] = len(bary)
            bary.append((i / L, j / L, k / L))
    tris = []
    for j in range(L):
        for k in range(L - j):
            # "upright" triangle: (j,k) -> (j+1,k) -> (j,k+1): same orientation as P0,P1,P2
            tris.append((index[(j, k)], index[(j + 1, k)], index[(j, k + 1)]))
            if j + k + 2 <= L:
                tris.append((index[(j + 1, k)], index[(j + 1, k + 1)], index[(j, k + 1)]))
    return np.array(bary), np.array(tris, dtype=np.int64)


def exact_at(rest_points, face_normals, lattice_eval):
    """Exact FFD image of points lying on flat faces with unit normals ``face_normals``.

    Returns (positions (N, 3), unit normals (N, 3)) with n' ~ cof(J) n.
    ``lattice_eval(p) -> (positions, jacobians)``, e.g. ``lattice.evaluate``.
    """
    rest_points = np.asarray(rest_points, dtype=np.float64).reshape(-1, 3)
    face_normals = np.asarray(face_normals, dtype=np.float64).reshape(-1, 3)
    pos, jac = lattice_eval(rest_points)
    pos = np.asarray(pos, dtype=np.float64)
    nrm = np.einsum("nrc,nc->nr", cofactor(np.asarray(jac, dtype=np.float64)), face_normals)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pos, nrm


def dense_exact_ffd(tri_positions, lattice_eval, level):
    """Exact FFD of flat triangles sampled on a dense uniform barycentric grid.

    ``tri_positions`` (T, 3, 3): the corners of each flat triangle.  ``lattice_eval(p)`` returns
    (positions, jacobians) for (N, 3) points.  Returns a namespace with

    * ``bary`` (M, 3), ``sub_triangles`` (L^2, 3): the grid (see :func:`barycentric_grid`);
    * ``rest`` (T, M, 3): the sample points on the flat faces;
    * ``face_normals`` (T, 3): unit normals of the flat faces;
    * ``positions`` (T, M, 3): F(rest);
    * ``normals`` (T, M, 3): unit exact normals cof(J) n / |cof(J) n|;
    * ``volume``: signed volume enclosed by the dense deformed triangles (meaningful when the
      input triangles form a closed, outward-oriented surface).
    """
    tri = np.asarray(tri_positions, dtype=np.float64).reshape(-1, 3, 3)
    bary, sub = barycentric_grid(level)
    rest = np.einsum("mk,tkd->tmd", bary, tri)
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    T, M = rest.shape[:2]
    pos, nrm = exact_at(rest.reshape(-1, 3), np.repeat(fn, M, axis=0), lattice_eval)
    pos = pos.reshape(T, M, 3)
    nrm = nrm.reshape(T, M, 3)
    vol = 0.0
    for t in range(T):
        vol += mesh_volume(pos[t], sub)
    return SimpleNamespace(bary=bary, sub_triangles=sub, rest=rest, face_normals=fn,
                           positions=pos, normals=nrm, volume=vol)


def mesh_volume(positions, triangles):
    """Signed volume of a closed triangle mesh by the divergence theorem (float64)."""
    P = np.asarray(positions, dtype=np.float64)
    T = np.asarray(triangles)
    a, b, c = P[T[:, 0]], P[T[:, 1]], P[T[:, 2]]
    return float(np.einsum("nd,nd->n", a, np.cross(b, c)).sum() / 6.0)


def face_normals_of_polygons(positions, faces):
    """Unit normals of the flat input faces (Newell's method).

    ``faces``: (F, 3) triangles or (corner_vertices, face_offsets) as in ``smoothffd.Mesh``."""
    P = np.asarray(positions, dtype=np.float64)
    if isinstance(faces, tuple):
        corners, offsets = (np.asarray(x) for x in faces)
        polys = [corners[offsets[f]:offsets[f + 1]] for f in range(len(offsets) - 1)]
    else:
        polys = list(np.asarray(faces))
    out = np.empty((len(polys), 3))
    for f, poly in enumerate(polys):
        v = P[poly]
        w = np.roll(v, -1, axis=0)
        n = np.array([((v[:, 1] - w[:, 1]) * (v[:, 2] + w[:, 2])).sum(),
                      ((v[:, 2] - w[:, 2]) * (v[:, 0] + w[:, 0])).sum(),
                      ((v[:, 0] - w[:, 0]) * (v[:, 1] + w[:, 1])).sum()])
        out[f] = n / np.linalg.norm(n)
    return out


def smooth_ffd_errors(result, input_face_normals, lattice_eval):
    """Errors of a smooth-FFD ``result`` (smoothffd.Result) against the exact FFD of the flat
    input faces, measured the paper's way (Tables 2-3): distance between corresponding points
    (each output vertex vs F(rest_position)) and angle between corresponding normals (each
    output corner normal vs cof(J) n_face at that corner's rest point).

    Returns a dict: geometry_avg, geometry_max, normal_avg_deg, normal_max_deg, volume
    (signed volume of the output mesh)."""
    pos = np.asarray(result.positions, dtype=np.float64)
    rest = np.asarray(result.rest_positions, dtype=np.float64)
    tris = np.asarray(result.triangles)
    fidx = np.asarray(result.face_index)
    exact, _ = lattice_eval(rest)
    gerr = np.linalg.norm(pos - np.asarray(exact, dtype=np.float64), axis=1)
    fn = np.asarray(input_face_normals, dtype=np.float64)[fidx]  # (T, 3)
    # Each corner's exact normal is taken from the side of its own triangle: the sample point
    # is nudged (1e-6 of the way) towards the triangle's rest centroid, so corners on a knot
    # plane where J jumps (LINEAR, degree 1, repeated knots) or on the box boundary use the
    # Jacobian of the piece the triangle lies in.
    corners = rest[tris]  # (T, 3, 3)
    centroid = corners.mean(axis=1, keepdims=True)
    crest = (corners + 1e-6 * (centroid - corners)).reshape(-1, 3)
    _, nex = exact_at(crest, np.repeat(fn, 3, axis=0), lattice_eval)
    got = np.asarray(result.corner_normals, dtype=np.float64).reshape(-1, 3)
    got = got / np.linalg.norm(got, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.einsum("nd,nd->n", got, nex), -1.0, 1.0)))
    return dict(geometry_avg=float(gerr.mean()), geometry_max=float(gerr.max()),
                normal_avg_deg=float(ang.mean()), normal_max_deg=float(ang.max()),
                volume=mesh_volume(pos, tris))


# ---------------------------------------------------------------------------------------------
# small test helpers
# ---------------------------------------------------------------------------------------------


def rotation(axis, angle):
    """3x3 rotation about ``axis`` by ``angle`` (Rodrigues)."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def affine(A, t):
    """4x4 matrix with linear part A and translation t."""
    M = np.eye(4)
    M[:3, :3] = A
    M[:3, 3] = t
    return M


def blender_rest(shape, lo=-0.5, hi=0.5):
    """Blender-style rest points ``co``: a regular grid from lo to hi (0 on 1-point axes)."""
    lo = np.broadcast_to(np.asarray(lo, dtype=np.float64), (3,))
    hi = np.broadcast_to(np.asarray(hi, dtype=np.float64), (3,))
    axes = [np.linspace(lo[a], hi[a], n) if n > 1 else np.zeros(1) for a, n in enumerate(shape)]
    U, V, W = np.meshgrid(*axes, indexing="ij")
    return np.stack([U, V, W], axis=-1)


def cube_triangles(lo=-1.0, hi=1.0):
    """(12, 3, 3): outward-oriented triangles of the cube [lo, hi]^3."""
    import itertools

    v = np.array(list(itertools.product((lo, hi), repeat=3)), dtype=np.float64)  # 4x+2y+z
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, c, d in quads:
        tris += [(a, b, c), (a, c, d)]
    return v[np.array(tris)]
