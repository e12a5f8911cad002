"""App handlers and timers that keep every Smooth FFD result up to date, each through the
one update path (pipeline.update_modifier).

Writing the result mesh tags the depsgraph, which fires depsgraph_update_post again: a guard
(state.flags.busy, state.muted) stops that re-entry, and update_modifier skips work when its
inputs have not changed.
"""
import threading

import bpy
from bpy.app.handlers import persistent

from . import compat, frames, holdframes, holds, linked, live, nodegroup, objects, pipeline, \
    stack_input, state, statusline


def smooth_ffd_modifiers(scene=None):
    """(object, modifier) pairs of every Smooth FFD modifier in the scene (or the file)
    that the add-on may write: linked objects are left out (linked.py)."""
    objects = scene.objects if scene is not None else bpy.data.objects
    out = []
    for obj in objects:
        if obj.type != 'MESH' or obj.library is not None:
            continue
        for mod in obj.modifiers:
            if nodegroup.is_smooth_ffd_modifier(mod):
                out.append((obj, mod))
    return out


def update_all(scene=None, depsgraph=None, render=None, changed_meshes=None, force=False,
               changed=None, frame_change=False, defer_stack=False, in_handler=False):
    """Updates all Smooth FFD modifiers; returns how many wrote new geometry.

    changed: (geometry, transform) sets of the original IDs the last evaluation updated
    (None: unknown); frame_change: a new frame. defer_stack (render_pre, whose depsgraph is
    the viewport's): modifiers that read the stack's geometry (stack_input) are not computed
    but cleared, so that the render depsgraph's first evaluation of the frame passes their
    input through, and frame_change_post computes them from the render's stack.
    in_handler: called from a depsgraph evaluation's handler (depsgraph_update_post,
    frame_change_post), where the depsgraph must not be evaluated again (stack_input.defer).

    Skipped: modifiers whose bake covers this frame (the group shows the bake), and in the
    viewport, objects the view layer does not show (hidden with H, in an excluded or hidden
    collection) unless something shown uses them (_needed): they are brought up to date by
    the depsgraph update that shows them again."""
    if state.flags.busy:
        return 0
    state.flags.busy = True
    try:
        if scene is None:
            scene = bpy.context.scene
        render = state.flags.rendering if render is None else render
        if not _may_write(scene):
            return 0
        if depsgraph is None:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        release_deleted_lattices()
        linked.report_scene(scene)
        stack_input.begin_pass()
        frame = frames.scene_frame(scene)
        view_layer = getattr(depsgraph, "view_layer", None) or bpy.context.view_layer
        p = state.Pass(depsgraph, scene=scene, render=render, force=force, changed=changed,
                       changed_meshes=changed_meshes, frame_change=frame_change,
                       can_evaluate=not in_handler)
        count = 0
        hidden = []
        for obj, mod in smooth_ffd_modifiers(scene):
            if not (mod.show_render if render else mod.show_viewport):
                continue
            if frames.in_bake(mod, frame):
                statusline.set_baked(obj, mod, scene)
                continue
            if not render and not force and not _shown(obj, view_layer):
                hidden.append((obj, mod))
                continue
            if defer_stack and stack_input.Stack(obj, mod, render).reads_stack:
                frames.set_frames(mod, "Result", state.NEVER)
                obj.update_tag()
                continue
            count += pipeline.update_modifier(obj, mod, p)
        if hidden:
            needed = _needed([obj for obj, _ in hidden])
            for obj, mod in hidden:
                if obj in needed:
                    count += pipeline.update_modifier(obj, mod, p)
                else:
                    state.skipped_hidden[0] += 1
        return count
    finally:
        state.flags.busy = False
        start_timers()


def _shown(obj, view_layer):
    try:
        return obj.visible_get(view_layer=view_layer)
    except (TypeError, RuntimeError):   # an object not in this view layer
        return False


def _needed(objects):
    """The hidden objects among `objects` that something shown may still use: another ID
    refers to them (a Boolean or Object Info input, a parent, a constraint: anything but the
    collections holding them), or one of those collections is instanced (a collection
    instance shows its objects even where the view layer hides or excludes them). Blender
    reports non-refcounted references too (bpy.data.user_map), so a hidden Boolean cutter is
    kept up to date. Run only when hidden objects exist, once per update."""
    users = bpy.data.user_map(subset=set(objects))
    instanced = _instanced_collections()
    needed = set()
    for obj in objects:
        refs = users.get(obj, ())
        if any(not isinstance(u, bpy.types.Collection) and u != obj and
               not isinstance(u, bpy.types.Scene) for u in refs) \
                or any(c in instanced for c in obj.users_collection):
            needed.add(obj)
    return needed


def _instanced_collections():
    """Collections shown through a collection instance, with every collection inside them."""
    out = set()
    stack = [c for c in bpy.data.collections if c.users_dupli_group]
    while stack:
        c = stack.pop()
        if c not in out:
            out.add(c)
            stack.extend(c.children)
    return out


def _may_write(scene):
    """A render started from a window calls the handlers from its job thread: writing data
    there is safe only with the interface locked. Without the lock the add-on leaves the
    data alone (the group then renders the viewport result on its own frame and the source
    mesh elsewhere) and says so on the console."""
    if threading.current_thread() is threading.main_thread() or \
            scene.render.use_lock_interface:
        return True
    print(f"Smooth FFD: not computed for this render (frame {scene.frame_current}): Render > "
          f"Lock Interface is off in scene {scene.name!r}, and the add-on writes no data from "
          f"the render thread without it; frames without a result render the source mesh")
    return False


def release_deleted_lattices():
    """Lets go of lattices the user deleted, as Blender's Lattice modifier does.

    The modifier's Lattice input is an ID property, which holds a user: a lattice deleted in
    the viewport (X) left every collection but stayed in the file, still deforming (Blender
    frees a deleted object only once nothing holds a user of it). A lattice that had another
    user this session (a collection holding it, a fake user, another ID property) and now
    has none but Smooth FFD inputs is taken out of those inputs and removed, which is what
    deleting it would have done without the add-on: pointers that hold no user (a Lattice
    modifier, a hook) are cleared too. The modifier shows the source, and its status says the
    lattice was deleted. Undo brings both back. on_load applies the same rule to files saved
    with such a lattice. A lattice that never had another user (made by a script, never
    linked) is left alone, as Blender leaves it."""
    refs = {}
    for _obj, mod in smooth_ffd_modifiers():
        try:
            lat = compat.get_modifier_input(mod, "Lattice")
        except KeyError:
            continue
        if lat is not None:
            refs.setdefault(lat, []).append((_obj, mod))
    for lat, users in refs.items():
        if lat.library is not None:   # a linked lattice is its library's business
            continue
        key = lat.as_pointer()
        # Every collection holding the lattice, a fake user or any other ID property holds a
        # user of it: more users than these inputs means it is still wanted (cheaper than
        # asking for its collections on every update).
        if lat.users > len(users):
            state.wanted_lattices.add(key)
            continue
        if key not in state.wanted_lattices:
            continue
        state.wanted_lattices.discard(key)
        for obj, mod in users:
            compat.set_modifier_input(mod, "Lattice", None)
            ro = objects.result_object(obj, mod, create=False)
            if ro is not None:   # the error message says why, also after a reload
                st = state.of_result(ro, create=True)
                st.lattice_gone = lat.name
                st.last_key = st.status_base = None
            statusline.set_status(
                obj, mod, f"Error: no lattice object set (the lattice object {lat.name!r} was "
                          f"deleted)", state.NEVER, report=False)
        bpy.data.objects.remove(lat)


# --- timers ---------------------------------------------------------------------------------

def settle():
    """The timer after live editing (live.py): once nothing changed for state.SETTLE seconds,
    updates every modifier, which computes the exact normals of the results computed without
    them (their key differs); else runs again when that time has come."""
    wait = live.wait()
    if wait > 0:
        return wait
    update_all(bpy.context.scene)
    return None


def _deferred_update():
    """The timer of a stack reading deferred to the next evaluation (stack_input.defer)."""
    update_all(bpy.context.scene)
    return None


def start_timers():
    """Registers the timers the last round of updates asked for (state.pending_timers): in a
    window only (background mode runs no timers), a deferred stack reading only from the
    main thread."""
    wanted = set(state.pending_timers)
    state.pending_timers.clear()
    if bpy.app.background:
        return
    if "settle" in wanted and not bpy.app.timers.is_registered(settle):
        bpy.app.timers.register(settle, first_interval=state.SETTLE)
    if "stack" in wanted and threading.current_thread() is threading.main_thread() \
            and not bpy.app.timers.is_registered(_deferred_update):
        bpy.app.timers.register(_deferred_update, first_interval=0.0)


def _changed_ids(depsgraph):
    """(geometry, transform): original IDs whose geometry / transform the last evaluation
    updated (to skip re-reading meshes and the stack's geometry)."""
    geometry, transform = set(), set()
    for u in depsgraph.updates:
        if u.is_updated_geometry:
            geometry.add(u.id.original)
        if u.is_updated_transform:
            transform.add(u.id.original)
    return geometry, transform


@persistent
def on_depsgraph_update_pre(scene, depsgraph=None):
    """Writes the result before Blender evaluates an edit, where the original data give the
    evaluated inputs (gather.early_inputs): Blender then evaluates the modifier once, with
    the new result, instead of once with the old one and again after on_depsgraph_update."""
    if state.flags.busy or state.flags.rendering:
        return
    state.flags.busy = True
    try:
        frame = frames.scene_frame(scene)
        view_layer = bpy.context.view_layer
        p = state.Pass(None, scene=scene, early=True)
        for obj, mod in smooth_ffd_modifiers(scene):
            if mod.show_viewport and not frames.in_bake(mod, frame) and _shown(obj, view_layer):
                pipeline.update_modifier(obj, mod, p)
    finally:
        state.flags.busy = False
        start_timers()


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    if state.flags.busy or depsgraph is None:
        return
    changed = _changed_ids(depsgraph)
    update_all(scene, depsgraph, changed_meshes=changed[0], changed=changed, in_handler=True)


@persistent
def on_frame_change(scene, depsgraph=None):
    if state.flags.busy:
        return
    update_all(scene, depsgraph, frame_change=True, in_handler=True)


@persistent
def on_load(*_args):
    state.forget_session()   # in-memory plans and reports belong to the previous file
    for obj, mod in smooth_ffd_modifiers():
        try:
            nodegroup.migrate(mod)   # older layouts -> this Blender's (menu, frame ranges)
        except ImportError as e:
            # No core for this Blender: the group stays as saved (its limits are the core's),
            # and the status says what to install.
            statusline.fail(obj, mod, None, str(e))
            continue
        # A lattice saved in no collection was kept only by Smooth FFD inputs (older add-ons
        # held deleted lattices): count it as wanted once, so that it is let go of.
        try:
            lat = compat.get_modifier_input(mod, "Lattice")
        except KeyError:
            continue
        if lat is not None and not lat.users_collection:
            state.wanted_lattices.add(lat.as_pointer())
    scene = bpy.context.scene
    if scene is not None:
        linked.report_scene(scene, force=True)
    if scene is not None and smooth_ffd_modifiers(scene):
        update_all(scene)


@persistent
def on_save_pre(*_args):
    """The saved status of a result bound to one frame says what Blender without the add-on
    shows on the others (the group's choice, nodegroup); on_save_post puts the session's
    status back, so the note is in the file only."""
    state.saved_status.clear()
    for obj, mod in smooth_ffd_modifiers():
        try:
            lo, hi = frames.get_frames(mod, "Result")
            text = compat.get_modifier_input(mod, "Status")
        except KeyError:
            continue
        if (lo, hi) in (state.ALWAYS, state.NEVER) or not text.startswith("OK"):
            continue
        state.saved_status[(obj.name_full, mod.name)] = text
        compat.set_modifier_input(mod, "Status", f"{text} \u2014 {saved_note(lo, hi)}")


def saved_note(lo, hi):
    return (f"saved: without the add-on, frames other than {(lo + hi) / 2:g} show the source "
            f"mesh (bake them for Blender without the add-on)")


@persistent
def on_save_post(*_args):
    for obj, mod in smooth_ffd_modifiers():
        text = state.saved_status.get((obj.name_full, mod.name))
        if text is not None:
            compat.set_modifier_input(mod, "Status", text)
    state.saved_status.clear()


@persistent
def on_undo_redo(scene, *_args):
    state.invalidate_sources()


@persistent
def on_render_pre(scene, *_args):
    state.flags.rendering = True
    # With motion blur, a moving input's shutter subframes hold the pieces the rendered frame
    # is cut into (plans.hold_pieces): one output topology over the shutter.
    state.flags.renders += 1
    state.flags.render_shutter = holds.shutter(scene) + (
        scene.frame_current + scene.frame_subframe, state.flags.renders) if holds.motion_blur(scene) else None
    # With motion blur, adaptive tessellations get one topology over the frame's shutter
    # (holdframes.hold_shutter: the subframes are evaluated here, before the render's).
    if not state.flags.busy:
        for (name, mod_name), note in holdframes.hold_shutter(
                scene, smooth_ffd_modifiers(scene)).items():
            print(f"Smooth FFD [{name} / {mod_name}]: motion blur: {note}")
    # Final renders use the render level and exact normals; the frame is already set here.
    # Modifiers reading the stack's geometry wait for the render depsgraph (frame_change_post).
    update_all(scene, render=True, defer_stack=True)


@persistent
def on_render_init(scene, *_args):
    # From here until the job ends, frame changes (-a) also compute at the render level.
    state.flags.rendering = True


@persistent
def on_render_done(scene, *_args):
    state.flags.rendering = False
    state.flags.render_shutter = None
    holdframes.end_shutter(smooth_ffd_modifiers(scene))
    # Back to the viewport level for the interactive session; modifiers reading the stack's
    # geometry read the viewport's on its next evaluation (their result is the render's).
    update_all(scene, defer_stack=True)


def is_rendering():
    return state.flags.rendering


_HANDLERS = (
    ("depsgraph_update_pre", on_depsgraph_update_pre),
    ("depsgraph_update_post", on_depsgraph_update),
    ("frame_change_post", on_frame_change),
    ("load_post", on_load),
    ("save_pre", on_save_pre),
    ("save_post", on_save_post),
    ("undo_post", on_undo_redo),
    ("redo_post", on_undo_redo),
    ("render_init", on_render_init),
    ("render_pre", on_render_pre),
    ("render_cancel", on_render_done),
    ("render_complete", on_render_done),
)


def register():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn not in lst:
            lst.append(fn)


def unregister():
    for name, fn in _HANDLERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
    # Timers of this module's updates (live editing's settle, a deferred stack reading): a
    # disabled add-on runs none.
    for fn in (settle, _deferred_update):
        if bpy.app.timers.is_registered(fn):
            bpy.app.timers.unregister(fn)
