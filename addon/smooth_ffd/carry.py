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

CHUNK = 1 << 18   # output triangles per numpy batch (bounds temporary memory at high levels)


class CarryMap:
    """Where the output lies in the core's triangulation of the source, for one plan."""

    def __init__(self, source, plan, rest_positions):
        t0 = time.perf_counter()
        tri_face, self.tri_corners = triangulation(source)
        tri_vertices = source.corner_vertices[self.tri_corners]
        self.tri_points = np.asarray(source.positions, np.float64)[tri_vertices]
        first, count = logic.face_triangle_ranges(tri_face, len(source.face_offsets) - 1)
        patch_vertex = np.asarray(plan.patch_vertex()).reshape(-1, 3)
        rest = np.asarray(rest_positions)
        self.patch_tri = logic.patch_core_triangles(plan.patch_face(), rest[patch_vertex],
                                                    first, count, self.tri_points)
        self.level = plan.level
        self.build_ms = 1e3 * (time.perf_counter() - t0)

    def corners(self, triangles, rest, start, stop):
        return logic.output_corner_barycentrics(triangles, self.level, self.patch_tri,
                                                self.tri_corners, self.tri_points, rest,
                                                start, stop)


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
    nt = len(res.triangles)
    for name, uvs in source.uv_layers:
        layer = layers.new(name=name)
        if name == source.uv_render or carry is None:
            values = res.uvs
        else:
            values = np.empty((nt * 3, 2), dtype=np.float32)
            for s in range(0, nt, CHUNK):
                e = min(nt, s + CHUNK)
                c, b = carry.corners(res.triangles, res.rest_positions, s, e)
                values[3 * s:3 * e] = logic.interpolate_corner_values(uvs, c, b)
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
    src = np.zeros((len(inner), 3), dtype=np.int64)
    bary = np.zeros((len(inner), 3))
    for s in range(0, len(inner), 3 * CHUNK):
        r = rep[inner[s:s + 3 * CHUNK]]
        ot = r // 3
        core_tri = carry.patch_tri[ot // (carry.level * carry.level)]
        tp = carry.tri_points[core_tri]
        pts = np.asarray(res.rest_positions, np.float64)[nv + inner[s:s + 3 * CHUNK]]
        bary[s:s + len(r)] = logic.triangle_barycentrics(pts, tp[:, 0], tp[:, 1], tp[:, 2])
        src[s:s + len(r)] = source.corner_vertices[carry.tri_corners[core_tri]]
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
