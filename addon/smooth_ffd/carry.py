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
