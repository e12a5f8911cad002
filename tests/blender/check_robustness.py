"""Robustness of the live add-on (Blender side), the cases check_live.py does not
cover: deleting the deformed object, renaming the object / lattice / modifier, linking the
object into another scene, and edits or frame changes requested while a render runs.

In every case: no exception reaches Blender from our handlers (sys.excepthook records what
Blender's handler caller prints), the source mesh is unchanged (vertex coordinates and
counts), and the status line (`smooth_ffd.status(mod)`) is a clear "OK ..." or "Error: ...".
"""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, handlers  # noqa: E402

TOL = 1e-5
VIEWPORT, RENDER = 1, 2

# Blender prints an exception raised in an app handler through PyErr_Print, which calls
# sys.excepthook: record them so that a failing handler is a failing check, not a log line.
_handler_errors = []
_prev_hook = sys.excepthook


def _hook(tp, value, tb):
    _handler_errors.append(f"{tp.__name__}: {value}")
    _prev_hook(tp, value, tb)


sys.excepthook = _hook


def no_handler_errors(name):
    errs = list(_handler_errors)
    _handler_errors.clear()
    T.check(f"{name}: no exception in handlers", not errs, "; ".join(errs[:3]))


def scene(kind="suzanne", level=VIEWPORT):
    T.clear()
    for sc in list(bpy.data.scenes):
        if sc != bpy.context.scene:
            bpy.data.scenes.remove(sc)
    obj = T.make_mesh(kind)
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=3)
    ref = T.lattice_modifier_twin(obj, lat)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=RENDER)
    T.update()
    return obj, lat, ref, mod


def digest(mesh):
    return (T.positions(mesh).tobytes(), len(mesh.vertices), len(mesh.polygons), len(mesh.loops))


def status_ok(mod):
    return smooth_ffd.status(mod).startswith("OK")


def parity(name, obj, lat, ref, mod, got=None):
    """Evaluated result's first V vertices == Blender's Lattice modifier, and status OK."""
    if got is None:
        got = T.positions(T.evaluated_mesh(obj))
    exp = T.positions(T.evaluated_mesh(ref))
    if len(got) < len(exp):
        T.check(name, False, f"{len(got)} < {len(exp)} vertices, {smooth_ffd.status(mod)}")
        return
    err = np.abs(got[:len(exp)] - exp).max() / T.lattice_size(obj, lat)
    T.check(name, err <= TOL and status_ok(mod), f"err {err:.2e}, {smooth_ffd.status(mod)}")


def result_objects():
    return [o for o in bpy.data.objects if T.state.OWNER_KEY in o.keys()]


# --- deleting the deformed object -----------------------------------------------------------

def test_delete_object():
    obj, lat, ref, mod = scene("cube")
    me = obj.data                      # shared with the twin, so it outlives obj
    src = digest(me)
    ro_name = T.objects.result_object(obj, mod, create=False).name
    # A second deformed object that must keep working.
    other = T.link(bpy.data.objects.new("other", bpy.data.meshes.new("other")))
    other.data = me.copy()
    other.location.x = 0.2
    mod2 = smooth_ffd.add_smooth_ffd(other, lat, viewport_level=VIEWPORT, render_level=RENDER)
    other_ref = T.lattice_modifier_twin(other, lat)
    T.update()

    bpy.data.objects.remove(obj)
    T.update()
    lat.data.points[4].co_deform.z += 0.3
    T.update()
    handlers.update_all(bpy.context.scene)          # a direct call raises what a handler would
    bpy.context.scene.frame_set(2)
    no_handler_errors("delete object")
    T.check("delete object: source mesh intact", digest(me) == src)
    ro = bpy.data.objects.get(ro_name)
    harmless = ro is None or (ro.users == 0 and not ro.users_collection)
    T.check("delete object: its hidden result is gone or an unused orphan", harmless,
            "gone" if ro is None else f"users {ro.users}")
    if ro is not None:
        # An orphan: not saved, and purging it (File > Clean Up) is fine.
        rmesh = ro.data
        bpy.data.objects.remove(ro)
        if rmesh is not None and rmesh.users == 0:
            bpy.data.meshes.remove(rmesh)
        T.update()
        no_handler_errors("delete object: orphan result removed")
    parity("delete object: the other object still live", other, lat, other_ref, mod2)

    # The operator path (what the UI's X does), with undo back to the object.
    ro_name = T.objects.result_object(other, mod2, create=False).name
    bpy.ops.ed.undo_push(message="before delete")
    for o in bpy.context.view_layer.objects:
        o.select_set(o == other)
    bpy.context.view_layer.objects.active = other
    res = bpy.ops.object.delete()
    print("object.delete:", res)
    bpy.ops.ed.undo_push(message="deleted")
    T.update()
    no_handler_errors("operator delete")
    # Nothing may keep the deleted object alive (it would stay in the file, unseen).
    gone = bpy.data.objects.get("other")
    T.check("operator delete: object gone from the file", gone is None,
            "" if gone is None else f"still there, {gone.users} users")
    ro = bpy.data.objects.get(ro_name)
    T.check("operator delete: hidden result unused (not saved)", ro is None or ro.users == 0,
            "" if ro is None else f"{ro.users} users")
    bpy.ops.ed.undo()
    T.update()
    other = bpy.data.objects.get("other")
    T.check("undo delete: object back", other is not None)
    if other is not None:
        lat = bpy.data.objects["lat"]
        lat.data.points[10].co_deform.x -= 0.2
        T.update()
        parity("undo delete: live again", other, lat, bpy.data.objects["other.ref"],
               other.modifiers[0])
    no_handler_errors("undo delete")

    # A new object under the deleted one's name and modifier name: no stale state reused.
    me3 = bpy.data.meshes.new("src3")
    me3.from_pydata([(x, y, z) for x in (-0.5, 0.4) for y in (-0.45, 0.5) for z in (-0.5, 0.3)],
                    [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6),
                         (0, 2, 6, 4), (1, 5, 7, 3)])
    lat = bpy.data.objects["lat"]
    new = T.link(bpy.data.objects.new("src", me3))
    mod3 = smooth_ffd.add_smooth_ffd(new, lat, viewport_level=VIEWPORT, render_level=RENDER)
    T.update()
    parity("same name after delete: fresh result", new, lat, T.lattice_modifier_twin(new, lat), mod3)
    no_handler_errors("same name after delete")


# --- renaming -------------------------------------------------------------------------------

def test_rename():
    obj, lat, ref, mod = scene()
    src = digest(obj.data)
    ro = T.objects.result_object(obj, mod, create=False)
    obj.name = "renamed object"
    lat.name = "renamed lattice"
    lat.data.name = "renamed lattice data"
    obj.data.name = "renamed mesh"
    T.update()
    parity("rename object and lattice", obj, lat, ref, mod)
    lat.data.points[4].co_deform.z += 0.4
    T.update()
    parity("rename: lattice edit still live", obj, lat, ref, mod)
    T.check("rename: same hidden result object", T.objects.result_object(obj, mod, create=False) == ro)
    # Renaming the modifier itself.
    mod.name = "Renamed FFD"
    mod = obj.modifiers["Renamed FFD"]
    lat.data.points[1].co_deform.y += 0.2
    T.update()
    parity("rename modifier: still live", obj, lat, ref, mod)
    used = [o for o in result_objects() if o.users > 0]
    T.check("rename modifier: one result in use", len(used) == 1, str([o.name for o in used]))
    no_handler_errors("rename")
    T.check("rename: source mesh intact", digest(obj.data) == src)


# --- linking into another scene -------------------------------------------------------------

def scene_depsgraph(sc):
    """A scene's view layer depsgraph without a window showing it (background mode): made
    on demand by evaluated_depsgraph_get in a context whose scene and view layer are sc's."""
    vl = sc.view_layers[0]
    if vl.depsgraph is None:
        with bpy.context.temp_override(scene=sc, view_layer=vl):
            bpy.context.evaluated_depsgraph_get()
    return vl.depsgraph


def test_other_scene():
    obj, lat, ref, mod = scene()
    src = digest(obj.data)
    other = bpy.data.scenes.new("Other")
    other.collection.objects.link(obj)          # the lattice stays in the first scene only
    dg2 = scene_depsgraph(other)
    dg2.update()
    got2 = T.positions(obj.evaluated_get(dg2).data)
    parity("linked into another scene: same result there", obj, lat, ref, mod, got=got2)
    # An edit evaluated only in the other scene's depsgraph (as when its window is active;
    # background mode has no window to switch, so update that view layer's depsgraph).
    lat.data.points[13].co_deform.z += 0.35
    lat.data.update_tag()
    dg2.update()
    dg2.update()    # our handler writes the result during the first; the second shows it
    got2 = T.positions(obj.evaluated_get(dg2).data)
    no_handler_errors("other scene: update")
    parity("other scene: lattice edit seen there", obj, lat, ref, mod, got=got2)
    # Now also the lattice linked there, and the other scene's frame changed.
    other.collection.objects.link(lat)
    lat.data.points[0].co_deform.x += 0.25
    lat.data.update_tag()
    other.frame_set(3)
    dg2.update()
    got2 = T.positions(obj.evaluated_get(dg2).data)
    parity("other scene: frame change there", obj, lat, ref, mod, got=got2)
    handlers.update_all(other, dg2)
    # Unlinked from the first scene: only the other scene has it.
    for coll in list(obj.users_collection):
        if coll != other.collection:
            coll.objects.unlink(obj)
    T.update()
    lat.data.points[2].co_deform.x -= 0.2
    lat.data.update_tag()
    dg2.update()
    dg2.update()
    got2 = T.positions(obj.evaluated_get(dg2).data)
    parity("other scene only: still live", obj, lat, ref, mod, got=got2)
    # Removing the other scene leaves the object with no scene: harmless.
    bpy.data.scenes.remove(other)
    T.update()
    no_handler_errors("other scene")
    T.check("other scene: source mesh intact", digest(obj.data) == src)
    T.check("other scene: status line", status_ok(mod), smooth_ffd.status(mod))


# --- updates while rendering ----------------------------------------------------------------

def render_setup(obj, lat, ref):
    sc = bpy.context.scene
    ref.hide_render = True
    T.tiny_cycles((0, -5, 0))
    sc.render.filepath = os.path.join(tempfile.mkdtemp(), "frame.png")
    p = lat.data.points[13]
    p.co_deform = (0.0, 0.0, 0.0)
    p.keyframe_insert("co_deform", frame=1)
    p.co_deform = (0.0, 0.0, 0.8)
    p.keyframe_insert("co_deform", frame=5)
    sc.frame_set(1)
    T.update()


def render_with(pre=None, post=None):
    """Renders one still; returns what the result mesh held while it rendered."""
    record = []

    def probe(scene, *_):
        obj = bpy.data.objects["src"]
        mod = obj.modifiers[0]
        ro = T.objects.result_object(obj, mod, create=False)
        record.append({"tris": len(ro.data.polygons), "status": smooth_ffd.status(mod),
                       "positions": T.positions(ro.data)[:len(obj.data.vertices)]})

    added = [("render_post", probe)]
    if pre is not None:
        added.append(("render_pre", pre))     # after the add-on's own render_pre
    if post is not None:
        added.append(("render_post", post))
    for name, fn in added:
        getattr(bpy.app.handlers, name).append(fn)
    try:
        bpy.ops.render.render(write_still=True)
    finally:
        for name, fn in added:
            getattr(bpy.app.handlers, name).remove(fn)
    return record


def test_render_during_updates():
    obj, lat, ref, mod = scene()
    render_setup(obj, lat, ref)
    src = digest(obj.data)
    sc = bpy.context.scene
    npatch = T.patches(obj, mod)
    size = T.lattice_size(obj, lat)

    # 1. Render right after an edit, with no depsgraph update in between.
    lat.data.points[4].co_deform.z += 0.3
    rec = render_with()
    T.update()
    T.check("render right after edit: rendered", len(rec) == 1, str(len(rec)))
    if rec:
        err = np.abs(rec[0]["positions"] - T.positions(T.evaluated_mesh(ref))).max() / size
        T.check("render right after edit: renders the edited lattice at render level",
                err <= TOL and rec[0]["tris"] == npatch * RENDER ** 2
                and rec[0]["status"].startswith("OK"),
                f"err {err:.2e}, {rec[0]['tris']} tris, {rec[0]['status']}")
    no_handler_errors("render right after edit")

    # 2. A lattice edit made by another render_pre handler, after the add-on computed the
    #    render result: the render shows the old or the new lattice (never a torn mesh),
    #    and the session is up to date and at the viewport level afterwards.
    old = T.positions(T.evaluated_mesh(ref))

    def edit(scene, *_):
        bpy.data.objects["lat"].data.points[22].co_deform.x += 0.3
    rec = render_with(pre=edit)
    T.update()
    new = T.positions(T.evaluated_mesh(ref))
    T.check("edit in render_pre: rendered", len(rec) == 1, str(len(rec)))
    if rec:
        e_old = np.abs(rec[0]["positions"] - old).max() / size
        e_new = np.abs(rec[0]["positions"] - new).max() / size
        T.check("edit in render_pre: rendered geometry is the old or the new lattice's",
                min(e_old, e_new) <= TOL, f"err vs old {e_old:.2e}, vs new {e_new:.2e}")
    parity("edit in render_pre: live afterwards", obj, lat, ref, mod)
    n = len(T.evaluated_mesh(obj).polygons)
    T.check("edit in render_pre: viewport level afterwards", n == npatch * VIEWPORT ** 2, f"{n}")
    no_handler_errors("edit in render_pre")

    # 3. A frame change requested from render_post (while the render job still runs).
    def jump(scene, *_):
        scene.frame_set(4)
    rec = render_with(post=jump)
    T.update()
    T.check("frame change in render_post: rendered", len(rec) == 1 and sc.frame_current == 4,
            f"{len(rec)} renders, frame {sc.frame_current}")
    parity("frame change in render_post: live at the new frame", obj, lat, ref, mod)
    n = len(T.evaluated_mesh(obj).polygons)
    T.check("frame change in render_post: viewport level afterwards",
            n == npatch * VIEWPORT ** 2, f"{n}")
    T.check("render: handlers' render flag cleared", not handlers.is_rendering())
    no_handler_errors("frame change in render_post")

    # 4. A bad setting made during the render: an error status, the source shown, and
    #    recovery once fixed.
    def break_it(scene, *_):
        compat = T.compat
        m = bpy.data.objects["src"].modifiers[0]
        if compat.HAS_MENU_SOCKET:   # a menu holds only its items: a number that is none
            m[compat.input_identifier(m.node_group, "Backend")] = 99
        else:
            compat.set_modifier_input(m, "Backend", "gpu9")
    rec = render_with(pre=break_it)
    T.update()
    st = smooth_ffd.status(mod)
    T.check("bad setting during render: error status", st.startswith("Error"), st)
    compat = T.compat
    compat.set_modifier_input(mod, "Backend", "auto")
    obj.update_tag()
    T.update()
    parity("bad setting during render: recovers", obj, lat, ref, mod)
    no_handler_errors("bad setting during render")
    T.check("render: source mesh intact", digest(obj.data) == src)


def main():
    T.setup()
    for fn in (test_delete_object, test_rename, test_other_scene, test_render_during_updates):
        T.run(fn.__name__, fn)
    no_handler_errors("end")
    T.finish()


main()
