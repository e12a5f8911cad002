"""App handlers that keep every Smooth FFD result up to date.

Writing the result mesh tags the depsgraph, which fires depsgraph_update_post again: a guard
stops that re-entry, and update_modifier skips work when its inputs have not changed.
"""
import contextlib

import bpy
from bpy.app.handlers import persistent

from . import modifier_update, nodegroup

_busy = False
_rendering = False


def smooth_ffd_modifiers(scene=None):
    """(object, modifier) pairs of every Smooth FFD modifier in the scene (or the file)."""
    objects = scene.objects if scene is not None else bpy.data.objects
    out = []
    for obj in objects:
        if obj.type != 'MESH':
            continue
        for mod in obj.modifiers:
            if nodegroup.is_smooth_ffd_modifier(mod):
                out.append((obj, mod))
    return out


def update_all(scene=None, depsgraph=None, render=None, changed_meshes=None, force=False):
    """Updates all Smooth FFD modifiers; returns how many wrote new geometry."""
    global _busy
    if _busy:
        return 0
    _busy = True
    try:
        if scene is None:
            scene = bpy.context.scene
        if depsgraph is None:
            depsgraph = bpy.context.evaluated_depsgraph_get()
        render = _rendering if render is None else render
        count = 0
        for obj, mod in smooth_ffd_modifiers(scene):
            if not (mod.show_render if render else mod.show_viewport):
                continue
            # The object itself is re-evaluated whenever its lattice moves; only an update
            # of its mesh data means the source changed.
            mesh_changed = changed_meshes is None or obj.data in changed_meshes
            count += modifier_update.update_modifier(obj, mod, depsgraph, render=render,
                                            mesh_changed=mesh_changed, force=force)
        return count
    finally:
        _busy = False


@contextlib.contextmanager
def muted():
    """Handlers do nothing inside: our own depsgraph updates must neither recurse nor put
    the viewport level back over a render-level result (Apply)."""
    global _busy
    was = _busy
    _busy = True
    try:
        yield
    finally:
        _busy = was


def guarded(fn, *args, **kwargs):
    with muted():
        return fn(*args, **kwargs)


def _changed_ids(depsgraph):
    """Original IDs whose geometry the last evaluation updated (to skip re-reading meshes)."""
    out = set()
    for u in depsgraph.updates:
        if u.is_updated_geometry:
            out.add(u.id.original)
    return out


@persistent
def on_depsgraph_update_pre(scene, depsgraph=None):
    """Writes the result before Blender evaluates an edit, where the original data give the
    evaluated inputs (modifier_update._early_inputs): Blender then evaluates the modifier
    once, with the new result, instead of once with the old one and again after
    on_depsgraph_update."""
    global _busy
    if _busy or _rendering:
        return
    _busy = True
    try:
        for obj, mod in smooth_ffd_modifiers(scene):
            if mod.show_viewport:
                modifier_update.update_modifier(obj, mod, None, early=True)
    finally:
        _busy = False


@persistent
def on_depsgraph_update(scene, depsgraph=None):
    if _busy or depsgraph is None:
        return
    update_all(scene, depsgraph, changed_meshes=_changed_ids(depsgraph))


@persistent
def on_frame_change(scene, depsgraph=None):
    if _busy:
        return
    update_all(scene, depsgraph)


@persistent
def on_load(*_args):
    modifier_update.forget()   # in-memory plans belong to the previous file
    for _obj, mod in smooth_ffd_modifiers():
        nodegroup.migrate(mod)   # 3.4-4.0's text Backend -> 4.1+'s menu
    scene = bpy.context.scene
    if scene is not None and smooth_ffd_modifiers(scene):
        # Frame handlers may run on the render thread; the lock keeps the UI from racing it.
        scene.render.use_lock_interface = True
        update_all(scene)


@persistent
def on_undo_redo(scene, *_args):
    modifier_update.invalidate_sources()


@persistent
def on_render_pre(scene, *_args):
    global _rendering
    _rendering = True
    if smooth_ffd_modifiers(scene):
        scene.render.use_lock_interface = True
    # Final renders use the render level and exact normals; the frame is already set here.
    update_all(scene, render=True)


@persistent
def on_render_init(scene, *_args):
    # From here until the job ends, frame changes (-a) also compute at the render level.
    global _rendering
    _rendering = True


@persistent
def on_render_done(scene, *_args):
    global _rendering
    _rendering = False
    # Back to the viewport level for the interactive session.
    update_all(scene)


def is_rendering():
    return _rendering


_HANDLERS = (
    ("depsgraph_update_pre", on_depsgraph_update_pre),
    ("depsgraph_update_post", on_depsgraph_update),
    ("frame_change_post", on_frame_change),
    ("load_post", on_load),
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
