"""Smooth FFD: smooth free-form deformation of meshes by lattices (Cui & Feng 2015).

Modules, top to bottom (each imports only modules below it; docs/addon.md):
- Blender's entry points: operators (menus), api (scripting, what the operators call),
  handlers (app handlers and timers);
- the one update path: pipeline (update_modifier) over gather (read the inputs, the stack's
  geometry through stack_input), plans (plan cache and the core's frame), write (the result
  mesh, with carry's UV maps and vertex groups), statusline (the status line), live (live
  editing); bake (frames baked into the file) runs it frame by frame;
- Blender data: objects (the hidden objects), frames (the frame ranges), linked (linked data
  and overrides), nodegroup (the node group standing in for a modifier type), meshio and
  latticeio (mesh and lattice data through numpy), compat (every Blender-version difference);
- core (finds the `smoothffd` core and asks it for its limits and names); inputs and
  result_arrays (pure numpy, no bpy);
- state: every modifier's in-memory state, the custom-property keys, the frame ranges' values
  and every other value kept between calls; imports no other module.
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
    for _m in (state, inputs, result_arrays, compat, core, nodegroup, frames, linked, meshio,
               latticeio, carry, objects, statusline, stack_input, tessellation, gather, plans,
               live, write, holds, pipeline, bake, holdframes, handlers, api, operators):
        importlib.reload(_m)
else:
    import bpy  # noqa: F401
    from . import (state, inputs, result_arrays, compat, core, nodegroup, frames, linked, meshio,
                   latticeio, carry, objects, statusline, stack_input, tessellation, gather,
                   plans, live, write, holds, pipeline, bake, holdframes, handlers, api,
                   operators)

from .api import (add_smooth_ffd, apply_smooth_ffd, remove_smooth_ffd,  # noqa: E402,F401
                  update, status, bake_smooth_ffd, clear_bake, hold_tessellation,
                  clear_hold)


def register():
    operators.register()
    handlers.register()


def unregister():
    handlers.unregister()
    operators.unregister()
