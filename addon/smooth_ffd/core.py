"""Loads the core package `smoothffd` (kept apart so that its import errors are reported in the
status line instead of breaking the add-on's registration).

Where it comes from, without any sys.path edit:
- Blender 4.2+ extension: the wheels listed in blender_manifest.toml, which Blender installs
  into the extension's site-packages (`import smoothffd`);
- legacy add-on zip (Blender 3.4-4.1): the package vendored as the sub-package
  `smooth_ffd._vendor.smoothffd` (scripts/package.sh);
- otherwise an installed `smoothffd` (pip), e.g. a development setup.
"""
import sys

_module = None


def smoothffd():
    """The imported core; raises ImportError with a message saying what to do."""
    global _module
    if _module is None:
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
                    f"{sys.version_info[0]}.{sys.version_info[1]}, Linux x86-64): see "
                    "docs/packaging.md") from e2
        _module = m
    return _module


def make_deformer(source, lattice, level, backend):
    sf = smoothffd()
    mesh = sf.Mesh(source.positions, (source.corner_vertices, source.face_offsets),
                   corner_normals=source.corner_normals, uvs=source.uvs,
                   vertex_weights=source.weights)
    return sf.Deformer(mesh, lattice, level=level, device=backend)
