"""Error metrics for comparing a smooth FFD result with a dense reference (pure numpy).

The paper (section 6.3, Tables 2-4) reports the geometry error as Euclidean distances
between corresponding vertices, the normal error as angles between corresponding normals, and
the volume error as |v' - v| / v; these functions compute exactly those, in float64.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["ErrorStats", "EdgeReport", "geometry_error", "normal_angle_error",
           "signed_volume", "volume_error", "edge_report", "is_watertight", "radial_error",
           "dense_reference", "reference_errors", "polygon_normals", "flat_faces",
           "triangle_shapes", "Quality", "quality"]


class ErrorStats(NamedTuple):
    """Summary of per-element errors: mean, max and root mean square."""

    mean: float
    max: float
    rms: float

    @classmethod
    def of(cls, values):
        v = np.asarray(values, dtype=np.float64).ravel()
        if v.size == 0:
            return cls(0.0, 0.0, 0.0)
        return cls(float(v.mean()), float(v.max()), float(np.sqrt(np.mean(v * v))))


def _vectors(a, name):
    a = np.asarray(a, dtype=np.float64)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ValueError(f"{name}: expected (..., 3) vectors, got shape {a.shape}")
    return a.reshape(-1, 3)


def geometry_error(positions, reference):
    """Distances between corresponding points. positions, reference (N, 3) -> ErrorStats."""
    p, r = _vectors(positions, "positions"), _vectors(reference, "reference")
    if p.shape != r.shape:
        raise ValueError(f"positions {p.shape} and reference {r.shape} differ in shape")
    return ErrorStats.of(np.linalg.norm(p - r, axis=1))


def normal_angles(normals, reference):
    """Angles in degrees between corresponding vectors, (..., 3) -> (N,). Neither input needs
    unit length. atan2(|a x b|, a.b) stays accurate for tiny angles, where acos(a.b) loses
    about half the digits."""
    a, b = _vectors(normals, "normals"), _vectors(reference, "reference")
    if a.shape != b.shape:
        raise ValueError(f"normals {a.shape} and reference {b.shape} differ in shape")
    cross = np.linalg.norm(np.cross(a, b), axis=1)
    dot = np.einsum("ij,ij->i", a, b)
    return np.degrees(np.arctan2(cross, dot))


def normal_angle_error(normals, reference):
    """Angle error in degrees between corresponding normals (..., 3) -> ErrorStats."""
    return ErrorStats.of(normal_angles(normals, reference))


def _triangles(triangles, n_vertices=None):
    t = np.asarray(triangles)
    if t.ndim != 2 or t.shape[1] != 3 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"triangles: expected (T, 3) integers, got {t.shape} {t.dtype}")
    if n_vertices is not None and t.size and (t.min() < 0 or t.max() >= n_vertices):
        raise ValueError(f"triangles: index out of range [0, {n_vertices})")
    return t.astype(np.int64)


def signed_volume(positions, triangles):
    """Signed volume enclosed by a closed triangle mesh (divergence theorem: the sum of the
    signed tetrahedra (origin, a, b, c)). Positive for outward (counter-clockwise seen from
    outside) orientation. positions (V, 3), triangles (T, 3) -> float."""
    p = _vectors(positions, "positions")
    t = _triangles(triangles, len(p))
    # Centering first makes the sum far less sensitive to cancellation for meshes far from 0.
    c = p.mean(axis=0) if len(p) else np.zeros(3)
    a, b, d = p[t[:, 0]] - c, p[t[:, 1]] - c, p[t[:, 2]] - c
    return float(np.einsum("ij,ij->i", a, np.cross(b, d)).sum() / 6.0)


def volume_error(volume, reference_volume):
    """Relative volume error |v' - v| / |v| (the paper's Table 4)."""
    if reference_volume == 0:
        raise ValueError("reference_volume: 0 (an open or flat surface has no volume to compare)")
    return abs(volume - reference_volume) / abs(reference_volume)


class EdgeReport(NamedTuple):
    """Edge statistics of a triangle mesh.

    edges          number of distinct undirected edges
    boundary       edges used by exactly one triangle
    non_manifold   edges used by three or more triangles
    misoriented    edges used twice in the same direction (inconsistent winding)
    degenerate     triangles that repeat a vertex
    """

    edges: int
    boundary: int
    non_manifold: int
    misoriented: int
    degenerate: int

    @property
    def watertight(self):
        """Closed, manifold and consistently oriented."""
        return self.boundary == 0 and self.non_manifold == 0 and self.misoriented == 0


def edge_report(triangles):
    """Count boundary / non-manifold / misoriented edges of a (T, 3) triangle array."""
    t = _triangles(triangles)
    degenerate = int(((t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 2] == t[:, 0])).sum())
    directed = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    directed = directed[directed[:, 0] != directed[:, 1]]
    if len(directed) == 0:
        return EdgeReport(0, 0, 0, 0, degenerate)
    lo, hi = directed.min(axis=1), directed.max(axis=1)
    n = int(hi.max()) + 1
    key = lo * n + hi  # one int64 per undirected edge
    uniq, inv, count = np.unique(key, return_inverse=True, return_counts=True)
    # In a consistently wound closed surface each edge appears once as (a, b), once as (b, a).
    forward = np.bincount(inv.ravel(), weights=(directed[:, 0] < directed[:, 1]),
                          minlength=len(uniq))
    misoriented = int(((count == 2) & (forward != 1)).sum())
    return EdgeReport(len(uniq), int((count == 1).sum()), int((count >= 3).sum()), misoriented,
                      degenerate)


def is_watertight(triangles):
    """True when every edge has exactly two triangles with opposite directions."""
    return edge_report(triangles).watertight


def radial_error(positions, center, radius):
    """Distance of points from a sphere: | |p - center| - radius |, (N, 3) -> ErrorStats."""
    p = _vectors(positions, "positions")
    c = np.asarray(center, dtype=np.float64).reshape(3)
    return ErrorStats.of(np.abs(np.linalg.norm(p - c, axis=1) - float(radius)))


def dense_reference(lattice, rest_positions, triangles):
    """Exact FFD of a flat-faced rest surface, for comparing with a result.

    lattice         anything with ``evaluate(points) -> (F(p) (N, 3), J (N, 3, 3))``
    rest_positions  (N, 3) points of the undeformed input surface (``Result.rest_positions``)
    triangles       (T, 3) output triangles (``Result.triangles``)

    Returns ``(positions (N, 3), corner_normals (T, 3, 3))``: F at every rest point, and at
    every corner the rest triangle's flat normal mapped by the cofactor of J (Eq. 3,
    ``n' = det(J) J^-T n``), normalized. The flat normal is the exact surface normal only for
    flat-faced inputs (the paper's cube test); elsewhere it is what exact FFD of the polygon
    mesh itself gives.
    """
    rest = _vectors(rest_positions, "rest_positions")
    t = _triangles(triangles, len(rest))
    pos, jac = lattice.evaluate(rest)
    pos = np.asarray(pos, dtype=np.float64)
    jac = np.asarray(jac, dtype=np.float64)
    a, b, c = rest[t[:, 0]], rest[t[:, 1]], rest[t[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    cof = _cofactor(jac)  # (N, 3, 3), cof(J) = det(J) J^-T, defined even where J is singular
    out = np.einsum("tkrc,tc->tkr", cof[t], n)
    out /= np.maximum(np.linalg.norm(out, axis=2, keepdims=True), 1e-300)
    return pos, out


def _cofactor(j):
    """Cofactor matrices of (N, 3, 3): rows are cross products of the other two columns'
    rows, i.e. cof(J) = det(J) J^-T without dividing by det."""
    c0, c1, c2 = j[:, :, 0], j[:, :, 1], j[:, :, 2]
    # cof(J) @ n == (J e1 x J e2) n_0 + (J e2 x J e0) n_1 + (J e0 x J e1) n_2
    return np.stack([np.cross(c1, c2), np.cross(c2, c0), np.cross(c0, c1)], axis=2)


def reference_errors(result, lattice, closed=True):
    """Compare a ``smoothffd.Result`` with exact FFD of its flat rest surface (the paper's
    section 6.3 measures; exact for flat-faced inputs such as its cube).

    Returns a dict: ``geometry`` and ``normal`` (degrees) ErrorStats over all output vertices /
    corners, and when ``closed``: ``volume``, ``reference_volume`` (the exact FFD sampled at
    the output vertices) and ``volume_error`` (relative). The first V output vertices are the
    input vertices, so their geometry error should be ~float32 rounding.
    """
    if getattr(result, "corner_normals", None) is None:
        raise ValueError("result: has no corner_normals (deformed with normals=False); "
                         "reference_errors compares normals too, deform with normals=True")
    ref_pos, ref_nrm = dense_reference(lattice, result.rest_positions, result.triangles)
    out = {"geometry": geometry_error(result.positions, ref_pos),
           "normal": normal_angle_error(result.corner_normals, ref_nrm)}
    if closed:
        v = signed_volume(result.positions, result.triangles)
        v_ref = signed_volume(ref_pos, result.triangles)
        out.update(volume=v, reference_volume=v_ref, volume_error=volume_error(v, v_ref))
    return out


# ----------------------------------------------------------------------------------------
# Output quality on real meshes (`python3 -m smoothffd quality`)


def polygon_normals(positions, corner_vertices, face_offsets):
    """Newell normals of polygons: (F, 3) vectors of twice each face's vector area (not
    normalized). For a triangle, the cross product of its edges; for a non-planar polygon the
    normal Blender and most tools give the face; the sum over any triangulation of the face."""
    p = _vectors(positions, "positions")
    cv = np.asarray(corner_vertices, dtype=np.int64)
    fo = np.asarray(face_offsets, dtype=np.int64)
    nxt = np.arange(len(cv)) + 1
    ends = fo[1:] - 1
    nxt[ends] = fo[:-1]  # the last corner of each face wraps to its first
    a, b = p[cv], p[cv[nxt]]
    terms = np.cross(a - p[cv[fo[:-1]]].repeat(np.diff(fo), axis=0),
                     b - p[cv[fo[:-1]]].repeat(np.diff(fo), axis=0))
    face = np.repeat(np.arange(len(fo) - 1), np.diff(fo))
    out = np.zeros((len(fo) - 1, 3))
    np.add.at(out, face, terms)
    return out


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _corner_normals_of(mesh):
    """The mesh's corner normals, or the smooth area-weighted vertex normals the core
    computes when it has none."""
    if mesh.corner_normals is not None:
        return _unit(mesh.corner_normals)
    fn = polygon_normals(mesh.positions, mesh.corner_vertices, mesh.face_offsets)
    vn = np.zeros((len(mesh.positions), 3))
    face = np.repeat(np.arange(len(fn)), np.diff(mesh.face_offsets))
    np.add.at(vn, mesh.corner_vertices, fn[face])
    return _unit(vn[mesh.corner_vertices])


def flat_faces(mesh, angle_degrees=1.0):
    """Faces whose split normals say they are flat: every corner carries the face's own
    (Newell) normal, within `angle_degrees` (the core's sharp angle). (F,) bool."""
    fn = _unit(polygon_normals(mesh.positions, mesh.corner_vertices, mesh.face_offsets))
    face = np.repeat(np.arange(len(fn)), np.diff(mesh.face_offsets))
    cos = np.einsum("ij,ij->i", _corner_normals_of(mesh), fn[face])
    ok = cos >= np.cos(np.radians(angle_degrees))
    return np.logical_and.reduceat(ok, np.asarray(mesh.face_offsets[:-1], dtype=np.int64)) & \
        (np.linalg.norm(fn, axis=1) > 0)


def triangle_shapes(positions, triangles):
    """Per triangle: area, smallest angle (degrees) and aspect ratio, longest edge squared
    * sqrt(3) / (4 area) (1 for an equilateral triangle, inf for a degenerate one)."""
    p = _vectors(positions, "positions")
    t = _triangles(triangles, len(p))
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    e = np.stack([b - a, c - b, a - c], axis=1)          # edge k: corner k -> k + 1
    l2 = np.einsum("tki,tki->tk", e, e)
    area = 0.5 * np.linalg.norm(np.cross(e[:, 0], -e[:, 2]), axis=1)
    # angle at corner k between edges k (out) and k - 1 (in, reversed): atan2 is accurate
    out_e, in_e = e, -np.roll(e, 1, axis=1)
    cr = np.linalg.norm(np.cross(out_e, in_e), axis=2)
    dt = np.einsum("tki,tki->tk", out_e, in_e)
    ang = np.degrees(np.arctan2(cr, dt)).min(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        aspect = np.where(area > 0, l2.max(axis=1) * np.sqrt(3.0) / (4.0 * area), np.inf)
    return area, ang, aspect


class Quality(NamedTuple):
    """Quality of a result on its input (``quality``). Lengths are relative to the input's
    bounding-box diagonal (``size``), areas to its square.

    triangles       output triangles
    reversed        output triangles whose geometric normal points against their normal
                    field: (b - a) x (c - a) has a negative dot product with the mean of the
                    triangle's three corner normals
    degenerate      output triangles of zero area
    tiny            output triangles of area under 1e-8 (relative)
    min_angle       smallest angle of any output triangle, degrees
    max_aspect      largest aspect ratio (longest edge^2 sqrt(3) / (4 area); 1: equilateral)
    flat_faces      input faces that the split normals say are flat (``flat_faces``)
    flat_deviation  largest distance of an output vertex of a flat face from the exact FFD
                    of the flat input (the identity for ``lattice=None``), across the surface:
                    (x - F(p)) . n' with n' the deformed unit normal of the input triangle at
                    p (Eq. 3); at rest, the distance from the triangle's plane
    flat_slide      the same, the whole distance |x - F(p)| (also along the surface: where a
                    flat face meets a smooth one, the shared crease curves within the flat
                    face's plane)
    volume_change   (output volume - volume of the exact FFD of the flat input) / the
                    latter, None for an output that is not closed
    against_face    input corners whose normal points away from their face (n . face
                    normal <= 0): triangles there cannot agree with both
    watertight      the output's edge report says closed, manifold, consistently oriented
    size            the input's bounding-box diagonal
    input_min_angle smallest angle of the input's own triangulation (``input_triangles``),
                    degrees, None when not given: what the output cannot beat
    """

    triangles: int
    reversed: int
    degenerate: int
    tiny: int
    min_angle: float
    max_aspect: float
    flat_faces: int
    flat_deviation: float
    flat_slide: float
    volume_change: object
    against_face: int
    watertight: bool
    size: float
    input_min_angle: object = None


def quality(result, mesh, lattice=None, flat_angle_degrees=1.0, input_triangles=None):
    """Measure a ``smoothffd.Result`` of ``mesh`` for the defects real assets show
    (docs/results.md, "Real meshes"): reversed and degenerate triangles, the smallest angle
    and the largest aspect ratio, how far flat faces move from the exact FFD of their flat
    input, and the volume change. lattice: the deformation used (anything with
    ``evaluate``); None means the identity. input_triangles: (Tin, 3) vertex indices of the
    core's triangulation of the input (``Deformer.plan.input_triangles``), for its smallest
    angle. -> Quality."""
    if getattr(result, "corner_normals", None) is None:
        raise ValueError("result: has no corner_normals (deformed with normals=False); "
                         "quality measures triangles against their normals")
    pos = np.asarray(result.positions, dtype=np.float64)
    tri = _triangles(result.triangles, len(pos))
    inp = np.asarray(mesh.positions, dtype=np.float64)
    size = float(np.linalg.norm(inp.max(axis=0) - inp.min(axis=0))) if len(inp) else 0.0
    size = size if size > 0 else 1.0
    a, b, c = pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]
    geo = np.cross(b - a, c - a)
    cn = np.asarray(result.corner_normals, dtype=np.float64).sum(axis=1)
    reversed_ = int((np.einsum("ij,ij->i", geo, cn) < 0).sum())
    area, ang, aspect = triangle_shapes(pos, tri)
    flat = flat_faces(mesh, flat_angle_degrees)
    fi = np.asarray(result.face_index, dtype=np.int64)
    dev = slide = 0.0
    ft = tri[flat[fi]]
    if len(ft):
        rest = np.asarray(result.rest_positions, dtype=np.float64)
        on = np.unique(ft)
        ref = np.zeros_like(rest)
        jac = np.zeros((len(rest), 3, 3))
        jac[:] = np.eye(3)
        ref[on] = rest[on]
        if lattice is not None:
            f, j = lattice.evaluate(rest[on])
            ref[on], jac[on] = np.asarray(f, dtype=np.float64), np.asarray(j, dtype=np.float64)
        r0, r1, r2 = rest[ft[:, 0]], rest[ft[:, 1]], rest[ft[:, 2]]
        n = _unit(np.cross(r1 - r0, r2 - r0))
        nd = _unit(np.einsum("tkrc,tc->tkr", _cofactor(jac.reshape(-1, 3, 3))[ft], n))
        off = np.einsum("tki,tki->tk", pos[ft] - ref[ft], nd)
        dev = float(np.abs(off).max()) / size
        slide = float(np.linalg.norm(pos[on] - ref[on], axis=1).max()) / size
    report = edge_report(tri)
    vol = None
    if report.watertight:
        rest = np.asarray(result.rest_positions, dtype=np.float64)
        ref = rest if lattice is None else np.asarray(lattice.evaluate(rest)[0], dtype=np.float64)
        v_ref = signed_volume(ref, tri)
        if v_ref != 0:
            vol = (signed_volume(pos, tri) - v_ref) / abs(v_ref)
    fn = _unit(polygon_normals(mesh.positions, mesh.corner_vertices, mesh.face_offsets))
    face = np.repeat(np.arange(len(fn)), np.diff(mesh.face_offsets))
    against = int((np.einsum("ij,ij->i", _corner_normals_of(mesh), fn[face]) <= 0).sum())
    return Quality(triangles=len(tri), reversed=reversed_, degenerate=int((area == 0).sum()),
                   tiny=int((area < 1e-8 * size * size).sum()),
                   min_angle=float(ang.min()) if len(ang) else 0.0,
                   max_aspect=float(aspect.max()) if len(aspect) else 0.0,
                   flat_faces=int(flat.sum()), flat_deviation=dev, flat_slide=slide,
                   volume_change=vol,
                   against_face=against, watertight=report.watertight, size=size,
                   input_min_angle=None if input_triangles is None or not len(input_triangles)
                   else float(triangle_shapes(inp, input_triangles)[1].min()))
