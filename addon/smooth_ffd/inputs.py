"""The modifier's settings and Blender's data turned into the core's inputs: validation,
lattice layout and placement, vertex-group weights, and fingerprints that tell when an input
changed. Pure numpy, no bpy (tests/blender/test_inputs.py runs it in any Python).

Shapes follow docs/api.md: V source vertices, C source corners (loops), F source faces.
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


def lattice_weight_grid(flat, shape):
    """Blender's flat u-fastest point weights (nu*nv*nw,) -> (nu, nv, nw) for the core."""
    nu, nv, nw = shape
    return np.asarray(flat, dtype=np.float64).reshape(nw, nv, nu).transpose(2, 1, 0).copy()


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
    """The Backend setting (text on 3.4-4.0, a menu item's name from 4.1) -> 'auto'/'cpu'/'cuda'."""
    b = str(text or "auto").strip().lower()
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
