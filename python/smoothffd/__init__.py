"""smoothffd: smooth free-form deformation with sharp-feature awareness (Cui & Feng 2015).

Deforms every triangle of a mesh, and its normal field, into cubic Bézier patches under a
B-spline volume or a Blender lattice. See docs/api.md.

The pure-Python parts (`smoothffd.io`, `smoothffd.lattice_json`, `smoothffd.metrics`) import
without the native module; everything else needs it and says how to build it when it is missing.
"""

import sys

__version__ = "0.1.0"
__all__ = ["BSplineLattice", "BlenderLattice", "Mesh", "Deformer", "Result", "CompactResult", "deform",
           "cuda_status", "MAX_LEVEL", "DEVICES"]

try:
    from . import _core  # noqa: F401
except ImportError as exc:  # the pure-Python submodules still work
    _CORE_ERROR = (
        "smoothffd: the native module smoothffd._core is missing or does not load "
        f"({exc}). Install a wheel made for this Python "
        f"({sys.version_info.major}.{sys.version_info.minor}): `pip install smoothffd` or a "
        "wheel from scripts/package.sh's dist/; in a source tree, `bash scripts/build.sh` "
        "builds it in place.")

    def __getattr__(name):
        if name in __all__:
            raise ImportError(_CORE_ERROR)
        raise AttributeError(f"module 'smoothffd' has no attribute {name!r}")
else:
    from .deform import DEVICES, MAX_LEVEL, CompactResult, Deformer, Result, cuda_status, deform  # noqa: F401
    from .lattice import BlenderLattice, BSplineLattice  # noqa: F401
    from .mesh import Mesh  # noqa: F401
