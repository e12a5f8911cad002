"""The two lattice kinds: the paper's B-spline volume and Blender's Lattice modifier.

Both reduce to F(p) = p + sum_ijk W_ijk(s(p)) D_ijk with s(p) = A p + b an affine map into the
lattice's parameter space and W a tensor product of three per-axis piecewise polynomials (built
natively, `native/smoothffd/lattice/axis_basis.cpp`). A lattice object holds the *structure*
(what a plan depends on) and the control values D (what changes every frame).
"""

import copy

import numpy as np

from . import _core
from ._validate import finite_float, float_array, int_triple
from .lattice_json import INTERPOLATIONS


def is_singular(matrix):
    """Whether the linear part (the upper-left 3x3) of a transform cannot be inverted: its
    determinant, scaled by its largest entry (no overflow at 1e200), is at most 1e-12. The one
    check of a singular placement: BlenderLattice's lattice_to_object, and the Blender add-on's
    object matrix."""
    m = np.asarray(matrix, dtype=np.float64)[:3, :3]
    scale = np.abs(m).max()
    return not (scale > 0 and abs(np.linalg.det(m / scale)) > 1e-12)


class _Lattice:
    """Shared evaluation API; subclasses set `_spec`, `_values`, `_key`."""

    def evaluate(self, points):
        """Position and Jacobian of the deformation at `points` (N, 3), in float64.

        Returns `(positions (N, 3), jacobians (N, 3, 3))` with `jacobians[n, r, c] = dF_r/dp_c`.
        """
        pts = float_array(points, "points")
        if pts.ndim == 1 and pts.shape == (3,):
            pts = pts[None, :]
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points: expected shape (N, 3), got {pts.shape}")
        return self._spec.evaluate(pts, self._core_values(), np.ones(len(pts)))

    def _core_values(self):
        """(nu*nv*nw, C) float64: the control values as the core takes them (C = 3, or 4 for
        a BlenderLattice with point weights)."""
        return self._values.reshape(-1, 3)

    def _check_pieces(self, name):
        """The core numbers a sample's knot span in 10 bits an axis (build_plan: at most 1023)."""
        for a, n in enumerate(self._spec.piece_counts):
            if n > 1023:
                raise ValueError(f"{name}: axis {'uvw'[a]} has {n} knot spans (polynomial pieces); "
                                 "the core handles at most 1023 an axis")

    def knot_planes(self):
        """Per axis, the values c of the planes s_a(p) = c where the polynomial piece changes."""
        return list(self._spec.planes())

    @property
    def object_to_param(self):
        """(3, 4) affine map from object space to the lattice's parameter space."""
        return self._map.copy()

    @property
    def degrees(self):
        """Polynomial degree of each axis (their sum is the exact patch degree, paper sec. 3)."""
        return tuple(self._spec.degrees)

    @property
    def shape(self):
        return tuple(self._values.shape[:3])

    def control_values(self):
        """(nu, nv, nw, 3) displacements D_ijk."""
        return self._values.copy()

    def structure_key(self):
        """Hashable; lattices with equal keys share a plan (only their values differ)."""
        return self._key

    def basis_key(self):
        """Hashable; lattices with equal keys differ at most in their values and in where they
        lie (object_to_param: a lattice that moves, turns or scales with a bone): a plan follows
        from one to the other (Deformer.follow)."""
        return self._basis_key


def _finite(name, what, compute):
    """compute() in float64 without overflow warnings; a ValueError naming `name` where the
    result is not finite (values near the float64 limit, e.g. points at 1e308 - -1e308)."""
    with np.errstate(over="ignore", invalid="ignore", divide="ignore", under="ignore"):
        value = compute()
    if not np.isfinite(value).all():
        raise ValueError(f"{name}: {what} is beyond float64 range (values too large)")
    return value


def _open_uniform_knots(degree, count):
    inner = np.linspace(0.0, 1.0, count - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


class BSplineLattice(_Lattice):
    """The paper's B-spline volume R(u, v, w) (Eq. 1) embedded in an axis-aligned box.

    control_points: (nu, nv, nw, 3) in object space, index [i, j, k] along u, v, w.
    degree: per axis, 1..5. knots: None (open uniform, clamped) or three non-decreasing arrays
    of nu + degree + 1 (...) values. The box [box_min, box_max] maps affinely onto the knot
    domain [knots[p], knots[n]] (default: the bounding box of the control points). Outside the
    box the displacement of the nearest box point continues, as Blender does outside a lattice.
    """

    def __init__(self, control_points, degree=(2, 2, 2), knots=None, box_min=None, box_max=None):
        cp = float_array(control_points, "control_points", shape=(None, None, None, 3))
        self.degree = int_triple(degree, "degree", 1, 5)
        counts = cp.shape[:3]
        for a in range(3):
            if counts[a] < self.degree[a] + 1:
                raise ValueError(
                    f"control_points: axis {a} has {counts[a]} points, degree {self.degree[a]} "
                    f"needs at least {self.degree[a] + 1}")
        if knots is None:
            kv = [_open_uniform_knots(self.degree[a], counts[a]) for a in range(3)]
        else:
            if len(knots) != 3:
                raise ValueError("knots: expected three knot vectors (u, v, w) or None")
            kv = []
            for a in range(3):
                k = float_array(knots[a], f"knots[{a}]", shape=(None,))
                want = counts[a] + self.degree[a] + 1
                if len(k) != want:
                    raise ValueError(f"knots[{a}]: expected {want} values "
                                     f"(points + degree + 1), got {len(k)}")
                if np.any(k[1:] < k[:-1]):  # not np.diff: -1e308 .. 1e308 overflows
                    raise ValueError(f"knots[{a}]: must be non-decreasing")
                if not k[self.degree[a]] < k[counts[a]]:
                    raise ValueError(f"knots[{a}]: the domain [knots[p], knots[n]] is empty")
                kv.append(k)
        self.knots = None if knots is None else [k.copy() for k in kv]
        if box_min is None or box_max is None:
            flat = cp.reshape(-1, 3)
            bmin = flat.min(axis=0) if box_min is None else float_array(box_min, "box_min", (3,))
            bmax = flat.max(axis=0) if box_max is None else float_array(box_max, "box_max", (3,))
        else:
            bmin = float_array(box_min, "box_min", (3,))
            bmax = float_array(box_max, "box_max", (3,))
        if np.any(bmax <= bmin):
            raise ValueError(f"box_min/box_max: the box is empty or singular ({bmin} .. {bmax})")
        self.box_min, self.box_max = bmin, bmax
        self.control_points = cp
        self._kv = kv
        lo = np.array([kv[a][self.degree[a]] for a in range(3)])
        hi = np.array([kv[a][counts[a]] for a in range(3)])
        scale = _finite("box_min/box_max", "the map from the box onto the knot domain",
                        lambda: (hi - lo) / (bmax - bmin))
        if not (scale > 0).all():
            raise ValueError("box_min/box_max: the map from the box onto the knot domain "
                             "underflows (a box far larger than its knot domain)")
        self._map = np.zeros((3, 4))
        for a in range(3):
            self._map[a, a] = scale[a]
            self._map[a, 3] = _finite("box_min/box_max", "the map from the box onto the knot domain",
                                      lambda: lo[a] - bmin[a] * scale[a])
        self._greville = _finite("box_min/box_max", "the rest lattice (Greville points in the box)",
                                 lambda: self._greville_points(kv, counts, lo, hi, bmin, bmax))
        self._values = _finite("control_points", "control_points - rest lattice",
                               lambda: cp - self._greville)
        self._spec = _core.LatticeSpec.bspline(list(self.degree), kv, list(counts), self._map)
        self._check_pieces("control_points")
        self._basis_key = ("bspline", self.degree, counts, tuple(tuple(k) for k in kv))
        self._key = self._basis_key + (tuple(bmin), tuple(bmax))

    def _greville_points(self, kv, counts, lo, hi, bmin, bmax):
        axes = []
        for a in range(3):
            p, k = self.degree[a], kv[a]
            xi = np.array([k[i + 1:i + p + 1].mean() for i in range(counts[a])])
            axes.append(bmin[a] + (xi - lo[a]) / (hi[a] - lo[a]) * (bmax[a] - bmin[a]))
        g = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
        return g

    @classmethod
    def identity(cls, box_min, box_max, shape=(5, 5, 5), degree=(2, 2, 2), knots=None):
        """The lattice whose deformation is exactly the identity (points at the Greville
        abscissae of the knots, mapped into the box)."""
        shape = int_triple(shape, "shape", 2, 1000)
        bmin = float_array(box_min, "box_min", (3,))
        bmax = float_array(box_max, "box_max", (3,))
        placeholder = np.zeros(tuple(shape) + (3,))
        lat = cls(placeholder, degree=degree, knots=knots, box_min=bmin, box_max=bmax)
        return cls(lat._greville, degree=degree, knots=knots, box_min=bmin, box_max=bmax)

    def with_control_points(self, control_points):
        """Same structure (degree, knots, box), new control points.

        The per-frame path: only the new points are checked and converted; the structure
        (knots, Greville points, the core's lattice spec) is shared with this lattice."""
        cp = float_array(control_points, "control_points", shape=self.control_points.shape)
        lat = copy.copy(self)
        lat.control_points = cp
        lat._values = _finite("control_points", "control_points - rest lattice", lambda: cp - self._greville)
        return lat

    with_points = with_control_points

    @property
    def rest_points(self):
        """The identity lattice's control points (Greville abscissae in the box)."""
        return self._greville.copy()


class BlenderLattice(_Lattice):
    """Exactly what Blender's Lattice modifier computes (docs/algorithm.md, "Blender's Lattice modifier, exactly").

    rest_points / points: (nu, nv, nw, 3) in lattice space (LatticePoint.co / co_deform, or
    the evaluated lattice's points), index [u, v, w]. interpolation: per axis LINEAR,
    CARDINAL, CATMULL_ROM or BSPLINE. lattice_to_object: the 4x4 matrix M^-1 L (deformed
    object's world matrix inverse times the lattice object's). strength scales the
    displacement as the modifier's Strength does.

    point_weights: None, or (nu, nv, nw) finite weights, index [u, v, w] as the points: the
    lattice's vertex group (Lattice.vertex_group; a point not in the group weighs 0). Blender
    then blends each vertex toward its deformed position by the weights interpolated with
    the lattice's own basis, s(p) = sum W(p) w_ijk, its per-vertex factor f (strength times
    the mesh's vertex-group weight) entering both sums: p' = p + f^2 s(p) d(p), where
    p' = p + f d(p) without weights (docs/algorithm.md).
    """

    def __init__(self, rest_points, points, interpolation=("BSPLINE",) * 3,
                 lattice_to_object=np.eye(4), strength=1.0, point_weights=None):
        rest = float_array(rest_points, "rest_points", shape=(None, None, None, 3))
        pts = float_array(points, "points", shape=(None, None, None, 3))
        if pts.shape != rest.shape:
            raise ValueError(f"points: shape {pts.shape} differs from rest_points {rest.shape}")
        if min(rest.shape[:3]) < 1:
            raise ValueError("rest_points: every axis needs at least one point")
        if isinstance(interpolation, str):
            interpolation = (interpolation,) * 3
        try:
            interp = tuple(str(t).upper().replace("KEY_", "") for t in interpolation)
        except TypeError:
            raise TypeError("interpolation: expected a name or three names") from None
        if len(interp) != 3 or any(t not in INTERPOLATIONS for t in interp):
            raise ValueError(f"interpolation: expected three of {INTERPOLATIONS}, got {interpolation!r}")
        m = float_array(lattice_to_object, "lattice_to_object", shape=(4, 4))
        if not np.allclose(m[3], [0, 0, 0, 1]):
            raise ValueError("lattice_to_object: the last row must be (0, 0, 0, 1)")
        if is_singular(m):
            raise ValueError("lattice_to_object: the matrix is singular")
        self.strength = finite_float(strength, "strength")
        self.rest_points, self.points = rest, pts
        self.point_weights = None if point_weights is None else self._weights(point_weights)
        self._lw = None if point_weights is None else self._scaled_weights(self.point_weights)
        self.interpolation = interp
        self.lattice_to_object = m
        counts = rest.shape[:3]
        inv = np.linalg.inv(m)
        self._map = np.zeros((3, 4))
        for a in range(3):
            if counts[a] == 1:
                continue  # a one-point axis contributes the constant weight 1
            f = rest[0, 0, 0, a]
            last = [0, 0, 0]
            last[a] = counts[a] - 1
            with np.errstate(all="ignore"):  # overflow: refused by _finite below
                # Spacing over the whole axis (co = f + i d): rounds less than one step does.
                d = (rest[last[0], last[1], last[2], a] - f) / (counts[a] - 1)
                if not abs(d) > 0:
                    raise ValueError(f"rest_points: axis {a} has zero spacing")
                self._map[a, :3] = inv[a, :3] / d
                self._map[a, 3] = (inv[a, 3] - f) / d
        _finite("rest_points", "the map into lattice space (lattice_to_object inverse / spacing)",
                lambda: self._map)
        self._values = _finite("points", "strength * lattice_to_object (points - rest_points)",
                               lambda: self.strength * np.einsum("rc,uvwc->uvwr", m[:3, :3], pts - rest))
        weighted = self.point_weights is not None
        self._spec = _core.LatticeSpec.blender(list(interp), list(counts), self._map, point_weights=weighted)
        self._check_pieces("points")
        self._basis_key = ("blender", interp, counts, weighted)
        self._key = ("blender", interp, counts, tuple(self._map.ravel()), weighted)

    def _weights(self, point_weights):
        return float_array(point_weights, "point_weights", shape=self.points.shape[:3])

    def _scaled_weights(self, weights):
        # The core's 4th value: the point's weight times the strength (Blender's factor enters
        # the weight sum as it does the displacement sum: compose_weighted_deformation).
        return _finite("point_weights", "strength * point_weights",
                       lambda: self.strength * weights.reshape(-1, 1))

    def _core_values(self):
        values = self._values.reshape(-1, 3)
        if self.point_weights is None:
            return values
        return np.concatenate([values, self._lw], axis=1)

    def with_points(self, points, point_weights=None):
        """Same structure (rest points, interpolation, matrix), new deformed points.

        The per-frame path: only the new points are checked and converted; the structure is
        shared with this lattice. point_weights: new weights for a lattice that has them
        (None keeps the current ones); a lattice without weights takes none (adding them
        changes the structure: build a new BlenderLattice)."""
        pts = float_array(points, "points", shape=self.points.shape)
        if point_weights is not None and self.point_weights is None:
            raise ValueError("point_weights: this lattice has none (its plan evaluates 3 values a "
                             "point); build a new BlenderLattice(..., point_weights=...)")
        weights = None if point_weights is None else self._weights(point_weights)
        lat = copy.copy(self)
        lat.points = pts
        if weights is not None:
            lat.point_weights, lat._lw = weights, self._scaled_weights(weights)
        m = self.lattice_to_object
        lat._values = _finite("points", "strength * lattice_to_object (points - rest_points)",
                              lambda: self.strength * np.einsum("rc,uvwc->uvwr", m[:3, :3], pts - self.rest_points))
        return lat
