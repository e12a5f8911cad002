"""Smooth FFD: smooth free-form deformation of meshes by lattices (Cui & Feng 2015).

Modules: compat (every Blender-version difference), nodegroup (the node group standing in for
a modifier type), meshio and latticeio (Blender data in and out through numpy), carry (UV maps
and vertex groups onto the result), stack_input (the stack's geometry above a modifier as its
input), modifier_update (one modifier's update and plan cache),
bake (frames baked into the file for Blender without the add-on), linked (linked
objects and library overrides), handlers, operators, api
(scripting). Pure numpy, no bpy: inputs (settings and data -> the
core's inputs), result_arrays (arrays for the result mesh). core finds the `smoothffd` core.
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
    for _m in (compat, inputs, result_arrays, nodegroup, linked, meshio, latticeio, core, carry,
               stack_input, modifier_update, bake, handlers, api, operators):
        importlib.reload(_m)
else:
    import bpy  # noqa: F401
    from . import (compat, inputs, result_arrays, nodegroup, linked, meshio, latticeio, core,
                   carry, stack_input, modifier_update, bake, handlers, api, operators)

from .api import (add_smooth_ffd, apply_smooth_ffd, remove_smooth_ffd,  # noqa: E402,F401
                  update, status, bake_smooth_ffd, clear_bake)


def register():
    operators.register()
    handlers.register()


def unregister():
    handlers.unregister()
    operators.unregister()
