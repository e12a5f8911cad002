"""Public scripting API (also what the operators call):

    import smooth_ffd
    mod = smooth_ffd.add_smooth_ffd(obj, lattice_obj, viewport_level=3, render_level=10)
    smooth_ffd.apply_smooth_ffd(obj, mod)
"""
import bpy

from . import bake, compat, handlers, inputs, linked, modifier_update, nodegroup, stack_input


def add_smooth_ffd(obj, lattice_obj=None, viewport_level=3, render_level=10, backend="auto",
                   strength=1.0, vertex_group="", invert_vertex_group=False, name="Smooth FFD"):
    """Adds a Smooth FFD modifier to a mesh object and computes its first result."""
    if obj is None or obj.type != 'MESH':
        raise TypeError("obj: Smooth FFD works on mesh objects")
    if lattice_obj is not None and lattice_obj.type != 'LATTICE':
        raise TypeError(f"lattice_obj: {lattice_obj.name!r} is not a lattice object")
    linked.check_writable(obj, action="add a modifier to")
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
    # In a window, renders compute from the render thread: the one scene setting the add-on
    # changes, and it says so (console, operator report, status; modifier_update).
    lock_message[0] = modifier_update.ensure_render_lock(bpy.context.scene)
    obj.update_tag()
    update(obj, mod)
    return mod


# What the last add_smooth_ffd said about Render > Lock Interface (None: nothing changed);
# the Add operator reports it.
lock_message = [None]


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
        frame = modifier_update.scene_frame()
        for m in ([mod] if mod is not None else smooth_ffd_modifiers(obj)):
            if handlers.in_bake(m, frame):   # the group shows the bake here: nothing to do
                handlers._baked_status(obj, m, bpy.context.scene)
                continue
            modifier_update.update_modifier(obj, m, depsgraph, render=render, force=force)
    handlers.guarded(depsgraph.update)


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
    return len({n.inputs["Object"].default_value for n in host.modifiers[0].node_group.nodes
                if n.bl_idname == 'GeometryNodeObjectInfo'})


def clear_bake(obj, mod=None):
    """Removes the bake of a modifier (or of each of the object's); the modifier computes
    live again on those frames. Returns whether there was one."""
    linked.check_writable(obj, mod, "clear the bake of")
    mods = [mod] if mod is not None else smooth_ffd_modifiers(obj)
    had = [bake.clear(obj, m) for m in mods]
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
    with handlers.muted():
        name = mod.name   # the modifier is freed by the operator: never touch it after
        depsgraph = bpy.context.evaluated_depsgraph_get()
        # The object's own mesh, as Blender's Apply takes for a modifier that is not first
        # (it reports "Applied modifier was not first"): the modifiers above stay and then
        # deform the applied mesh, as they deformed the source.
        if not modifier_update.update_modifier(obj, mod, depsgraph, render=True, force=True,
                                               own_input=True):
            raise RuntimeError(f"Smooth FFD cannot be applied: {status(mod)}")
        ro = modifier_update.result_object(obj, mod, create=False)
        hidden = _hidden_objects(mod)
        host = bake.bake_object(mod)
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
        modifier_update.forget(ro=ro)
        _delete_result(ro)
        _delete_hidden(hidden)
        if host is not None and host.users == 0:
            bake.remove_host(host)
    return obj.data


def remove_smooth_ffd(obj, mod):
    """Removes the modifier; the object shows its (never modified) source mesh again."""
    linked.check_writable(obj, mod, "remove")
    ro = modifier_update.result_object(obj, mod, create=False)
    hidden = _hidden_objects(mod)
    modifier_update.forget(obj, mod)
    bake.clear(obj, mod)
    obj.modifiers.remove(mod)
    _delete_result(ro)
    _delete_hidden(hidden)


def _hidden_objects(mod):
    """The modifier's hidden objects besides its result: (object, the key marking it ours)
    for its Stack Object (stack_input) and its Result Points (modifier_update.points_object),
    where its group has them."""
    found = []
    for layouts, name, key in ((nodegroup.STACK_LAYOUTS, "Stack Object", stack_input.STACK_KEY),
                               (nodegroup.POINTS_LAYOUTS, "Result Points",
                                modifier_update.POINTS_KEY)):
        if nodegroup.layout(mod.node_group) in layouts:
            found.append((compat.get_modifier_input(mod, name), key))
    return found


def _delete_hidden(hidden):
    """Deletes the hidden objects _hidden_objects found, once nothing uses them."""
    for ob, key in hidden:
        if ob is not None and ob.get(key) is not None and ob.users == 0:
            stack_input.remove(ob)


def _delete_result(ro):
    if ro is None:
        return
    mesh = ro.data
    bpy.data.objects.remove(ro)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)
