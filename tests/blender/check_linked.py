"""Linked and overridden data.

A library file holds a character: Suzanne with a Smooth FFD modifier, its lattice (a point
animated over frames 1-4, so every result belongs to one frame) and a twin with Blender's own
Lattice modifier (the reference), all in the collection "Character", saved on frame 2. A
second library is the same with frames 1-4 baked. Shot files link the collection
(`bpy.data.libraries.load(link=True)`):

- linked and instanced by an empty (File > Link's default) and linked into the scene: the
  add-on writes nothing linked (the modifier's inputs and status, the library's result
  object and mesh stay as loaded, nothing is computed), says so once on the console, and
  each frame shows the library's saved result on frame 2 and the source mesh on the others,
  never another frame's result; a render computes nothing either;
- linked from the baked library: every baked frame shows the library's bake, equal to the
  library's render-level result of that frame;
- a library override (`ID.override_hierarchy_create`, 3.4+): every frame equals the
  library's live result of that frame and its first V vertices the Lattice twin's (1e-5 of
  the lattice's size), in a local result object; Cycles renders frames 2 and 4 at the render
  level with that frame's geometry; saved (on frame 4) and reopened, the override keeps its
  result object and frame range (recorded as override properties: a Blender without the
  add-on shows frame 4's result on frame 4 and the source on frame 2; also from a library
  whose float inputs are not overridable, as a 3.4 library of an older add-on) and animates
  again;
  a bake in the shot shows the library's render-level results; a level change and a moved
  lattice object follow;
- made with Object > Library Override > Make and saved, the shot follows a library changed
  afterwards (Blender resyncs the override on load), keeping its result object;
- the library files are never modified (bytes and modification time; the changed library
  is a copy).
"""
import hashlib
import json
import os
import shutil
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import (smooth_ffd, compat, handlers, linked,  # noqa: E402
                          nodegroup)

VIEWPORT, RENDER = 1, 2
FRAMES = (1, 2, 3, 4)
SAVED_FRAME = 2
FLOAT_INPUTS = ("Strength", "Result From", "Result To", "Bake From", "Bake To")
TOL = 1e-5
RES = 40


# --- the library ------------------------------------------------------------------------------

def _fcurves(id_data):
    ad = id_data.animation_data
    action = ad.action if ad is not None else None
    if action is None:
        return []
    if hasattr(action, "fcurves") and len(action.fcurves):
        return list(action.fcurves)
    return [fc for layer in getattr(action, "layers", []) for strip in layer.strips
            for bag in getattr(strip, "channelbags", []) for fc in bag.fcurves]


def _into(coll, ob):
    for c in list(ob.users_collection):
        c.objects.unlink(ob)
    coll.objects.link(ob)
    return ob


def snap(mesh):
    return {"pos": T.positions(mesh), "cv": T.triangles_like_loops(mesh)}


def build_library(folder):
    """Saves lib.blend (frame 2's live result) and lib_baked.blend (frames 1-4 baked);
    returns the paths and the library's own results per frame (viewport and render level)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    coll = bpy.data.collections.new("Character")
    sc.collection.children.link(coll)
    obj = _into(coll, T.make_mesh("suzanne", "char"))
    lat = _into(coll, T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5))
    p = lat.data.points[13]
    p.co_deform = (0.0, 0.0, 0.0)
    p.keyframe_insert("co_deform", frame=1)
    p.co_deform = (0.0, 0.0, 1.0)
    p.keyframe_insert("co_deform", frame=4)
    for fc in _fcurves(lat.data):
        for k in fc.keyframe_points:
            k.interpolation = 'LINEAR'
    ref = _into(coll, T.lattice_modifier_twin(obj, lat))
    ref.hide_render = True
    sc.frame_start, sc.frame_end = FRAMES[0], FRAMES[-1]
    sc.frame_set(1)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=VIEWPORT, render_level=RENDER)
    live, live_render = {}, {}
    for f in FRAMES:
        sc.frame_set(f)
        T.update()
        live[f] = snap(T.evaluated_mesh(obj))
        smooth_ffd.update(obj, mod, render=True)
        live_render[f] = snap(T.evaluated_mesh(obj))
    sc.frame_set(SAVED_FRAME)
    smooth_ffd.update(obj, mod)
    T.check("library: the result belongs to frame 2 only",
            T.frames.get_frames(mod, "Result") == (1.5, 2.5), smooth_ffd.status(mod))
    paths = {n: f'["{compat.input_identifier(mod.node_group, n)}"]' for n, *_ in nodegroup.INPUTS}
    if not compat.HAS_MODIFIER_PROPERTIES:
        fixed = [n for n, p in paths.items() if not mod.is_property_overridable_library(p)]
        T.check("library: every input stays overridable by library overrides after the "
                "add-on wrote it (3.4 lost the flag of float inputs)", not fixed, str(fixed))
        # As an older add-on left a 3.4 library: its float inputs not overridable (the
        # override then gets the flags back, linked.prepare_override).
        for n in FLOAT_INPUTS:
            mod.property_overridable_library_set(paths[n], False)
    paths = {"lib": os.path.join(folder, "lib.blend"),
             "baked": os.path.join(folder, "lib_baked.blend")}
    bpy.ops.wm.save_as_mainfile(filepath=paths["lib"])
    smooth_ffd.bake_smooth_ffd(obj, mod, FRAMES[0], FRAMES[-1])
    bpy.ops.wm.save_as_mainfile(filepath=paths["baked"])
    return paths, live, live_render, T.positions(obj.data), T.lattice_size(obj, lat)


def file_state(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest(), os.stat(path).st_mtime_ns


# --- shots ------------------------------------------------------------------------------------

def new_shot(path, mode):
    """An empty file linking the library's collection: 'instance' (an empty instancing it,
    File > Link's default), 'scene' (the collection linked into the scene), 'override'
    (a library override of the instanced collection, the instance removed as Blender's
    Make Library Override does) or 'operator' (that operator itself).
    Returns the scene and, read before the add-on saw anything, the state of the linked
    character (untouched_state)."""
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    sc.frame_start, sc.frame_end = FRAMES[0], FRAMES[-1]
    with T.state.muted():
        with bpy.data.libraries.load(path, link=True) as (_src, dst):
            dst.collections = ["Character"]
        coll = dst.collections[0]
        state = untouched_state(find("char", "linked"))
        if mode == "scene":
            sc.collection.children.link(coll)
        else:
            empty = bpy.data.objects.new("Character", None)
            empty.instance_type = 'COLLECTION'
            empty.instance_collection = coll
            sc.collection.objects.link(empty)
            if mode == "override":
                coll.override_hierarchy_create(sc, bpy.context.view_layer, reference=empty)
                bpy.data.objects.remove(empty)
            elif mode == "operator":   # Object > Library Override > Make, on the empty
                bpy.context.view_layer.objects.active = empty
                empty.select_set(True)
                with bpy.context.temp_override(active_object=empty, object=empty,
                                               selected_objects=[empty]):
                    result = bpy.ops.object.make_override_library()
                T.check("Make Library Override ran", result == {'FINISHED'}, str(result))
    sc.frame_set(1)
    T.update()
    return sc, state


def find(name, kind):
    """The object called name that is linked ('linked') or a library override ('override')."""
    for ob in bpy.data.objects:
        if ob.name == name and (ob.library is not None if kind == "linked"
                                else ob.override_library is not None):
            return ob
    raise KeyError(f"no {kind} object {name!r}")


def evaluated(obj):
    """The evaluated mesh of obj as the depsgraph shows it (also inside an instance)."""
    dg = bpy.context.evaluated_depsgraph_get()
    for inst in dg.object_instances:
        if inst.object.original == obj:
            return snap(inst.object.data)
    raise KeyError(f"{obj.name_full} is not in the depsgraph")


def untouched_state(obj):
    """Everything of a linked Smooth FFD object the add-on could write: the modifier's
    inputs, the library's result object (its custom properties) and mesh."""
    mod = obj.modifiers[0]
    values = {}
    for name, *_ in nodegroup.INPUTS:
        v = compat.get_modifier_input(mod, name)
        values[name] = v.name_full if isinstance(v, bpy.types.ID) else v
    ro = compat.get_modifier_input(mod, "Result Object")
    mesh = ro.data
    ours = lambda idb: {k: str(v) for k, v in idb.items() if k.startswith("smooth_ffd")}
    # (not every key: Cycles adds its settings group to objects it renders)
    return (values, ours(ro), ours(mesh),
            hashlib.sha256(T.positions(mesh).tobytes()).hexdigest(), len(mesh.polygons),
            len(obj.modifiers))


def same_mesh(name, got, exp, size):
    if got["pos"].shape != exp["pos"].shape or not np.array_equal(got["cv"], exp["cv"]):
        T.check(name, False, f"{len(got['pos'])} vs {len(exp['pos'])} vertices")
        return
    err = float(np.abs(got["pos"] - exp["pos"]).max()) / size
    T.check(name, err <= TOL, f"{len(got['pos'])} vertices, err {err:.1e}")


def is_source(name, got, src):
    T.check(name, got["pos"].shape == src.shape and np.abs(got["pos"] - src).max() == 0,
            f"{len(got['pos'])} vertices (source {len(src)})")


def camera(sc):
    cam = T.link(bpy.data.objects.new("cam", bpy.data.cameras.new("cam")))
    cam.location = (0, -5, 0)
    cam.rotation_euler = (np.pi / 2, 0, 0)
    sc.camera = cam
    sc.render.engine = 'CYCLES'
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False   # Debian's build has no OpenImageDenoise
    sc.cycles.device = 'CPU'
    sc.render.resolution_x = sc.render.resolution_y = RES
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.render.image_settings.file_format = 'PNG'
    sc.render.image_settings.color_mode = 'RGBA'


def render_mask(sc, frame, folder, name):
    sc.frame_set(frame)
    sc.render.filepath = os.path.join(folder, name + ".png")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(sc.render.filepath)
    return np.array(img.pixels[:]).reshape(-1, 4)[:, 3] > 0.5


# --- linked, no override ----------------------------------------------------------------------

def test_linked(lib):
    for mode in ("instance", "scene"):
        sc, state = new_shot(lib["paths"]["lib"], mode)
        char = find("char", "linked")
        mod = char.modifiers[0]
        computed = T.state.counters["computed"]
        what = f"linked ({'instanced by an empty' if mode == 'instance' else 'in the scene'})"
        for f in FRAMES:
            sc.frame_set(f)
            T.update()
            got = evaluated(char)
            if f == SAVED_FRAME:
                same_mesh(f"{what}: frame {f} shows the library's saved result", got,
                          lib["live"][f], lib["size"])
            else:
                is_source(f"{what}: frame {f} shows the source mesh, not frame "
                          f"{SAVED_FRAME}'s result", got, lib["src"])
        smooth_ffd.update(char)          # asked directly: still nothing
        smooth_ffd.update()
        key = (char.name_full, mod.name)
        text = T.state.linked_reported.get(key, "")
        T.check(f"{what}: the console says once what it shows and what to do",
                "is linked from" in text and f"saved result on frame {SAVED_FRAME}" in text
                and "library override" in text and not linked.report(char, mod), text)
        if mode == "instance":   # a render computes nothing for it either
            camera(sc)
            render_mask(sc, 3, tempfile.mkdtemp(), "linked3")
        T.check(f"{what}: nothing computed", T.state.counters["computed"] == computed,
                f"{T.state.counters['computed'] - computed} computed")
        T.check(f"{what}: nothing linked written (modifier inputs, status, result mesh)",
                untouched_state(char) == state)
        mine = [o.name for o in bpy.data.objects if o.library is None and
                T.state.OWNER_KEY in o.keys()]
        T.check(f"{what}: no local result object made", not mine, str(mine))
        try:
            smooth_ffd.add_smooth_ffd(char, find("lat", "linked"))
            T.check(f"{what}: add_smooth_ffd refuses a linked object", False)
        except RuntimeError as e:
            T.check(f"{what}: add_smooth_ffd refuses a linked object", "linked" in str(e),
                    str(e))


def test_linked_bake(lib):
    sc, state = new_shot(lib["paths"]["baked"], "instance")
    char = find("char", "linked")
    for f in FRAMES:
        sc.frame_set(f)
        T.update()
        same_mesh(f"linked, library baked: frame {f} shows the library's bake (its "
                  f"render-level result)", evaluated(char), lib["live_render"][f], lib["size"])
    text = T.state.linked_reported.get((char.name_full, char.modifiers[0].name), "")
    T.check("linked, library baked: the console names the baked frames",
            "bake on frames 1-4" in text, text)
    T.check("linked, library baked: nothing linked written", untouched_state(char) == state)


# --- library override -------------------------------------------------------------------------

def check_frames(what, sc, char, ref, lat, lib):
    for f in FRAMES:
        sc.frame_set(f)
        T.update()
        mod = char.modifiers[0]
        got = evaluated(char)
        same_mesh(f"{what}: frame {f} is the library's live result of frame {f}", got,
                  lib["live"][f], lib["size"])
        exp = evaluated(ref)["pos"]
        n = len(exp)
        err = np.abs(got["pos"][:n] - exp).max() / T.lattice_size(char, lat) \
            if len(got["pos"]) >= n else np.inf
        T.check(f"{what}: frame {f}, first V vertices = the Lattice modifier's",
                err <= TOL and smooth_ffd.status(mod).startswith(f"OK") and
                f", frame {f}, " in smooth_ffd.status(mod), f"err {err:.1e}, "
                f"{smooth_ffd.status(mod)}")


def without_addon(blend, frames, obj_name):
    """noaddon_eval.py on `blend` in a fresh Blender that never loads the add-on."""
    data = T.run_without_addon(blend, frames, [obj_name])
    T.check("no-add-on Blender: the add-on was not loaded",
            json.loads(str(data["addon_modules"])) == [], str(data["addon_modules"]))
    return data


def test_override(lib):
    sc, state = new_shot(lib["paths"]["lib"], "override")
    char, ref, lat = (find(n, "override") for n in ("char", "char.ref", "lat"))
    lib_char = char.override_library.reference
    lib_ro = compat.get_modifier_input(lib_char.modifiers[0], "Result Object")
    check_frames("override", sc, char, ref, lat, lib)
    mod = char.modifiers[0]
    ro = T.objects.result_object(char, mod, create=False)
    T.check("override: its result object is local (not the library's, not an override)",
            ro is not None and ro != lib_ro and ro.library is None and
            ro.override_library is None and ro.data.library is None,
            f"{ro and ro.name_full} (library's: {lib_ro.name_full})")

    # Cycles renders frames 2 and 4 at the render level, each with its own geometry.
    camera(sc)
    folder = tempfile.mkdtemp()
    record = []

    def probe(scene, *_):
        r = T.objects.result_object(char, char.modifiers[0], create=False)
        record.append({"frame": scene.frame_current, "tris": len(r.data.polygons),
                       "pos": T.positions(r.data)[:len(lib["src"])]})
    bpy.app.handlers.render_post.append(probe)
    try:
        ours = {f: render_mask(sc, f, folder, f"ours{f}") for f in (2, 4)}
    finally:
        bpy.app.handlers.render_post.remove(probe)
    npatch = T.patches(char, char.modifiers[0])
    for f in (2, 4):
        r = next((r for r in record if r["frame"] == f), None)
        if r is None:
            T.check(f"override render, frame {f}: ran", False, str(record))
            continue
        sc.frame_set(f)
        T.update()
        err = np.abs(r["pos"] - evaluated(ref)["pos"]).max() / lib["size"]
        T.check(f"override render, frame {f}: render level, that frame's geometry",
                r["tris"] == npatch * RENDER ** 2 and err <= TOL,
                f"{r['tris']} tris (level {RENDER}: {npatch * RENDER ** 2}), err {err:.1e}")
    char.hide_render, ref.hide_render = True, False
    twin = {f: render_mask(sc, f, folder, f"ref{f}") for f in (1, 4)}
    char.hide_render, ref.hide_render = False, True
    diff, stale = float((ours[4] != twin[4]).mean()), float((twin[1] != twin[4]).mean())
    T.check("override render: frame 4 draws frame 4's geometry",
            ours[4].mean() > 0.02 and diff < stale / 3,
            f"mask mismatch {diff:.3f} (frame 1's: {stale:.3f})")
    T.check("override render: back to the viewport level",
            len(T.evaluated_mesh(char).polygons) == npatch * VIEWPORT ** 2)

    # Saved on frame 4 (not the library's frame 2) and reopened.
    sc.frame_set(4)
    T.update()
    uid = ro.get(T.state.UID_KEY)
    shot = os.path.join(tempfile.mkdtemp(), "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=shot)
    data = without_addon(shot, (4, 2), "char")
    same_mesh("override saved, without the add-on: frame 4 shows the saved result",
              {"pos": data["char/4/pos"].astype(np.float64), "cv": data["char/4/cv"]},
              lib["live"][4], lib["size"])
    is_source("override saved, without the add-on: frame 2 shows the source, not frame 4's "
              "result", {"pos": data["char/2/pos"].astype(np.float64)}, lib["src"])
    now = untouched_state(lib_char)
    T.check("override: nothing linked written", now == state,
            "" if now == state else f"{state} -> {now}")
    bpy.ops.wm.open_mainfile(filepath=shot)
    sc = bpy.context.scene
    char, ref, lat = (find(n, "override") for n in ("char", "char.ref", "lat"))
    lib_char = char.override_library.reference
    mod = char.modifiers[0]
    paths = {p.rna_path for p in char.override_library.properties}
    want = {f'modifiers["{mod.name}"]["{compat.input_identifier(mod.node_group, n)}"]'
            for n in ("Result Object", "Result From", "Result To", "Status")}
    T.check("reopened: result object, frame range and status are override properties",
            want <= paths, str(sorted(want - paths)))
    ro = T.objects.result_object(char, mod, create=False)
    T.check("reopened: the same local result object", ro is not None and
            ro.get(T.state.UID_KEY) == uid and ro.library is None,
            f"{ro and ro.name_full}")
    check_frames("override reopened", sc, char, ref, lat, lib)

    # A bake in the shot: local frame meshes, recorded in the override's inputs.
    smooth_ffd.bake_smooth_ffd(char, mod, FRAMES[0], FRAMES[-1])
    for f in FRAMES:
        sc.frame_set(f)
        T.update()
        same_mesh(f"override baked in the shot: frame {f} is the library's render-level "
                  f"result", evaluated(char), lib["live_render"][f], lib["size"])
    host = compat.get_modifier_input(mod, "Bake Object")
    T.check("override baked in the shot: the bake is local",
            host is not None and host.library is None and host.override_library is None)
    smooth_ffd.clear_bake(char, mod)
    sc.frame_set(2)
    T.update()
    same_mesh("override, bake cleared: live again", evaluated(char), lib["live"][2], lib["size"])

    # Edits in the shot: a level and the lattice object's place (override properties).
    compat.set_modifier_input(mod, "Viewport Level", 2)
    char.update_tag()
    lat.location.x += 0.07
    sc.frame_set(3)
    T.update()
    got = evaluated(char)["pos"]
    exp = evaluated(ref)["pos"]
    err = np.abs(got[:len(exp)] - exp).max() / T.lattice_size(char, lat)
    n = len(T.evaluated_mesh(char).polygons)
    T.check("override: level 2 and a moved lattice object follow",
            n == T.patches(char, mod) * 4 and err <= TOL, f"{n} tris, err {err:.1e}")
    try:
        smooth_ffd.remove_smooth_ffd(char, mod)
        T.check("override: remove refuses the library's modifier", False)
    except RuntimeError as e:
        T.check("override: remove refuses the library's modifier",
                "from the library" in str(e) and len(char.modifiers) == 1, str(e))
    T.check("override reopened: nothing linked written", untouched_state(lib_char) == state)


def test_override_resync(lib):
    """Made with the operator, saved, then the library changes (a lattice point moves, an
    object joins the collection: Blender resyncs the override on load): the override keeps
    its result object and follows the new library."""
    copy = os.path.join(tempfile.mkdtemp(), "lib.blend")
    shutil.copyfile(lib["paths"]["lib"], copy)
    sc, _state = new_shot(copy, "operator")
    char = find("char", "override")
    for f in (1, 3):
        sc.frame_set(f)
        T.update()
        same_mesh(f"override by the operator: frame {f} is the library's live result",
                  evaluated(char), lib["live"][f], lib["size"])
    ro = T.objects.result_object(char, char.modifiers[0], create=False)
    uid = ro.get(T.state.UID_KEY) if ro is not None else None
    shot = os.path.join(os.path.dirname(copy), "shot.blend")
    bpy.ops.wm.save_as_mainfile(filepath=shot)
    bpy.ops.wm.open_mainfile(filepath=copy)    # the library's author edits it
    bpy.data.objects["lat"].data.points[0].co_deform.x -= 0.3
    bpy.data.collections["Character"].objects.link(bpy.data.objects.new("extra", None))
    bpy.ops.wm.save_mainfile()
    bpy.ops.wm.open_mainfile(filepath=shot)
    sc = bpy.context.scene
    char, ref, lat = (find(n, "override") for n in ("char", "char.ref", "lat"))
    T.check("library changed: the override resynced (the new object is in it)",
            any(o.name == "extra" and o.override_library is not None for o in bpy.data.objects))
    ro = T.objects.result_object(char, char.modifiers[0], create=False)
    T.check("library changed: the override keeps its local result object",
            ro is not None and ro.get(T.state.UID_KEY) == uid)
    for f in (1, 4):
        sc.frame_set(f)
        T.update()
        got, exp = evaluated(char)["pos"], evaluated(ref)["pos"]
        err = np.abs(got[:len(exp)] - exp).max() / T.lattice_size(char, lat)
        moved = np.abs(exp - lib["live"][f]["pos"][:len(exp)]).max() / lib["size"]
        T.check(f"library changed: frame {f} follows the new lattice",
                err <= TOL and moved > 1e-3 and f", frame {f}, " in
                smooth_ffd.status(char.modifiers[0]), f"err {err:.1e} (moved {moved:.1e})")


def main():
    T.setup()
    folder = tempfile.mkdtemp()
    paths, live, live_render, src, size = build_library(folder)
    before = {k: file_state(p) for k, p in paths.items()}
    lib = {"paths": paths, "live": live, "live_render": live_render, "src": src, "size": size}
    for fn in (test_linked, test_linked_bake, test_override, test_override_resync):
        T.run(fn.__name__, fn, lib)
    after = {k: file_state(p) for k, p in paths.items()}
    T.check("the library files are never modified (bytes, modification time)", after == before,
            f"{before} -> {after}")
    T.finish()


main()
