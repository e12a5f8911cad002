"""The hidden objects a modifier's node group reads (nodegroup), never linked to a scene: its
result object (the result mesh), its Result Points (positions-only updates before 3.6), its
Stack Object (the input check, stack_input) and its bake host (bake); finding them, making
them and deleting them. Each is tied to its modifier by a custom property (state's keys)."""
import bpy

from . import compat, frames, linked, meshio, nodegroup, state


def result_object(obj, mod, create=True):
    """The hidden mesh object whose geometry the modifier's Object Info node shows.

    It belongs to one (object, modifier); a duplicated object or copied modifier still points
    at the original's result, so it gets its own here instead of overwriting that one.
    """
    ro = compat.get_modifier_input(mod, "Result Object")
    if ro is not None and ro.type == 'MESH' and _owned_by(ro, obj, mod):
        return ro
    if not create:
        return None
    name = f"{obj.name}.{mod.name}.result"
    me = bpy.data.meshes.new(name)
    ro = bpy.data.objects.new(name, me)   # never linked to a scene: hidden, yet saved (mod uses it)
    ro[state.OWNER_KEY] = obj.name_full
    ro[state.MODIFIER_KEY] = mod.name
    state.uid(ro)
    compat.set_modifier_input(mod, "Result Object", ro)
    return ro


def state_of(obj, mod):
    """The in-memory state of a modifier (None when it has no result object yet)."""
    return state.of_result(result_object(obj, mod, create=False))


def _owned_by(ro, obj, mod):
    """Whether ro is this modifier's own result (not the original's, reached through a
    duplicated object or a copied modifier).

    The owner is kept by name, not as an ID pointer: a pointer is a user of the object, and
    with the modifier pointing back at the result the two kept each other alive, so an
    object deleted in the UI (bpy.ops.object.delete) stayed in the file, unlinked, with its
    result (tests/blender/check_robustness.py). Only this modifier uses ro: it is ours,
    whatever the object and the modifier are called now (a rename keeps the result and,
    through state.uid, the plan; the names recorded are brought up to date). Shared (a
    duplicate or a copy): the recorded names decide, and the other one gets a result of its
    own.
    """
    if not linked.local_result(ro):   # the library's result (an override's input): never ours
        return False
    owner = ro.get(state.OWNER_KEY)
    if isinstance(owner, bpy.types.ID):          # files saved before: a pointer, converted
        if owner != obj:
            return False
        ro[state.OWNER_KEY] = owner = obj.name_full
    if ro.users <= 1:
        if owner != obj.name_full:
            ro[state.OWNER_KEY] = obj.name_full
        if ro.get(state.MODIFIER_KEY) != mod.name:
            ro[state.MODIFIER_KEY] = mod.name
        return True
    return owner == obj.name_full and ro.get(state.MODIFIER_KEY) == mod.name


# --- Result Points --------------------------------------------------------------------------

def points_object(obj, mod, ro, create=True):
    """The hidden mesh object of vertices only through which positions-only updates reach
    the group (its Result Points, nodegroup), one per result object; None when the modifier
    has none of its own and create is False."""
    po = compat.get_modifier_input(mod, "Result Points")
    if po is not None and po.type == 'MESH' and po.get(state.POINTS_KEY) == state.uid(ro) \
            and linked.local_result(po):
        return po
    if not create:
        return None
    name = f"{obj.name}.{mod.name}.points"
    po = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    po[state.POINTS_KEY] = state.uid(ro)
    return po


def sends_points(mod):
    """Whether this Blender sends positions-only updates through the Result Points (before
    3.6, nodegroup) and this modifier's group has them."""
    return compat.POSITIONS_THROUGH_POINTS and \
        nodegroup.layout(mod.node_group) in nodegroup.POINTS_LAYOUTS


def set_points(obj, mod, po):
    if compat.get_modifier_input(mod, "Result Points") != po:
        compat.set_modifier_input(mod, "Result Points", po)   # a new relation: re-tag
        obj.update_tag()


def empty_points(obj, mod, ro):
    """After a write of the whole result: the group shows the result mesh as it is. Its own
    points object is emptied (and kept for the next positions-only update), another's (a
    duplicate's original's) let go."""
    if nodegroup.layout(mod.node_group) not in nodegroup.POINTS_LAYOUTS:
        return
    po = points_object(obj, mod, ro, create=False)
    if po is not None and len(po.data.vertices):
        po.data.clear_geometry()
        po.data.update()
    set_points(obj, mod, po)


# --- Stack Object ---------------------------------------------------------------------------

def stack_object(obj, mod, ro):
    """The hidden mesh object holding the vertices of the input the result was computed from
    (the group's Stack Object: the input check), one per modifier. Only vertices: the group
    compares their number and positions."""
    so = compat.get_modifier_input(mod, "Stack Object")
    key = state.uid(ro)
    if so is not None and so.type == 'MESH' and so.get(state.STACK_KEY) == key:
        return so
    name = f"{obj.name}.{mod.name}.stack"
    so = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    so[state.STACK_KEY] = key
    return so


def record(so, positions):
    """Writes the input's vertex positions into the stack object's mesh."""
    meshio.write_vertices(so.data, positions)


def set_stack_object(obj, mod, target):
    """Points the modifier's Stack Object input at `target` (None: no input check) when it
    differs (a new pointer rebuilds the depsgraph's relations); lets go of an own stack
    object no longer used."""
    if nodegroup.layout(mod.node_group) not in nodegroup.STACK_LAYOUTS:
        return
    old = compat.get_modifier_input(mod, "Stack Object")
    if old == target:
        return
    compat.set_modifier_input(mod, "Stack Object", target)
    obj.update_tag()
    if old is not None and old.get(state.STACK_KEY) is not None and old.users == 0:
        remove(old)


# --- bake host ------------------------------------------------------------------------------

def bake_object(mod):
    """The host object of the modifier's bake (bake.py), or None."""
    if not frames.has_frames(mod):   # an older layout: no bake
        return None
    host = compat.get_modifier_input(mod, "Bake Object")
    return host if host is not None and host.get(state.BAKE_KEY) == "host" else None


# --- deleting -------------------------------------------------------------------------------

def remove(so):
    """Deletes a hidden object of vertices only (a stack object, a Result Points object) of
    this file (never a library's, nor an override of one)."""
    if so.library is not None or getattr(so, "override_library", None) is not None:
        return
    mesh = so.data
    bpy.data.objects.remove(so)
    if mesh is not None and mesh.users == 0 and mesh.library is None:
        bpy.data.meshes.remove(mesh)


def hidden_objects(mod):
    """The modifier's hidden objects besides its result: (object, the key marking it ours)
    for its Stack Object and its Result Points, where its group has them."""
    found = []
    for layouts, name, key in ((nodegroup.STACK_LAYOUTS, "Stack Object", state.STACK_KEY),
                               (nodegroup.POINTS_LAYOUTS, "Result Points", state.POINTS_KEY)):
        if nodegroup.layout(mod.node_group) in layouts:
            found.append((compat.get_modifier_input(mod, name), key))
    return found


def delete_hidden(hidden):
    """Deletes the hidden objects hidden_objects found, once nothing uses them."""
    for ob, key in hidden:
        if ob is not None and ob.get(key) is not None and ob.users == 0:
            remove(ob)


def delete_result(ro):
    if ro is None:
        return
    mesh = ro.data
    bpy.data.objects.remove(ro)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)
