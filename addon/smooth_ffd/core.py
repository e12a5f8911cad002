"""Finds and loads the core package `smoothffd` (kept apart so its import errors are reported
in the status line instead of breaking the add-on's registration)."""
import os
import sys

_HERE = os.path.dirname(os.path.abspath(__file__))
# Order: an explicit override, the copy bundled in the zip, the source tree's python/.
_CANDIDATES = [p for p in (os.environ.get("SMOOTHFFD_PYTHONPATH"),
                           os.path.join(_HERE, "_vendor"),
                           os.path.normpath(os.path.join(_HERE, "..", "..", "python")))
               if p and os.path.isdir(os.path.join(p, "smoothffd"))]

_module = None


def smoothffd():
    """The imported core; raises ImportError with a message saying what to do."""
    global _module
    if _module is None:
        if _CANDIDATES and _CANDIDATES[0] not in sys.path:
            sys.path.insert(0, _CANDIDATES[0])
        try:
            import smoothffd as m
        except ImportError as e:
            raise ImportError(
                f"cannot import the smoothffd core ({e}); it must be built for this Blender's "
                f"Python {sys.version_info[0]}.{sys.version_info[1]} (searched: "
                f"{', '.join(_CANDIDATES) or 'nothing found'})") from e
        _module = m
    return _module


def make_deformer(source, lattice, level, backend):
    sf = smoothffd()
    mesh = sf.Mesh(source.positions, (source.corner_vertices, source.face_offsets),
                   corner_normals=source.corner_normals, uvs=source.uvs,
                   vertex_weights=source.weights)
    return sf.Deformer(mesh, lattice, level=level, device=backend)
