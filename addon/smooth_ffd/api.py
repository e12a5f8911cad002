"""Public scripting API (also what the operators call):

    import smooth_ffd
    mod = smooth_ffd.add_smooth_ffd(obj, lattice_obj, viewport_level=3, render_level=10)
    smooth_ffd.apply_smooth_ffd(obj, mod)
"""
import bpy

from . import compat, handlers, inputs, modifier_update, nodegroup


def add_smooth_ffd(obj, lattice_obj=None, viewport_level=3, render_level=10, backend="auto",
                   strength=1.0, vertex_group="", invert_vertex_group=False, name="Smooth FFD"):
    """Adds a Smooth FFD modifier to a mesh object and computes its first result."""
    if obj is None or obj.type != 'MESH':
        raise TypeError("obj: Smooth FFD works on mesh objects")
    if lattice_obj is not None and lattice_obj.type != 'LATTICE':
        raise TypeError(f"lattice_obj: {lattice_obj.name!r} is not a lattice object")
    inputs.parse_level(viewport_level, "viewport_level")
    inputs.parse_level(render_level, "render_level")
    inputs.parse_backend(backend)
    mod = obj.modifiers.new(name, 'NODES')
    mod.node_group = nodegroup.ensure_group()
    values = {"Lattice": lattice_obj, "Viewport Level": int(viewport_level),
              "Render Level": int(render_level), "Backend": backend,
              "Strength": float(strength), "Vertex Group": vertex_group,
              "Invert Vertex Group": bool(invert_vertex_group)}
    for key, value in values.items():
        compat.set_modifier_input(mod, key, value)
    modifier_update.result_object(obj, mod)
    scene = bpy.context.scene
    scene.render.use_lock_interface = True   # see handlers.on_load
    obj.update_tag()
    update(obj, mod)
    return mod


def smooth_ffd_modifiers(obj):
    return [m for m in obj.modifiers if nodegroup.is_smooth_ffd_modifier(m)]


def update(obj=None, mod=None, render=False, force=False):
    """Recomputes now (one modifier or all) and re-evaluates the depsgraph so that
    obj.evaluated_get(depsgraph).data is the result when this returns."""
    depsgraph = bpy.context.evaluated_depsgraph_get()
    if obj is None:
        handlers.update_all(depsgraph=depsgraph, render=render, force=force)
    else:
        for m in ([mod] if mod is not None else smooth_ffd_modifiers(obj)):
            modifier_update.update_modifier(obj, m, depsgraph, render=render, force=force)
    handlers.guarded(depsgraph.update)


def status(mod):
    return compat.get_modifier_input(mod, "Status")


def apply_smooth_ffd(obj, mod):
    """Makes the result at the render level (exact normals) the object's mesh, like Apply.

    The old mesh data-block is left to Blender (undo keeps it); the hidden result object is
    deleted. Raises RuntimeError (source untouched) when the modifier has no valid result.
    """
    with handlers.muted():
        name = mod.name   # the modifier is freed by the operator: never touch it after
        depsgraph = bpy.context.evaluated_depsgraph_get()
        if not modifier_update.update_modifier(obj, mod, depsgraph, render=True, force=True):
            raise RuntimeError(f"Smooth FFD cannot be applied: {status(mod)}")
        ro = modifier_update.result_object(obj, mod, create=False)
        depsgraph.update()
        if obj.data.users > 1:
            # Blender refuses to apply to shared data; the other users keep the original mesh.
            obj.data = obj.data.copy()
        with bpy.context.temp_override(object=obj, active_object=obj, selected_objects=[obj]):
            # The operator applies exactly this modifier (not the ones after it) and
            # records undo.
            result = bpy.ops.object.modifier_apply(modifier=name)
        if 'FINISHED' not in result:
            raise RuntimeError(f"applying {name!r} failed: {result}")
        _delete_result(ro)
        modifier_update.forget(obj, name)   # its plan can be hundreds of MB at the render level
    return obj.data


def remove_smooth_ffd(obj, mod):
    """Removes the modifier; the object shows its (never modified) source mesh again."""
    ro = modifier_update.result_object(obj, mod, create=False)
    modifier_update.forget(obj, mod)
    obj.modifiers.remove(mod)
    _delete_result(ro)


def _delete_result(ro):
    if ro is None:
        return
    mesh = ro.data
    bpy.data.objects.remove(ro)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)
