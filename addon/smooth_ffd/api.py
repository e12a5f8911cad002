"""Public scripting API (also what the operators call):

    import smooth_ffd
    mod = smooth_ffd.add_smooth_ffd(obj, lattice_obj, viewport_level=3, render_level=10)
    smooth_ffd.apply_smooth_ffd(obj, mod)
"""
import bpy

from . import bake, compat, core, frames, handlers, holdframes, linked, nodegroup, objects, \
    pipeline, stack_input, state, statusline


def add_smooth_ffd(obj, lattice_obj=None, viewport_level=3, render_level=10, backend="auto",
                   strength=1.0, vertex_group="", invert_vertex_group=False, name="Smooth FFD"):
    """Adds a Smooth FFD modifier to a mesh object and computes its first result."""
    if obj is None or obj.type != 'MESH':
        raise TypeError("obj: Smooth FFD works on mesh objects")
    if lattice_obj is not None and lattice_obj.type != 'LATTICE':
        raise TypeError(f"lattice_obj: {lattice_obj.name!r} is not a lattice object")
    linked.check_writable(obj, action="add a modifier to")
    core.parse_level(viewport_level, "viewport_level")
    core.parse_level(render_level, "render_level")
    core.parse_backend(backend)
    mod = obj.modifiers.new(name, 'NODES')
    mod.node_group = nodegroup.ensure_group()
    values = {"Lattice": lattice_obj, "Viewport Level": int(viewport_level),
              "Render Level": int(render_level), "Backend": backend,
              "Strength": float(strength), "Vertex Group": vertex_group,
              "Invert Vertex Group": bool(invert_vertex_group)}
    for key, value in values.items():
        compat.set_modifier_input(mod, key, value)
    objects.result_object(obj, mod)
    # In a window, renders compute from the render thread: the one scene setting the add-on
    # changes, and it says so (console, operator report, status).
    state.lock_message[0] = statusline.ensure_render_lock(bpy.context.scene)
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
        stack_input.begin_pass()
        frame = frames.scene_frame()
        p = state.Pass(depsgraph, render=render, force=force)
        for m in ([mod] if mod is not None else smooth_ffd_modifiers(obj)):
            if frames.in_bake(m, frame):   # the group shows the bake here: nothing to do
                statusline.set_baked(obj, m, bpy.context.scene)
                continue
            pipeline.update_modifier(obj, m, p)
        handlers.start_timers()
    state.guarded(depsgraph.update)


def status(mod):
    return compat.get_modifier_input(mod, "Status")


def bake_smooth_ffd(obj, mod=None, frame_start=None, frame_end=None):
    """Bakes frames frame_start..frame_end (default: the scene's range) at the render level
    into the file (bake.py): Blender without the add-on then renders those frames right.
    Inside the range the modifier shows the bake, also with the add-on, until
    clear_bake(obj, mod). Returns the number of distinct meshes stored. Raises RuntimeError
    (nothing baked) when a frame has no valid result."""
    mod = _one(obj, mod)
    linked.check_writable(obj, mod, "bake")
    scene = bpy.context.scene
    host = bake.bake(obj, mod, scene.frame_start if frame_start is None else frame_start,
                     scene.frame_end if frame_end is None else frame_end, scene)
    handlers.update_all(scene)   # the frame shown: the bake there, the live result elsewhere
    return len({n.inputs["Object"].default_value for n in host.modifiers[0].node_group.nodes
                if n.bl_idname == 'GeometryNodeObjectInfo'})


def clear_bake(obj, mod=None):
    """Removes the bake of a modifier (or of each of the object's); the modifier computes
    live again on those frames. Returns whether there was one."""
    return _clear_each(obj, mod, "clear the bake of", bake.clear)


def hold_tessellation(obj, mod=None, frame_start=None, frame_end=None):
    """Holds the adaptive tessellation's counts over frames frame_start..frame_end (default:
    the scene's range): every one of those frames gets the same topology, the largest counts
    over them (holds.py), for the render's and the viewport's settings where they are
    Tolerance or Screen. Returns the kinds held ('render', 'viewport'). Raises ValueError
    when neither is adaptive, RuntimeError when the frames' patches differ."""
    mod = _one(obj, mod)
    linked.check_writable(obj, mod, "hold the tessellation of")
    scene = bpy.context.scene
    kinds = holdframes.hold(obj, mod, scene.frame_start if frame_start is None else frame_start,
                            scene.frame_end if frame_end is None else frame_end, scene)
    handlers.update_all(scene)
    return kinds


def clear_hold(obj, mod=None):
    """Every frame takes its own adaptive counts again; returns whether any were held."""
    return _clear_each(obj, mod, "clear the held tessellation of", holdframes.clear)


def _clear_each(obj, mod, action, clear):
    """clear(obj, m) for the modifier (or each of the object's); recomputes when any had
    something to clear, and returns whether one had."""
    linked.check_writable(obj, mod, action)
    mods = [mod] if mod is not None else smooth_ffd_modifiers(obj)
    had = [clear(obj, m) for m in mods]
    if any(had):
        update(obj)
    return any(had)


def _one(obj, mod):
    if mod is not None:
        return mod
    mods = smooth_ffd_modifiers(obj)
    if not mods:
        raise ValueError(f"{obj.name!r} has no Smooth FFD modifier")
    return mods[0]


def apply_smooth_ffd(obj, mod):
    """Makes the result at the render level (exact normals) the object's mesh, like Apply.

    The old mesh data-block is left to Blender (undo keeps it); the hidden result object is
    deleted. Raises RuntimeError (source untouched) when the modifier has no valid result.
    """
    linked.check_writable(obj, mod, "apply")
    with state.muted():
        name = mod.name   # the modifier is freed by the operator: never touch it after
        depsgraph = bpy.context.evaluated_depsgraph_get()
        # The object's own mesh, as Blender's Apply takes for a modifier that is not first
        # (it reports "Applied modifier was not first"): the modifiers above stay and then
        # deform the applied mesh, as they deformed the source.
        if not pipeline.update_modifier(obj, mod, state.Pass(depsgraph, render=True,
                                                                 force=True, own_input=True)):
            raise RuntimeError(f"Smooth FFD cannot be applied: {status(mod)}")
        ro = objects.result_object(obj, mod, create=False)
        hidden = objects.hidden_objects(mod)
        host = objects.bake_object(mod)
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
        # its plan can be hundreds of MB at the render level
        pipeline.forget(ro=ro)
        objects.delete_result(ro)
        objects.delete_hidden(hidden)
        if host is not None and host.users == 0:
            bake.remove_host(host)
    return obj.data


def remove_smooth_ffd(obj, mod):
    """Removes the modifier; the object shows its (never modified) source mesh again."""
    linked.check_writable(obj, mod, "remove")
    ro = objects.result_object(obj, mod, create=False)
    hidden = objects.hidden_objects(mod)
    pipeline.forget(obj, mod)
    bake.clear(obj, mod)
    obj.modifiers.remove(mod)
    objects.delete_result(ro)
    objects.delete_hidden(hidden)
