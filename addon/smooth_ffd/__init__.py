"""Smooth FFD: smooth free-form deformation of meshes by lattices (Cui & Feng 2015).

Blender-facing modules: compat, nodegroup, meshio, latticeio, engine, handlers, operators,
api. Pure logic without bpy: logic. The core (`smoothffd`) is found by core.py.
"""
bl_info = {
    "name": "Smooth FFD",
    "author": "smoothffd developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Modifiers > Add Modifier > Deform, and Object > Smooth FFD",
    "description": "Lattice deformation with smooth, tessellated output and exact normals",
    "category": "Object",
}

if "bpy" in locals():   # F8 / script reload: pick up edited submodules
    import importlib
    for _m in (compat, logic, nodegroup, meshio, latticeio, core, engine, handlers, api, operators):
        importlib.reload(_m)
else:
    import bpy  # noqa: F401
    from . import compat, logic, nodegroup, meshio, latticeio, core, engine, handlers, api, operators

from .api import add_smooth_ffd, apply_smooth_ffd, remove_smooth_ffd, update, status  # noqa: E402,F401


def register():
    operators.register()
    handlers.register()


def unregister():
    handlers.unregister()
    operators.unregister()
