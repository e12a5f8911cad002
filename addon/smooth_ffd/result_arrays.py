"""Arrays for writing the core's result into a Blender mesh: loops, sharp-edge flags, and the
vertex groups carried onto the output. Pure numpy, no bpy (tests/blender/test_result_arrays.py
runs it in any Python).

Shapes follow docs/api.md: V source vertices, N output vertices, T output triangles.
"""
import numpy as np


def triangle_loops(triangles):
    """Output triangles -> (loop vertex indices, loop starts, loop totals) as int32."""
    t = np.ascontiguousarray(triangles, dtype=np.int32)
    count = len(t)
    starts = np.arange(0, 3 * count, 3, dtype=np.int32)
    totals = np.full(count, 3, dtype=np.int32)
    return t.ravel(), starts, totals


def edge_flags(mesh_edges, flagged_pairs, num_vertices):
    """(E,) bool: which of the mesh's edges (E, 2) appear in flagged_pairs (K, 2), any order.

    Only an edge whose two ends are both ends of some flagged pair can be one, so those few
    candidates are matched (sorted keys), not every edge: a per-frame write of a dense result
    sorts nothing of its size."""
    e = np.asarray(mesh_edges).reshape(-1, 2)
    out = np.zeros(len(e), dtype=bool)
    if len(e) == 0 or flagged_pairs is None or len(flagged_pairs) == 0:
        return out
    f = np.sort(np.asarray(flagged_pairs, dtype=np.int64).reshape(-1, 2), axis=1)
    n = np.int64(num_vertices)
    end = np.zeros(int(n), dtype=bool)
    end[f.ravel()] = True
    cand = np.flatnonzero(end[e[:, 0]] & end[e[:, 1]])
    if len(cand) == 0:
        return out
    c = np.sort(e[cand].astype(np.int64), axis=1)
    ckey = c[:, 0] * n + c[:, 1]
    fkey = np.unique(f[:, 0] * n + f[:, 1])
    pos = np.clip(np.searchsorted(fkey, ckey), 0, len(fkey) - 1)
    out[cand[fkey[pos] == ckey]] = True
    return out


def interpolate_group(weights, member, src_vertices, bary):
    """One vertex group at output vertices inside source triangles.

    weights (V,), member (V,) bool: the group on the source (non-members count as 0).
    src_vertices (n, 3) source vertices of the triangle each output vertex lies in, bary
    (n, 3) its coordinates there (the core's Plan.vertex_sources). Returns (weights (n,)
    float32, member (n,) bool): a vertex is in the group when a corner it depends on
    (coordinate > 0) is; where those corners' weights are all equal the weight is exactly
    that value.
    """
    w = np.where(member, np.asarray(weights, np.float64), 0.0)[src_vertices]
    m = np.asarray(member, bool)[src_vertices]
    bary = np.asarray(bary, np.float64)
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
