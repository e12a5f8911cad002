"""Pure logic of the add-on: numpy only, no bpy, so it can be tested in any Python.

Shapes follow docs/api.md: V source vertices, C source corners (loops), F source faces,
N output vertices, T output triangles.
"""
import hashlib

import numpy as np

BACKENDS = ("auto", "cpu", "cuda")
INTERPOLATIONS = ("KEY_LINEAR", "KEY_CARDINAL", "KEY_CATMULL_ROM", "KEY_BSPLINE")
MAX_LEVEL = 64


class SmoothFFDError(Exception):
    """An error to show in the modifier's status line (not a bug of the add-on)."""


def lattice_grid(flat, shape):
    """Blender's flat u-fastest point array (nu*nv*nw, 3) -> (nu, nv, nw, 3) for the core."""
    nu, nv, nw = shape
    return np.asarray(flat, dtype=np.float64).reshape(nw, nv, nu, 3).transpose(2, 1, 0, 3)


def lattice_to_object(object_matrix, lattice_matrix):
    """M^-1 L: lattice-local coordinates -> deformed object's local coordinates."""
    m = np.asarray(object_matrix, dtype=np.float64)
    lat = np.asarray(lattice_matrix, dtype=np.float64)
    if abs(np.linalg.det(m[:3, :3])) < 1e-30:
        raise SmoothFFDError("the object's transform is singular (zero scale)")
    return np.linalg.solve(m, lat)


def interpolation_names(types):
    """Lattice data's interpolation_type_u/v/w ('KEY_BSPLINE', ...) -> core names ('BSPLINE')."""
    out = []
    for t in types:
        if t not in INTERPOLATIONS:
            raise SmoothFFDError(f"unsupported lattice interpolation {t!r}")
        out.append(t[len("KEY_"):])
    return tuple(out)


def vertex_weights(num_vertices, group_index, dvert_indices, dvert_groups, dvert_weights, invert):
    """Per-vertex factor of Blender's Lattice modifier from a vertex group (before strength).

    dvert_*: flat (vertex, group, weight) triples of the mesh's deform-vertex layer.
    Returns None when no group is used (every vertex moves fully).
    """
    if group_index is None:
        return None
    w = np.zeros(num_vertices, dtype=np.float64)
    sel = np.asarray(dvert_groups) == group_index
    w[np.asarray(dvert_indices)[sel]] = np.asarray(dvert_weights)[sel]
    w = np.clip(w, 0.0, 1.0)
    return 1.0 - w if invert else w


def parse_backend(text):
    b = (text or "auto").strip().lower()
    if b not in BACKENDS:
        raise SmoothFFDError(f"backend must be one of {', '.join(BACKENDS)}, not {text!r}")
    return b


def parse_level(value, what):
    level = int(value)
    if not 1 <= level <= MAX_LEVEL:
        raise SmoothFFDError(f"{what} must be between 1 and {MAX_LEVEL}, not {level}")
    return level


def digest(*arrays):
    """A short fingerprint of numpy arrays and plain values, to skip unchanged updates."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        if isinstance(a, np.ndarray):
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(np.ascontiguousarray(a).data)
        else:
            h.update(repr(a).encode())
    return h.hexdigest()


def triangle_loops(triangles):
    """Output triangles -> (loop vertex indices, loop starts, loop totals) as int32."""
    t = np.ascontiguousarray(triangles, dtype=np.int32)
    count = len(t)
    starts = np.arange(0, 3 * count, 3, dtype=np.int32)
    totals = np.full(count, 3, dtype=np.int32)
    return t.ravel(), starts, totals


def edge_flags(mesh_edges, flagged_pairs, num_vertices):
    """(E,) bool: which of the mesh's edges (E, 2) appear in flagged_pairs (K, 2), any order."""
    e = np.sort(np.asarray(mesh_edges, dtype=np.int64).reshape(-1, 2), axis=1)
    out = np.zeros(len(e), dtype=bool)
    if len(e) == 0 or flagged_pairs is None or len(flagged_pairs) == 0:
        return out
    f = np.sort(np.asarray(flagged_pairs, dtype=np.int64).reshape(-1, 2), axis=1)
    n = np.int64(num_vertices)
    ekey = e[:, 0] * n + e[:, 1]
    fkey = f[:, 0] * n + f[:, 1]
    order = np.argsort(ekey)
    pos = np.searchsorted(ekey, fkey, sorter=order)
    pos = np.clip(pos, 0, len(e) - 1)
    hit = ekey[order[pos]] == fkey
    out[order[pos[hit]]] = True
    return out


def format_status(backend, ms, level, triangles, normals_path):
    return f"OK: {backend}, level {level}, {triangles} tris, {ms:.1f} ms, normals {normals_path}"


# --- carrying per-corner and per-vertex data (UV maps, vertex groups) onto the output -----------
#
# Every output vertex lies on the flat input: `rest_positions` is its point on one triangle of
# the core's triangulation of its source face. Data the core does not interpolate itself (every
# UV map but the render one, vertex groups) is interpolated here barycentrically in that same
# triangle, which is how the core interpolates the render UV map and the deform weights.


def triangle_barycentrics(points, a, b, c, snap=1e-6):
    """(n, 3) float64 barycentric coordinates of points (n, 3) in triangles a, b, c (n, 3 each).

    Least squares in the triangle's plane; negative coordinates (rounding) are clamped, and
    coordinates below `snap` set to 0, then the rest renormalized: a point at a corner gets
    exactly (1, 0, 0), a point on an edge exactly 0 for the opposite corner. Degenerate
    (zero-area) triangles give their nearest corner.
    """
    b_raw, ok = _raw_barycentrics(points, a, b, c)
    out = np.clip(b_raw, 0.0, None)
    out[out < snap] = 0.0
    s = out.sum(axis=1)
    bad = ~ok | (s <= 0)
    out[~bad] /= s[~bad, None]
    if bad.any():
        p = np.asarray(points, np.float64)[bad]
        d = np.stack([np.linalg.norm(p - np.asarray(x, np.float64)[bad], axis=1) for x in (a, b, c)], 1)
        out[bad] = 0.0
        out[np.nonzero(bad)[0], np.argmin(d, axis=1)] = 1.0
    return out


def _raw_barycentrics(points, a, b, c):
    a = np.asarray(a, np.float64)
    e0 = np.asarray(b, np.float64) - a
    e1 = np.asarray(c, np.float64) - a
    p = np.asarray(points, np.float64) - a
    d00 = np.einsum("ij,ij->i", e0, e0)
    d01 = np.einsum("ij,ij->i", e0, e1)
    d11 = np.einsum("ij,ij->i", e1, e1)
    d20 = np.einsum("ij,ij->i", p, e0)
    d21 = np.einsum("ij,ij->i", p, e1)
    den = d00 * d11 - d01 * d01
    ok = den > 1e-12 * d00 * d11
    safe = np.where(ok, den, 1.0)
    b1 = (d11 * d20 - d01 * d21) / safe
    b2 = (d00 * d21 - d01 * d20) / safe
    return np.stack([1.0 - b1 - b2, b1, b2], axis=1), ok


def face_triangle_ranges(tri_face, num_faces):
    """Core triangles sorted by face -> (first, count) per face (count 0: no triangle)."""
    tri_face = np.asarray(tri_face, np.int64)
    if np.any(np.diff(tri_face) < 0):
        raise ValueError("tri_face: triangles must be grouped by face in increasing order")
    count = np.bincount(tri_face, minlength=num_faces).astype(np.int64)
    first = np.concatenate([[0], np.cumsum(count)[:-1]]).astype(np.int64)
    return first, count


def patch_core_triangles(patch_face, patch_points, tri_first, tri_count, tri_points):
    """The core triangle (index into tri_points (K, 3, 3)) that holds each patch.

    patch_points: (P, 3, 3) the patches' corners on the flat input. A patch is a piece of one
    triangle of its face's triangulation; the candidate that best contains the patch's
    centroid (largest smallest barycentric coordinate, minus its distance from the plane)
    is that triangle.
    """
    patch_face = np.asarray(patch_face, np.int64)
    first, count = tri_first[patch_face], tri_count[patch_face]
    if np.any(count <= 0):
        raise ValueError("a patch's face has no core triangle")
    centroid = np.asarray(patch_points, np.float64).mean(axis=1)
    best = first.copy()
    score = np.full(len(patch_face), -np.inf)
    for j in range(int(count.max(initial=0))):
        sel = np.nonzero(count > j)[0]
        t = first[sel] + j
        tp = np.asarray(tri_points, np.float64)[t]
        b, _ = _raw_barycentrics(centroid[sel], tp[:, 0], tp[:, 1], tp[:, 2])
        n = np.cross(tp[:, 1] - tp[:, 0], tp[:, 2] - tp[:, 0])
        area2 = np.linalg.norm(n, axis=1)
        dist = np.abs(np.einsum("ij,ij->i", centroid[sel] - tp[:, 0], n)) / np.maximum(area2, 1e-300)
        s = b.min(axis=1) - dist / np.sqrt(np.maximum(area2, 1e-300))
        s = np.where(np.isfinite(s), s, -np.inf)
        better = s > score[sel]
        best[sel[better]] = t[better]
        score[sel[better]] = s[better]
    return best


def grid_table(points, corners, level, tol=1e-3):
    """The tessellation grid of one patch as exact barycentric coordinates.

    points (L^2 * 3, 3): the rest points of a patch's output triangle corners, in the core's
    order; corners (3, 3): the patch's corners. The core tessellates every patch with the same
    grid (i/L, j/L, k/L), so the table serves all patches. Returns (L^2 * 3, 3) multiples of
    1/L, or None when the points are not on that grid (a degenerate patch).
    """
    c = np.asarray(corners, np.float64)
    n = len(points)
    b = triangle_barycentrics(points, np.repeat(c[:1], n, 0), np.repeat(c[1:2], n, 0),
                              np.repeat(c[2:], n, 0), snap=0.0)
    scaled = b * level
    steps = np.rint(scaled)
    if np.abs(scaled - steps).max(initial=0.0) > tol or np.any(steps.sum(axis=1) != level):
        return None
    return steps / level


def output_corner_barycentrics(triangles, level, patch_tri, tri_corners, tri_points, rest,
                               start=0, stop=None):
    """Direct (slow) path: for output triangles [start, stop), per corner the 3 source corners
    of the core triangle it lies in ((n*3, 3) int64) and its barycentric coordinates there
    from its rest point ((n*3, 3) float64). Output triangle t belongs to patch t // level^2."""
    triangles = np.asarray(triangles)
    stop = len(triangles) if stop is None else stop
    ot = np.arange(start, stop)
    core = np.asarray(patch_tri)[ot // (level * level)]
    tp = np.repeat(np.asarray(tri_points, np.float64)[core], 3, axis=0)
    pts = np.asarray(rest, np.float64)[np.asarray(triangles[start:stop]).reshape(-1)]
    bary = triangle_barycentrics(pts, tp[:, 0], tp[:, 1], tp[:, 2])
    corners = np.repeat(np.asarray(tri_corners, np.int64)[core], 3, axis=0)
    return corners, bary


def interpolate_patch_grid(table, patch_bary, values):
    """Per-corner values of every output triangle of patches, the way the core interpolates
    its UV map: values at the patch corners (patch_bary (P, 3, 3) @ values (P, 3, k), the
    values at each patch's core triangle corners), then the grid table (L^2 * 3, 3).
    Returns (P * L^2 * 3, k) float64."""
    at_corners = np.matmul(np.asarray(patch_bary, np.float64), np.asarray(values, np.float64))
    return np.matmul(table[None], at_corners).reshape(-1, at_corners.shape[-1])


def interpolate_corner_values(values, corners, bary):
    """values (C, k) per source corner -> (n, k) float64 at output corners."""
    v = np.asarray(values, np.float64)
    return np.einsum("nj,njk->nk", bary, v[corners])


def vertex_representatives(triangles, num_vertices):
    """(N,) one output corner (3 * triangle + corner) per output vertex, -1 where none."""
    flat = np.asarray(triangles).reshape(-1)
    rep = np.full(num_vertices, -1, dtype=np.int64)
    rep[flat] = np.arange(len(flat), dtype=np.int64)
    return rep


def interpolate_group(weights, member, src_vertices, bary):
    """One vertex group at output vertices inside source triangles.

    weights (V,), member (V,) bool: the group on the source (non-members count as 0).
    src_vertices (n, 3) source vertices of the triangle each output vertex lies in, bary
    (n, 3) its coordinates. Returns (weights (n,) float32, member (n,) bool): a vertex is in
    the group when a corner it depends on (coordinate > 0) is; where those corners' weights
    are all equal the weight is exactly that value.
    """
    w = np.where(member, np.asarray(weights, np.float64), 0.0)[src_vertices]
    m = np.asarray(member, bool)[src_vertices]
    used = bary > 0
    out = np.einsum("nk,nk->n", bary, w)
    hi = np.where(used, w, -np.inf).max(axis=1)
    lo = np.where(used, w, np.inf).min(axis=1)
    same = hi == lo
    out[same] = hi[same]
    return np.clip(out, 0.0, 1.0).astype(np.float32), (m & used).any(axis=1)


def weight_batches(indices, weights):
    """Groups vertex indices by equal weight: [(weight, [indices...]), ...], for
    VertexGroup.add, which takes one weight per call."""
    indices = np.asarray(indices, np.int64)
    weights = np.asarray(weights, np.float32)
    if len(indices) == 0:
        return []
    order = np.argsort(weights, kind="stable")
    w = weights[order]
    starts = np.concatenate([[0], np.nonzero(w[1:] != w[:-1])[0] + 1, [len(w)]]).tolist()
    idx = indices[order].tolist()            # one conversion; slicing lists is cheap
    values = w[starts[:-1]].tolist()
    return [(values[i], idx[starts[i]:starts[i + 1]]) for i in range(len(values))]
