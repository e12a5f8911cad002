"""Loads the core package `smoothffd` (kept apart so that its import errors are reported in the
status line instead of breaking the add-on's registration).

Where it comes from, without any sys.path edit:
- Blender 4.2+ extension: the wheels listed in blender_manifest.toml, which Blender installs
  into the extension's site-packages (`import smoothffd`);
- legacy add-on zip (Blender 3.4-4.1): the package vendored as the sub-package
  `smooth_ffd._vendor.smoothffd` (scripts/package.sh);
- otherwise an installed `smoothffd` (pip), e.g. a development setup.

The add-on asks the core for its limits and names (MAX_LEVEL, DEVICES) and its checks
(a singular matrix) instead of restating them: parse_level, parse_backend, lattice_to_object.
"""
import platform
import sys

import numpy as np

from . import inputs, state


def smoothffd():
    """The imported core; raises ImportError with a message saying what to do."""
    if state.core_module[0] is None:
        errors = []
        try:
            from ._vendor import smoothffd as m
        except ImportError as e:
            errors.append(f"bundled copy: {e}")
            try:
                import smoothffd as m
            except ImportError as e2:
                errors.append(f"installed package: {e2}")
                raise ImportError(
                    "cannot import the smoothffd core (" + "; ".join(errors) + "). Install the "
                    f"Smooth FFD package made for this Blender (Python "
                    f"{sys.version_info[0]}.{sys.version_info[1]}, {platform.system()} "
                    f"{platform.machine()})") from e2
        state.core_module[0] = m
    return state.core_module[0]


def parse_backend(text):
    """The Backend setting (text on 3.4-4.0, a menu item's name from 4.1) -> one of the core's
    DEVICES ('auto', the first, when empty)."""
    names = smoothffd().DEVICES
    b = str(text or names[0]).strip().lower()
    if b not in names:
        raise inputs.SmoothFFDError(f"backend must be one of {', '.join(names)}, not {text!r}")
    return b


def parse_level(value, what):
    """A level setting, 1 to the core's MAX_LEVEL."""
    top = smoothffd().MAX_LEVEL
    level = int(value)
    if not 1 <= level <= top:
        raise inputs.SmoothFFDError(f"{what} must be between 1 and {top}, not {level}")
    return level


def lattice_to_object(object_matrix, lattice_matrix):
    """M^-1 L: lattice-local coordinates -> deformed object's local coordinates. A singular
    object matrix (the core's check, smoothffd.lattice.is_singular) is an error."""
    m = np.asarray(object_matrix, dtype=np.float64)
    lat = np.asarray(lattice_matrix, dtype=np.float64)
    if smoothffd().lattice.is_singular(m):
        raise inputs.SmoothFFDError("the object's transform is singular (zero scale)")
    return np.linalg.solve(m, lat)


def make_deformer(source, lattice, level, backend, tolerance=None, max_level=None):
    """The core's Deformer of a source mesh: at a level, or adaptive (tolerance, max_level)."""
    sf = smoothffd()
    mesh = make_mesh(source)
    if tolerance is not None:
        return sf.Deformer(mesh, lattice, device=backend, tolerance=tolerance,
                           max_level=max_level)
    return sf.Deformer(mesh, lattice, level=level, device=backend)


def make_mesh(source):
    """The core's Mesh of a source mesh (meshio.SourceMesh): positions, faces, corner
    normals, the render UV map and the Vertex Group's weights."""
    return smoothffd().Mesh(source.positions, (source.corner_vertices, source.face_offsets),
                            corner_normals=source.corner_normals, uvs=source.uvs,
                            vertex_weights=source.weights)
