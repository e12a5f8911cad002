"""Carries what the core does not interpolate onto the result mesh: every UV map besides the
render one, and the vertex groups (names, per-vertex weights).

The core's plan says where each output corner and vertex lies on the input: a barycentric point
of one triangle of its triangulation of the source face (docs/api.md, "Where the output lies
on the input"). UV maps go through `Plan.interpolate_corners`, the arithmetic of the render UV
map; vertex groups are interpolated here from `Plan.vertex_sources`. The first V output
vertices are the source vertices: they get the source's values exactly.

Nothing here runs unless the source has vertex groups or more than one UV map, and then only
when the result's topology or these data change, never on a lattice edit.
"""
import numpy as np

from . import compat, result_arrays


def write_uv_layers(mesh, res, source, plan):
    """Every source UV map on the result, same names, order, active and active-render flags.
    plan: the core plan res came from (the other maps are interpolated as res.uvs is)."""
    layers = mesh.uv_layers
    names = [name for name, _ in source.uv_layers] if res.uvs is not None else []
    keep = [layer.name for layer in layers] == names   # then overwrite them in place
    if not keep:
        while len(layers):
            layers.remove(layers[0])
    if not names:
        return
    for i, (name, uvs) in enumerate(source.uv_layers):
        layer = layers[i] if keep else layers.new(name=name)
        values = res.uvs if name == source.uv_render else plan.interpolate_corners(uvs)
        compat.set_uvs(mesh, layer, values)
    by_name = {layer.name: layer for layer in layers}
    if source.uv_active in by_name:
        layers.active = by_name[source.uv_active]
    if source.uv_render in by_name:
        by_name[source.uv_render].active_render = True


def group_values(source, plan):
    """Per source group: (member indices, weights float32) on the output vertices."""
    nv = source.num_vertices
    tri, bary = plan.vertex_sources()
    corners, _ = plan.input_triangles()
    inner = np.nonzero(tri[nv:] >= 0)[0]        # every output vertex past the source's lies on one
    src = source.corner_vertices[corners[tri[nv:][inner]]]
    bary = bary[nv:][inner]
    out = []
    for member, weight in source.groups:
        w_in, m_in = result_arrays.interpolate_group(weight, member, src, bary)
        idx = np.concatenate([np.nonzero(member)[0], nv + inner[m_in]])
        w = np.concatenate([weight[member], w_in[m_in]])
        out.append((idx, w))
    return out


def write_vertex_groups(obj, source, plan):
    """The source's vertex groups on the result object (in its mesh since Blender 3.0, so the
    Object Info node passes them on: modifiers below and Apply see them). Returns the number
    of VertexGroup.add calls."""
    groups = obj.vertex_groups
    if not source.group_names:
        if len(groups):
            groups.clear()
        return 0
    groups.clear()
    calls = 0
    for name, (idx, w) in zip(source.group_names, group_values(source, plan)):
        vg = groups.new(name=name)
        # VertexGroup.add takes one weight per call: one call per distinct weight.
        for weight, chunk in result_arrays.weight_batches(idx, w):
            vg.add(chunk, weight, 'REPLACE')
            calls += 1
    return calls


class AdaptiveSources:
    """Where an adaptive result (the core's Deformer with a tolerance, whose topology is not
    the plan's) lies on the input, with the plan's methods that the carry above uses
    (vertex_sources, input_triangles, interpolate_corners). Each output corner lies on its
    triangle's source face (res.face_index) at its rest position (res.rest_positions: the
    point of the flat input face it is the image of); its barycentric point in the triangle
    of the core's triangulation of that face (plan.input_triangles) that holds it (the
    nearest, for rounding) gives the values, as the core interpolates the render UV map.
    The first V output vertices are the source vertices: exact one-hot points."""

    def __init__(self, res, plan, source):
        self._corners, tri_face = plan.input_triangles()
        self._nv = source.num_vertices
        pos = np.asarray(source.positions, np.float64)
        tri_pts = pos[source.corner_vertices[self._corners]]           # (Tin, 3, 3)
        order = np.argsort(tri_face, kind="stable")
        nf = int(tri_face.max(initial=-1)) + 1
        count = np.bincount(tri_face, minlength=nf)
        first = np.zeros(nf + 1, np.int64)
        np.cumsum(count, out=first[1:])
        tris = np.asarray(res.triangles).reshape(-1)
        face = np.repeat(np.asarray(res.face_index), 3)
        p = np.asarray(res.rest_positions, np.float64)[tris]
        best_t = np.full(len(tris), -1, np.int64)
        best_b = np.zeros((len(tris), 3), np.float64)
        best_s = np.full(len(tris), -np.inf)
        for k in range(int(count.max(initial=0))):
            ok = k < count[face]
            cand = order[np.minimum(first[face] + k, len(order) - 1)]
            b = _barycentric(p, tri_pts[cand])
            score = np.where(ok, b.min(axis=1), -np.inf)
            better = score > best_s
            best_s[better], best_t[better], best_b[better] = score[better], cand[better], b[better]
        self._corner_tri = best_t
        self._corner_bary = np.clip(best_b, 0.0, None)
        self._corner_bary /= np.maximum(self._corner_bary.sum(axis=1, keepdims=True), 1e-30)
        n = len(res.positions)
        vt = np.full(n, -1, np.int32)
        vb = np.zeros((n, 3), np.float32)
        vt[tris] = best_t
        vb[tris] = self._corner_bary
        # The source's own vertices: exact, on a triangle of a face that uses them.
        cv = source.corner_vertices[self._corners]                     # (Tin, 3)
        for j in range(3):
            vt[cv[:, j]] = np.arange(len(cv))
        nv = self._nv
        used = np.zeros(nv, bool)
        used[cv.ravel()] = True
        vt[:nv][~used] = -1
        vb[:nv] = 0.0
        rows = np.nonzero(used)[0]
        tri_of = vt[rows]
        for j in range(3):
            vb[rows[cv[tri_of, j] == rows], j] = 1.0
        self._vt, self._vb = vt, vb

    def input_triangles(self):
        return self._corners, None

    def vertex_sources(self):
        return self._vt, self._vb

    def interpolate_corners(self, values):
        v = np.asarray(values, np.float64)
        tri = self._corner_tri
        got = v[self._corners[tri]]                                    # (T*3, 3, ...)
        b = self._corner_bary.reshape(self._corner_bary.shape + (1,) * (v.ndim - 1))
        out = (got * b).sum(axis=1).astype(np.float32)
        return out.reshape((-1, 3) + v.shape[1:])


def _barycentric(p, tri):
    """Barycentric coordinates (N, 3) of points p (N, 3) in the planes of triangles (N, 3, 3)
    (the point projected on the plane)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00 = (v0 * v0).sum(1)
    d01 = (v0 * v1).sum(1)
    d11 = (v1 * v1).sum(1)
    d20 = (v2 * v0).sum(1)
    d21 = (v2 * v1).sum(1)
    den = d00 * d11 - d01 * d01
    den = np.where(np.abs(den) > 1e-300, den, 1e-300)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return np.stack([1.0 - v - w, v, w], axis=1)
