"""Carries what the core does not interpolate onto the result mesh: every UV map besides the
render one, and the vertex groups (names, per-vertex weights).

Each output vertex lies on the flat input, on one triangle of the core's triangulation of its
source face (`rest_positions`); its values are interpolated barycentrically in that triangle,
as the core does for the render UV map and the deform weights. The first V output vertices
are the source vertices: they get the source's values exactly.

Nothing here runs unless the source has vertex groups or more than one UV map, and then only
when the result's topology or these data change, never on a lattice edit.
"""
import time

import numpy as np

from . import compat, core, logic

CHUNK = 1 << 20   # output corners per numpy batch (bounds temporary memory at high levels)


class CarryMap:
    """Where the output lies in the core's triangulation of the source, for one plan.

    Per patch: the source corners of the core triangle it is a piece of, and its own corners'
    barycentric coordinates there (P, 3, 3). Per output triangle corner: the tessellation
    grid (the same table for every patch, exact multiples of 1/L). A corner's coordinates in
    its core triangle are the product, which is also how the core interpolates its UV map.
    """

    def __init__(self, source, plan, res):
        t0 = time.perf_counter()
        tri_face, tri_corners = triangulation(source)
        tri_points = np.asarray(source.positions, np.float64)[source.corner_vertices[tri_corners]]
        first, count = logic.face_triangle_ranges(tri_face, len(source.face_offsets) - 1)
        patch_vertex = np.asarray(plan.patch_vertex()).reshape(-1, 3)
        rest = np.asarray(res.rest_positions)
        pp = rest[patch_vertex].astype(np.float64)                     # (P, 3, 3)
        self.patch_tri = logic.patch_core_triangles(plan.patch_face(), pp, first, count, tri_points)
        self.core_corners = tri_corners[self.patch_tri]                # (P, 3) source corners
        tp = tri_points[self.patch_tri]
        self.patch_bary = logic.triangle_barycentrics(
            pp.reshape(-1, 3), *(np.repeat(tp[:, k], 3, axis=0) for k in range(3))
        ).reshape(-1, 3, 3)
        self.tri_corners, self.tri_points = tri_corners, tri_points   # the direct path
        self.level = plan.level
        self.table = _grid_table(res.triangles, rest, pp, self.level)
        self.build_ms = 1e3 * (time.perf_counter() - t0)

    def corner_values(self, values, res):
        """values (C, k) per source corner -> (T * 3, k) float32 at the output corners."""
        values = np.asarray(values)
        nt = len(res.triangles)
        out = np.empty((nt * 3, values.shape[1]), dtype=np.float32)
        per_patch = 3 * self.level * self.level
        if self.table is not None:
            step = max(1, CHUNK // per_patch)
            for s in range(0, len(self.core_corners), step):
                e = min(len(self.core_corners), s + step)
                out[s * per_patch:e * per_patch] = logic.interpolate_patch_grid(
                    self.table, self.patch_bary[s:e], values[self.core_corners[s:e]])
            return out
        for s in range(0, nt, CHUNK // 3):
            e = min(nt, s + CHUNK // 3)
            c, b = logic.output_corner_barycentrics(res.triangles, self.level, self.patch_tri,
                                                    self.tri_corners, self.tri_points,
                                                    res.rest_positions, s, e)
            out[3 * s:3 * e] = logic.interpolate_corner_values(values, c, b)
        return out

    def corner_barycentrics(self, res, corners):
        """For output corners (3 * triangle + corner): (source corners (n, 3), coordinates
        (n, 3)) in the core triangle each lies in."""
        corners = np.asarray(corners, np.int64)
        ll = self.level * self.level
        tri, c = corners // 3, corners % 3
        patch = tri // ll
        if self.table is not None:
            grid = self.table[3 * (tri % ll) + c]
            bary = np.einsum("nk,nkj->nj", grid, self.patch_bary[patch])
        else:
            tp = self.tri_points[self.patch_tri[patch]]
            pts = np.asarray(res.rest_positions, np.float64)[np.asarray(res.triangles)[tri, c]]
            bary = logic.triangle_barycentrics(pts, tp[:, 0], tp[:, 1], tp[:, 2])
        return self.core_corners[patch], bary


def _grid_table(triangles, rest, patch_points, level):
    """The grid table read off the three largest patches (they must agree), or None: then
    the direct path computes each corner's coordinates from its rest point."""
    ll = level * level
    p0, p1, p2 = patch_points[:, 0], patch_points[:, 1], patch_points[:, 2]
    area = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    tables = []
    for p in np.argsort(-area)[:3]:
        pts = rest[np.asarray(triangles[p * ll:(p + 1) * ll]).reshape(-1)]
        tables.append(logic.grid_table(pts, patch_points[p], level))
    if not tables or any(t is None for t in tables) or \
            any(not np.array_equal(t, tables[0]) for t in tables):
        return None
    return tables[0]


def triangulation(source):
    """The core's triangulation of the source faces: (tri_face (K,), tri_corners (K, 3)),
    grouped by face in order.

    A triangle is its own corners. Polygons are triangulated by the core (ear clipping,
    docs/api.md), and the choice of diagonals matters for interpolation, so they are read
    back from the core itself: a level-1 plan of just those faces against a one-cell lattice
    enclosing them (nothing to clip, so its patches are exactly the triangles).
    """
    fo = np.asarray(source.face_offsets, np.int64)
    cv = np.asarray(source.corner_vertices, np.int64)
    sizes = np.diff(fo)
    faces, corners = [], []
    tri = np.nonzero(sizes == 3)[0]
    if len(tri):
        c = fo[tri, None] + np.arange(3)
        v = cv[c]
        keep = (v[:, 0] != v[:, 1]) & (v[:, 1] != v[:, 2]) & (v[:, 2] != v[:, 0])
        faces.append(tri[keep])
        corners.append(c[keep])
    poly = np.nonzero(sizes > 3)[0]
    if len(poly):
        f, c = _polygon_triangles(source, fo, cv, poly)
        faces.append(f)
        corners.append(c)
    if not faces:
        return np.zeros(0, np.int64), np.zeros((0, 3), np.int64)
    face = np.concatenate(faces)
    corner = np.concatenate(corners)
    order = np.argsort(face, kind="stable")
    return face[order], corner[order]


def _polygon_triangles(source, fo, cv, poly):
    sizes = fo[poly + 1] - fo[poly]
    sub_fo = np.concatenate([[0], np.cumsum(sizes)])
    sub_corners = np.repeat(fo[poly] - sub_fo[:-1], sizes) + np.arange(sub_fo[-1])
    used, local_cv = np.unique(cv[sub_corners], return_inverse=True)
    pts = np.asarray(source.positions, np.float64)[used]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.01 * float((hi - lo).max()) + 1e-3 * (1.0 + float(np.abs(pts).max()))
    sf = core.smoothffd()
    lattice = sf.BSplineLattice.identity(lo - pad, hi + pad, shape=(2, 2, 2), degree=(1, 1, 1))
    plan = sf._core.build_plan(pts, local_cv.astype(np.int32), sub_fo.astype(np.int32),
                               None, None, None, lattice._spec, 1)
    if plan.sub_vertices != len(used):
        raise RuntimeError("carrying UV maps / vertex groups: the core clipped the "
                           "triangulation plan (unexpected)")
    pv = np.asarray(plan.patch_vertex()).reshape(-1, 3).astype(np.int64)   # local vertices
    pf = np.asarray(plan.patch_face()).astype(np.int64)                   # local faces
    # (local face, local vertex) -> source corner; a vertex repeated in one polygon: first.
    nv = np.int64(len(used))
    key = np.repeat(np.arange(len(poly), dtype=np.int64), sizes) * nv + local_cv
    order = np.argsort(key, kind="stable")
    want = pf[:, None] * nv + pv
    pos = np.searchsorted(key[order], want)
    return poly[pf], sub_corners[order[pos]]


# --- writing ------------------------------------------------------------------------------------

def write_uv_layers(mesh, res, source, carry):
    """Every source UV map on the result, same names, order, active and active-render flags."""
    layers = mesh.uv_layers
    while len(layers):
        layers.remove(layers[0])
    if res.uvs is None or not source.uv_layers:
        return
    for name, uvs in source.uv_layers:
        layer = layers.new(name=name)
        if name == source.uv_render or carry is None:
            values = res.uvs   # the core's own interpolation
        else:
            values = carry.corner_values(uvs, res)
        compat.set_uvs(mesh, layer, values)
    by_name = {layer.name: layer for layer in layers}
    if source.uv_active in by_name:
        layers.active = by_name[source.uv_active]
    if source.uv_render in by_name:
        by_name[source.uv_render].active_render = True


def group_values(res, source, carry):
    """Per source group: (member indices, weights float32) on the output vertices."""
    n = len(res.positions)
    nv = source.num_vertices
    rep = logic.vertex_representatives(res.triangles, n)[nv:]
    inner = np.nonzero(rep >= 0)[0]
    corners, bary = carry.corner_barycentrics(res, rep[inner])
    src = source.corner_vertices[corners]
    out = []
    for member, weight in source.groups:
        w_in, m_in = logic.interpolate_group(weight, member, src, bary)
        idx = np.concatenate([np.nonzero(member)[0], nv + inner[m_in]])
        w = np.concatenate([weight[member], w_in[m_in]])
        out.append((idx, w))
    return out


def write_vertex_groups(obj, res, source, carry):
    """The source's vertex groups on the result object (in its mesh since Blender 3.0, so the
    Object Info node passes them on: modifiers below and Apply see them)."""
    groups = obj.vertex_groups
    if not source.group_names:
        if len(groups):
            groups.clear()
        return 0
    groups.clear()
    calls = 0
    values = group_values(res, source, carry)
    for name, (idx, w) in zip(source.group_names, values):
        vg = groups.new(name=name)
        # VertexGroup.add takes one weight per call: one call per distinct weight.
        for weight, chunk in logic.weight_batches(idx, w):
            vg.add(chunk, weight, 'REPLACE')
            calls += 1
    return calls
