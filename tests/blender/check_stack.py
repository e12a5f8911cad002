"""Smooth FFD as a modifier among modifiers: the bake, a file without the add-on, lattice deletion, hidden objects, renames, Lock Interface.

- Bake: frames baked into the file render right in a Blender without the add-on (a second
  process, `blender -b --factory-startup` on 3.4, a bpy process that never imports the add-on
  on 4.2+: noaddon_eval.py), with the same positions, normals, UV maps and materials as the
  live result, frames whose triangle count differs included; Clear Bake makes it live again.
- Without the add-on and without a bake, no frame shows another frame's result: the saved
  result on its own frame (or on every frame when nothing it depends on is animated), the
  source mesh elsewhere, in the viewport and in a render; the saved status names the frame.
- Deleting the lattice lets it go as Blender's Lattice modifier does (no user left, the
  source shown, the status says why; undo brings it back; files saved with such a ghost
  lose it on load).
- Hidden objects (H, excluded collection) are not recomputed on edits, but when shown; a
  hidden object something shown uses (Boolean operand, collection instance) still is.
- Renaming the object or the modifier keeps the result object and the plan.
- Render > Lock Interface: never changed in background mode, by loading or by rendering; in
  a window session add_smooth_ffd turns it on and says so; renders from another thread
  without it write nothing.
"""
import json
import os
import sys
import tempfile
import threading

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, compat, handlers, nodegroup  # noqa: E402

TOL = 1e-5
VIEWPORT, RENDER = 1, 2


# --- helpers --------------------------------------------------------------------------------

def scene_setup(kind="suzanne", animate=True, move_at=4):
    """Suzanne with two UV maps, two materials and a vertex group; a 3x3x3 lattice whose
    middle point moves on frames 1-3 and whose object jumps at frame `move_at` (the mesh is
    clipped into other patches from there: another triangle count)."""
    T.clear()
    sc = bpy.context.scene
    sc.render.use_lock_interface = False
    obj = T.make_mesh(kind)
    me = obj.data
    me.uv_layers.new(name="Second")
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers["Second"].data.foreach_get("uv", uv)
    me.uv_layers["Second"].data.foreach_set("uv", (uv * 0.5 + 0.25).astype(np.float32))
    for name in ("Red", "Blue"):
        me.materials.append(bpy.data.materials.new(name))
    mi = (np.arange(len(me.polygons)) % 2).astype(np.int32)
    me.polygons.foreach_set("material_index", mi)
    vg = obj.vertex_groups.new(name="Group")
    vg.add(list(range(0, len(me.vertices), 3)), 0.7, 'REPLACE')
    me.update()
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    if animate:
        p = lat.data.points[13]
        p.co_deform = (0.0, 0.0, 0.0)
        p.keyframe_insert("co_deform", frame=1)
        p.co_deform = (0.0, 0.0, 0.6)
        p.keyframe_insert("co_deform", frame=3)
        lat.location = (0, 0, 0)
        lat.keyframe_insert("location", frame=1)
        lat.keyframe_insert("location", frame=move_at - 1)
        lat.location = (0.23, 0.11, -0.07)
        lat.keyframe_insert("location", frame=move_at)
        for fc in _fcurves(lat):
            for k in fc.keyframe_points:
                k.interpolation = 'CONSTANT'
        for fc in _fcurves(lat.data):
            for k in fc.keyframe_points:
                k.interpolation = 'LINEAR'
    sc.frame_start, sc.frame_end = 1, 5
    sc.frame_set(1)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=VIEWPORT, render_level=RENDER)
    T.update()
    return obj, lat, mod


def _fcurves(id_data):
    """F-curves of an ID's action (5.0 keeps them in layered-action channel bags)."""
    ad = id_data.animation_data
    action = ad.action if ad is not None else None
    if action is None:
        return []
    if hasattr(action, "fcurves") and len(action.fcurves):
        return list(action.fcurves)
    out = []
    for layer in getattr(action, "layers", []):
        for strip in layer.strips:
            for bag in getattr(strip, "channelbags", []):
                out.extend(bag.fcurves)
    return out


def camera(sc):
    cam = T.link(bpy.data.objects.new("cam", bpy.data.cameras.new("cam")))
    cam.location = (0, -5, 0)
    cam.rotation_euler = (np.pi / 2, 0, 0)
    sc.camera = cam
    sc.render.engine = 'CYCLES'
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False   # Debian's build has no OpenImageDenoise
    sc.cycles.device = 'CPU'
    sc.render.resolution_x = sc.render.resolution_y = 40
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.render.image_settings.file_format = 'PNG'
    sc.render.image_settings.color_mode = 'RGBA'


def plain_copy(mesh, name, hide=True):
    """A linked object holding a copy of `mesh`, no modifiers: a reference for renders."""
    ob = T.link(bpy.data.objects.new(name, mesh.copy()))
    ob.hide_render = hide
    return ob


def snapshot(mesh):
    """What the comparisons look at in an evaluated mesh."""
    uvs = {}
    for layer in mesh.uv_layers:
        uv = np.empty(len(mesh.loops) * 2, np.float32)
        layer.data.foreach_get("uv", uv)
        uvs[layer.name] = uv.reshape(-1, 2)
    mat = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", mat)
    return {"pos": T.positions(mesh).astype(np.float32), "cv": T.triangles_like_loops(mesh),
            "nrm": T.corner_normals(mesh).astype(np.float32), "uv": uvs, "mat": mat,
            "mats": [m.name if m else "" for m in mesh.materials]}


def from_npz(data, key):
    names = json.loads(str(data[key + "/uvnames"]))
    return {"pos": data[key + "/pos"], "cv": data[key + "/cv"], "nrm": data[key + "/nrm"],
            "uv": {n: data[f"{key}/uv{i}"] for i, n in enumerate(names)},
            "mat": data[key + "/mat"], "mats": json.loads(str(data[key + "/mats"]))}


def same(name, got, exp, nrm_tol=1e-5):
    """Bitwise-equal topology, UV maps and materials; positions and normals within float
    tolerance (they are copies, so in practice equal too)."""
    if got["pos"].shape != exp["pos"].shape or not np.array_equal(got["cv"], exp["cv"]):
        T.check(name, False, f"{len(got['pos'])} vs {len(exp['pos'])} vertices, "
                             f"{len(got['cv'])} vs {len(exp['cv'])} corners")
        return
    dp = float(np.abs(got["pos"] - exp["pos"]).max())
    dn = float(np.abs(got["nrm"] - exp["nrm"]).max())
    uv_ok = list(got["uv"]) == list(exp["uv"]) and all(
        np.array_equal(got["uv"][k], exp["uv"][k]) for k in exp["uv"])
    mat_ok = np.array_equal(got["mat"], exp["mat"]) and got["mats"] == exp["mats"]
    T.check(name, dp <= 1e-6 and dn <= nrm_tol and uv_ok and mat_ok,
            f"{len(exp['cv']) // 3} tris, pos {dp:.1e}, normals {dn:.1e}, "
            f"uv maps {list(got['uv'])} {'equal' if uv_ok else 'DIFFER'}, "
            f"materials {'equal' if mat_ok else 'DIFFER'}")


def without_addon(blend, frames=(), objects=(), renders=()):
    """Runs noaddon_eval.py on `blend` in a fresh Blender of this version that does not
    load the add-on (empty user profile; 3.4: --factory-startup); returns its .npz."""
    data = T.run_without_addon(blend, frames, objects, renders)
    T.check("no-add-on Blender: the add-on was not loaded",
            json.loads(str(data["addon_modules"])) == [] and
            json.loads(str(data["addon_handlers"])) == [],
            f"{data['addon_modules']} {data['addon_handlers']}")
    return data


def status(mod):
    return smooth_ffd.status(mod)


# --- 4. bake --------------------------------------------------------------------------------

def test_bake():
    obj, lat, mod = scene_setup()
    sc = bpy.context.scene
    frames = list(range(1, 6))
    live = {}
    for f in frames:   # the live result at the render level, frame by frame
        sc.frame_set(f)
        smooth_ffd.update(obj, mod, render=True)
        live[f] = snapshot(T.evaluated_mesh(obj))
    tris = {f: len(live[f]["cv"]) // 3 for f in frames}
    T.check("bake scene: the lattice object's jump changes the triangle count",
            tris[3] != tris[4] and tris[4] == tris[5], str(tris))
    sc.frame_set(2)
    T.update()
    ro = T.objects.result_object(obj, mod, create=False)
    meshes = smooth_ffd.bake_smooth_ffd(obj, mod, 1, 5)
    T.check("bake: frames with equal inputs share a mesh (4 and 5)", meshes == 4, str(meshes))
    T.check("bake: status says baked", status(mod).startswith("Baked: frames 1-5"), status(mod))
    for f in frames:
        sc.frame_set(f)
        T.update()
        same(f"bake, with the add-on: frame {f} is the live render-level result",
             snapshot(T.evaluated_mesh(obj)), live[f])
    # Inside the bake, edits do not show (as with any bake) and nothing is computed.
    before = T.state.counters["computed"]
    lat.data.points[0].co_deform.x += 0.2
    T.update()
    same("bake: an edit inside the baked frames shows the bake",
         snapshot(T.evaluated_mesh(obj)), live[5])
    T.check("bake: nothing computed inside the baked frames",
            T.state.counters["computed"] == before)
    lat.data.points[0].co_deform.x -= 0.2
    # Outside the bake the modifier is live (viewport level).
    sc.frame_set(7)
    T.update()
    n = len(T.evaluated_mesh(obj).polygons)
    T.check("bake: live outside the baked frames", status(mod).startswith("OK") and
            n == T.patches(obj, mod) * VIEWPORT ** 2, f"{n} tris, {status(mod)}")
    live7 = snapshot(T.evaluated_mesh(obj))

    # A machine without the add-on.
    camera(sc)
    for f in (2, 4):   # plain meshes of the live results, to render beside the baked object
        me = bpy.data.meshes.new(f"live{f}")
        _fill(me, live[f])
        T.link(bpy.data.objects.new(f"ref{f}", me)).hide_render = True
    sc.frame_set(2)
    T.update()
    path = os.path.join(tempfile.mkdtemp(), "baked.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    print(f"baked file: {os.path.getsize(path) / 1e6:.2f} MB for {meshes} meshes of up to "
          f"{max(tris.values())} triangles")
    renders = [{"frame": 4, "show": "src", "name": "ours4"},
               {"frame": 4, "show": "ref4", "name": "ref4"},
               {"frame": 4, "show": "ref2", "name": "ref2"}]
    data = without_addon(path, frames + [7, 8], ["src"], renders)
    for f in frames:
        same(f"bake, without the add-on: frame {f} is the live render-level result",
             from_npz(data, f"src/{f}"), live[f])
    # The live result saved was computed on frame 7 (the baked frames compute nothing).
    same("bake, without the add-on: frame 7 shows the live result saved for it",
         from_npz(data, "src/7"), live7)
    src = T.positions(obj.data).astype(np.float32)
    got8 = data["src/8/pos"]
    T.check("bake, without the add-on: a frame neither baked nor saved shows the source",
            got8.shape == src.shape and np.abs(got8 - src).max() == 0,
            f"{got8.shape} vs {src.shape}")
    ours, ref4, ref2 = (data[f"render/{n}"] > 0.5 for n in ("ours4", "ref4", "ref2"))
    diff, other = float((ours != ref4).mean()), float((ref2 != ref4).mean())
    T.check("bake, without the add-on: the render of frame 4 draws frame 4's geometry",
            ours.mean() > 0.02 and diff < other / 3, f"mask mismatch {diff:.3f} "
            f"(frame 2's geometry: {other:.3f}), coverage {ours.mean():.2f}")

    # Clear Bake: live again on those frames.
    bpy.ops.wm.open_mainfile(filepath=path)
    obj, lat = bpy.data.objects["src"], bpy.data.objects["lat"]
    mod = obj.modifiers[0]
    T.update()
    T.check("bake: reopened with the add-on, the bake is kept", status(mod).startswith("Baked"),
            status(mod))
    had = smooth_ffd.clear_bake(obj, mod)
    left = [o.name for o in bpy.data.objects if o.get(T.state.BAKE_KEY) is not None]
    T.check("clear bake: the bake's objects are gone", had and not left, str(left))
    T.update()
    n = len(T.evaluated_mesh(obj).polygons)
    T.check("clear bake: live again (viewport level)", status(mod).startswith("OK") and
            n == T.patches(obj, mod) * VIEWPORT ** 2, f"{n} tris, {status(mod)}")
    # Remove deletes a bake with the modifier.
    smooth_ffd.bake_smooth_ffd(obj, mod, 2, 3)
    smooth_ffd.remove_smooth_ffd(obj, mod)
    left = [o.name for o in bpy.data.objects if o.get(T.state.BAKE_KEY) is not None]
    T.check("remove: the bake goes with the modifier", not left, str(left))

    # Apply inside the baked frames applies what the modifier shows (the bake) and deletes it.
    obj, lat, mod = scene_setup()
    sc = bpy.context.scene
    sc.frame_set(4)
    smooth_ffd.update(obj, mod, render=True)
    want = snapshot(T.evaluated_mesh(obj))
    smooth_ffd.bake_smooth_ffd(obj, mod, 3, 5)
    sc.frame_set(4)
    T.update()
    smooth_ffd.apply_smooth_ffd(obj, mod)
    T.update()
    left = [o.name for o in bpy.data.objects if o.get(T.state.BAKE_KEY) is not None]
    got = T.positions(obj.data).astype(np.float32)
    T.check("apply inside the baked frames: the baked mesh, the bake deleted",
            not obj.modifiers and not left and got.shape == want["pos"].shape and
            np.abs(got - want["pos"]).max() <= 1e-6, f"{got.shape} vs {want['pos'].shape}, {left}")


# --- 4. without the add-on and without a bake: no other frame's result ----------------------

def test_stale_without_addon():
    obj, lat, mod = scene_setup()
    sc = bpy.context.scene
    camera(sc)
    src = T.positions(obj.data).astype(np.float32)
    sc.frame_set(3)
    T.update()
    lo, hi = T.frames.get_frames(mod, "Result")
    T.check("animated lattice: the result belongs to frame 3 only", (lo, hi) == (2.5, 3.5),
            f"[{lo}, {hi})")
    T.check("animated lattice: the status names the frame", ", frame 3, " in status(mod),
            status(mod))
    live3 = snapshot(T.evaluated_mesh(obj))
    ro = T.objects.result_object(obj, mod, create=False)
    plain_copy(ro.data, "saved3")
    plain_copy(obj.data, "src.plain")
    path = os.path.join(tempfile.mkdtemp(), "stale.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    renders = [{"frame": 1, "show": "src", "name": "ours1"},
               {"frame": 1, "show": "src.plain", "name": "source"},
               {"frame": 1, "show": "saved3", "name": "saved3"}]
    data = without_addon(path, [3, 1, 5], ["src"], renders)
    same("without the add-on: the saved frame (3) shows the saved result",
         from_npz(data, "src/3"), live3)
    for f in (1, 5):
        got = data[f"src/{f}/pos"]
        T.check(f"without the add-on: frame {f} shows the source mesh, not frame 3's result",
                got.shape == src.shape and np.abs(got - src).max() == 0,
                f"{len(got)} vertices (source {len(src)}, result {len(live3['pos'])})")
    if compat.HAS_WARNING_NODE:
        w1, w3 = (json.loads(str(data[f"src/{f}/warnings"])) for f in (1, 3))
        T.check("without the add-on: the modifier panel warns on frame 1, not on frame 3",
                nodegroup.STALE_MESSAGE in w1 and nodegroup.STALE_MESSAGE not in w3,
                f"frame 1: {w1}, frame 3: {w3}")
    saved_status = str(data["src/1/status"])
    T.check("without the add-on: the saved status names the frame of the result and says "
            "what other frames show", saved_status.startswith("OK") and ", frame 3, " in
            saved_status and "frames other than 3 show the source mesh" in saved_status,
            saved_status)
    T.check("the note is in the file only", "saved:" not in status(mod), status(mod))
    ours, source, saved = (data[f"render/{n}"] > 0.5 for n in ("ours1", "source", "saved3"))
    T.check("without the add-on: a render of frame 1 draws the source mesh",
            ours.mean() > 0.02 and (ours != source).mean() < 0.2 * (saved != source).mean(),
            f"mask vs source {(ours != source).mean():.3f}, vs frame 3's result "
            f"{(ours != saved).mean():.3f}")

    # Nothing animated: the result holds on every frame, with or without the add-on.
    obj, lat, mod = scene_setup(animate=False)
    lat.data.points[13].co_deform.z += 0.5
    T.update()
    T.check("static lattice: the result belongs to every frame",
            T.frames.get_frames(mod, "Result") == T.state.ALWAYS and
            ", frame " not in status(mod), status(mod))
    live = snapshot(T.evaluated_mesh(obj))
    path = os.path.join(tempfile.mkdtemp(), "static.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    data = without_addon(path, [1, 40], ["src"])
    for f in (1, 40):
        same(f"static lattice, without the add-on: frame {f} shows the result",
             from_npz(data, f"src/{f}"), live)


# --- 5. everyday behaviour ------------------------------------------------------------------

def twin(obj, lat):
    return T.lattice_modifier_twin(obj, lat)


def parity(name, obj, lat, ref, mod):
    got = T.positions(T.evaluated_mesh(obj))
    exp = T.positions(T.evaluated_mesh(ref))
    if len(got) < len(exp):
        T.check(name, False, f"{len(got)} < {len(exp)} vertices, {status(mod)}")
        return
    err = np.abs(got[:len(exp)] - exp).max() / T.lattice_size(obj, lat)
    T.check(name, err <= TOL and status(mod).startswith("OK"), f"err {err:.2e}, {status(mod)}")


def select_only(ob):
    for o in bpy.context.view_layer.objects:
        o.select_set(o == ob)
    bpy.context.view_layer.objects.active = ob


def test_delete_lattice():
    obj, lat, mod = scene_setup("cube", animate=False)
    ref = twin(obj, lat)
    T.update()
    parity("before deleting the lattice", obj, lat, ref, mod)
    src = T.positions(obj.data)
    bpy.ops.ed.undo_push(message="before delete")
    select_only(lat)
    bpy.ops.object.delete()
    bpy.ops.ed.undo_push(message="deleted lattice")
    T.update()
    lat = bpy.data.objects.get("lat")
    T.check("delete lattice: gone from the file, as without the add-on (no ghost)",
            lat is None, f"{lat.users} users" if lat is not None else "")
    T.check("delete lattice: Blender's Lattice modifier beside it lets it go too",
            ref.modifiers[0].object is None, str(ref.modifiers[0].object))
    T.check("delete lattice: the modifier's Lattice is empty",
            compat.get_modifier_input(mod, "Lattice") is None)
    got = T.positions(T.evaluated_mesh(obj))
    T.check("delete lattice: the modifier shows the source",
            got.shape == src.shape and np.abs(got - src).max() == 0, f"{got.shape}")
    T.check("delete lattice: the status says why", status(mod).startswith("Error") and
            "was deleted" in status(mod), status(mod))
    path = os.path.join(tempfile.mkdtemp(), "deleted.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    T.check("delete lattice: not in the saved file", bpy.data.objects.get("lat") is None,
            str([o.name for o in bpy.data.objects]))

    # Undo brings lattice and deformation back.
    obj, lat, mod = scene_setup("cube", animate=False)
    ref = twin(obj, lat)
    T.update()
    bpy.ops.ed.undo_push(message="before delete")
    select_only(lat)
    bpy.ops.object.delete()
    bpy.ops.ed.undo_push(message="deleted lattice")
    T.update()
    bpy.ops.ed.undo()
    T.update()
    obj, lat, ref = (bpy.data.objects.get(n) for n in ("src", "lat", "src.ref"))
    T.check("undo delete lattice: lattice back", lat is not None and bool(lat.users_collection))
    if lat is not None:
        mod = obj.modifiers[0]
        lat.data.points[4].co_deform.z += 0.3
        T.update()
        parity("undo delete lattice: deforming again", obj, lat, ref, mod)

    # A file saved by an older add-on with the deleted lattice kept alive by the modifier.
    obj, lat, mod = scene_setup("cube", animate=False)
    path = os.path.join(tempfile.mkdtemp(), "ghost.blend")
    with T.state.muted():   # as an older add-on did: nothing lets go of it
        for c in list(lat.users_collection):
            c.objects.unlink(lat)
        T.check("ghost file: the lattice kept by the modifier alone", lat.users == 1,
                str(lat.users))
        bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    T.update()
    obj = bpy.data.objects["src"]
    lat = bpy.data.objects.get("lat")
    T.check("ghost file: opened, the lattice is let go of",
            lat is None and
            compat.get_modifier_input(obj.modifiers[0], "Lattice") is None
            and "was deleted" in status(obj.modifiers[0]), status(obj.modifiers[0]))

    # A lattice never linked to a scene (made by a script) is used as Blender's modifier
    # uses it in this session.
    obj, lat, mod = scene_setup("cube", animate=False)
    free = bpy.data.objects.new("free", bpy.data.lattices.new("free"))
    free.scale = (1.6, 1.6, 1.6)
    free.data.points[0].co_deform.x -= 0.2
    compat.set_modifier_input(mod, "Lattice", free)
    obj.update_tag()
    T.update()
    T.check("unlinked lattice from a script: used", status(mod).startswith("OK") and
            compat.get_modifier_input(mod, "Lattice") == free, status(mod))


def test_hidden():
    obj, lat, mod = scene_setup("suzanne", animate=False)
    ref = twin(obj, lat)
    ref.hide_set(True)
    T.update()
    computed = lambda: T.state.counters["computed"]

    obj.hide_set(True)
    T.update()
    n0, s0 = computed(), T.state.skipped_hidden[0]
    for i in range(3):
        lat.data.points[4 + i].co_deform.z += 0.1
        T.update()
    T.check("hidden (H): not recomputed on lattice edits", computed() == n0 and
            T.state.skipped_hidden[0] > s0, f"{computed() - n0} computed")
    obj.hide_set(False)
    T.update()
    T.check("hidden (H): recomputed once when shown", computed() == n0 + 1,
            f"{computed() - n0} computed")
    parity("hidden (H): up to date when shown", obj, lat, ref, mod)

    coll = bpy.data.collections.new("Hidden")
    bpy.context.scene.collection.children.link(coll)
    for c in list(obj.users_collection):
        c.objects.unlink(obj)
    coll.objects.link(obj)
    layer = bpy.context.view_layer.layer_collection.children["Hidden"]
    layer.exclude = True
    T.update()
    n0 = computed()
    lat.data.points[10].co_deform.x += 0.2
    T.update()
    T.check("excluded collection: not recomputed on lattice edits", computed() == n0,
            f"{computed() - n0} computed")
    layer.exclude = False
    T.update()
    T.check("excluded collection: recomputed when included", computed() == n0 + 1,
            f"{computed() - n0} computed")
    parity("excluded collection: up to date when included", obj, lat, ref, mod)

    # Hidden but used by something shown: still kept up to date.
    obj.hide_set(True)
    cube = T.make_mesh("cube", "cutter.user")
    boolean = cube.modifiers.new("Boolean", 'BOOLEAN')
    boolean.object = obj
    T.update()
    n0 = computed()
    lat.data.points[12].co_deform.y += 0.2
    T.update()
    T.check("hidden Boolean operand: recomputed on edits", computed() == n0 + 1,
            f"{computed() - n0} computed")
    cube.modifiers.remove(boolean)
    layer.exclude = True
    empty = T.link(bpy.data.objects.new("instancer", None))
    empty.instance_type = 'COLLECTION'
    empty.instance_collection = coll
    T.update()
    n0 = computed()
    lat.data.points[14].co_deform.y -= 0.2
    T.update()
    T.check("excluded collection shown by a collection instance: recomputed on edits",
            computed() == n0 + 1, f"{computed() - n0} computed")


def test_rename():
    obj, lat, mod = scene_setup("suzanne", animate=False)
    ref = twin(obj, lat)
    T.update()
    ro = T.objects.result_object(obj, mod, create=False)
    plans, computed = T.state.plans_built[0], T.state.counters["computed"]
    results = len([o for o in bpy.data.objects if T.state.OWNER_KEY in o.keys()])
    obj.name = "renamed object"
    mod.name = "renamed modifier"
    mod = obj.modifiers["renamed modifier"]
    T.update()
    T.check("rename: nothing recomputed", T.state.counters["computed"] == computed,
            f"{T.state.counters['computed'] - computed} computed")
    lat.data.points[4].co_deform.z += 0.3
    T.update()
    parity("rename: live after renaming the object and the modifier", obj, lat, ref, mod)
    T.check("rename: same result object",
            T.objects.result_object(obj, mod, create=False) == ro)
    T.check("rename: no result orphaned",
            len([o for o in bpy.data.objects if T.state.OWNER_KEY in o.keys()]) == results)
    T.check("rename: the plan kept", T.state.plans_built[0] == plans,
            f"{T.state.plans_built[0] - plans} plans built")
    T.check("rename: the in-memory state found", T.objects.state_of(obj, mod) is not None
            and len(T.state.states) == 1, str(len(T.state.states)))


def test_lock_interface():
    obj, lat, mod = scene_setup("cube", animate=False)
    sc = bpy.context.scene
    T.check("background: add_smooth_ffd leaves Lock Interface alone",
            not sc.render.use_lock_interface)
    path = os.path.join(tempfile.mkdtemp(), "lock.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    sc = bpy.context.scene
    T.update()
    T.check("loading a file leaves Lock Interface alone", not sc.render.use_lock_interface)
    handlers.on_render_pre(sc)
    handlers.on_render_done(sc)
    T.check("rendering leaves Lock Interface alone", not sc.render.use_lock_interface)

    # A render job thread without the lock: nothing written.
    obj, lat = bpy.data.objects["src"], bpy.data.objects["lat"]
    mod = obj.modifiers[0]
    lat.data.points[3].co_deform.x += 0.2
    n0 = T.state.counters["computed"]
    got = []
    thread = threading.Thread(target=lambda: got.append(handlers.update_all(sc, render=True)))
    thread.start()
    thread.join()
    T.check("render thread without Lock Interface: nothing written",
            got == [0] and T.state.counters["computed"] == n0, str(got))
    T.update()

    # A window session: add_smooth_ffd turns it on and says so, in the status too.
    real = T.statusline.window_session
    T.statusline.window_session = lambda: True
    try:
        obj2 = T.make_mesh("cube", "second")
        mod2 = smooth_ffd.add_smooth_ffd(obj2, lat, viewport_level=VIEWPORT, render_level=RENDER)
        T.check("window: add_smooth_ffd turns Lock Interface on and says so",
                sc.render.use_lock_interface and T.state.lock_message[0] and
                "Lock Interface" in T.state.lock_message[0], str(T.state.lock_message[0]))
        T.check("window: the status says so", "Lock Interface turned on" in status(mod2),
                status(mod2))
        sc.render.use_lock_interface = False
        lat.data.points[5].co_deform.x += 0.2
        T.update()
        T.check("window, Lock Interface turned off: the status warns",
                "Lock Interface is off" in status(mod2), status(mod2))
    finally:
        T.statusline.window_session = real
        T.state.lock_turned_on.clear()


def test_migrate_layouts():
    """Groups of 3.4-4.0 from older add-ons, with frame ranges and no Stack Object (layout
    3) or with the Input Copy and no Result Points (layout 7), move to this Blender's group
    (9 on 3.4-4.0, 10 with the Backend menu on 4.1+), keeping the frame ranges and the bake;
    the next lattice edit then goes through the Result Points where this Blender sends them
    (before 3.6)."""
    for old_layout in (nodegroup.TEXT_FRAMES_LAYOUT, nodegroup.TEXT_COPY_LAYOUT):
        _migrate_layout(old_layout)


def _migrate_layout(old_layout):
    obj, lat, mod = scene_setup("cube", animate=False)
    old = nodegroup._build_group(old_layout)
    old_name = old.name
    ro = T.objects.result_object(obj, mod, create=False)
    values = {"Lattice": lat, "Render Level": 4, "Backend": "cpu", "Result Object": ro}
    if old_layout in nodegroup.FRAMES_LAYOUTS:
        values.update({"Result From": 2.5, "Result To": 3.5, "Bake From": 10.5, "Bake To": 12.5})
    else:
        values["Show Result"] = True
    with T.state.muted():
        mod.node_group = old
        for k, v in values.items():
            compat.set_modifier_input(mod, k, v)
        moved = nodegroup.migrate(mod)
    kept = {k: compat.get_modifier_input(mod, k) for k in values if k != "Show Result"}
    want = dict(values, Backend="CPU" if compat.HAS_MENU_SOCKET else "cpu")
    want.pop("Show Result", None)
    T.check(f"migrate layout {old_layout} -> {nodegroup.GROUP_LAYOUT}: settings kept",
            moved and nodegroup.layout(mod.node_group) == nodegroup.GROUP_LAYOUT and
            kept == want and old_name not in bpy.data.node_groups, str(kept))
    obj.update_tag()
    T.update()
    T.check(f"migrated from {old_layout}: live", status(mod).startswith("OK cpu"), status(mod))
    lat.data.points[1].co_deform.z += 0.1
    T.update()
    sent = (T.pipeline.last_timing(obj, mod) or {}).get("points")
    T.check(f"migrated from {old_layout}: lattice edit "
            f"{'through' if compat.POSITIONS_THROUGH_POINTS else 'not through'} the Result Points",
            status(mod).startswith("OK cpu") and sent == compat.POSITIONS_THROUGH_POINTS,
            f"{sent}, {status(mod)}")


def _fill(me, snap):
    """Builds a plain mesh from a snapshot (triangles)."""
    n = len(snap["pos"])
    me.vertices.add(n)
    me.vertices.foreach_set("co", snap["pos"].ravel())
    nt = len(snap["cv"]) // 3
    me.loops.add(len(snap["cv"]))
    me.polygons.add(nt)
    me.loops.foreach_set("vertex_index", snap["cv"])
    me.polygons.foreach_set("loop_start", np.arange(0, 3 * nt, 3, dtype=np.int32))
    if bpy.app.version < (4, 0):
        me.polygons.foreach_set("loop_total", np.full(nt, 3, np.int32))
    me.update(calc_edges=True)


def main():
    T.setup()
    for fn in (test_bake, test_stale_without_addon, test_delete_lattice, test_hidden, test_rename,
               test_lock_interface, test_migrate_layouts):
        T.run(fn.__name__, fn)
    T.finish()


main()
