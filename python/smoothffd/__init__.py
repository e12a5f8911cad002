"""smoothffd: smooth free-form deformation with sharp-feature awareness (Cui & Feng 2015).

Deforms every triangle of a mesh, and its normal field, into cubic Bézier patches under a
B-spline volume or a Blender lattice. See docs/api.md.
"""

try:
    from . import _core  # noqa: F401
except ImportError as exc:  # pragma: no cover - exercised only without a build
    import sys

    raise ImportError(
        "smoothffd: the native module smoothffd._core is missing or does not load "
        f"({exc}). Build it with `bash scripts/build.sh` (it must match this Python, "
        f"{sys.version_info.major}.{sys.version_info.minor})."
    ) from exc

from .deform import Deformer, Result, cuda_status, deform  # noqa: E402
from .lattice import BlenderLattice, BSplineLattice  # noqa: E402
from .mesh import Mesh  # noqa: E402

__all__ = ["BSplineLattice", "BlenderLattice", "Mesh", "Deformer", "Result", "deform",
           "cuda_status"]
__version__ = "0.1.0"
