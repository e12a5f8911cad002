"""Blender's data turned into the core's inputs: lattice layout, vertex-group weights, and
fingerprints that tell when an input changed; the add-on's error type. Pure numpy, no bpy, no
core (tests/blender/test_inputs.py runs it in any Python); what the core decides (levels,
backends, a singular placement) the add-on asks it (core.py).

Shapes follow docs/api.md: V source vertices, C source corners (loops), F source faces.
"""
import hashlib

import numpy as np


class SmoothFFDError(Exception):
    """An error to show in the modifier's status line (not a bug of the add-on)."""


def lattice_grid(flat, shape):
    """Blender's flat u-fastest point array (nu*nv*nw, 3) -> (nu, nv, nw, 3) for the core."""
    nu, nv, nw = shape
    return np.asarray(flat, dtype=np.float64).reshape(nw, nv, nu, 3).transpose(2, 1, 0, 3)


def lattice_weight_grid(flat, shape):
    """Blender's flat u-fastest point weights (nu*nv*nw,) -> (nu, nv, nw) for the core."""
    nu, nv, nw = shape
    return np.asarray(flat, dtype=np.float64).reshape(nw, nv, nu).transpose(2, 1, 0).copy()


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
