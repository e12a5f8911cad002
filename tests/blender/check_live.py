"""Live behaviour through the handlers: lattice edits, settings, frames, shape keys, source
edits, errors, undo, duplicate, save/reload (with and without the add-on), the Backend setting
(a menu from 4.1, text before; files with the text setting moved to the menu), apply, remove."""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, compat, latticeio, meshio, nodegroup  # noqa: E402

TOL = 1e-5


def scene(kind="suzanne", shape=(3, 3, 3), level=2):
    T.clear()
    obj = T.make_mesh(kind)
    lat = T.make_lattice(shape, "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=3)
    ref = T.lattice_modifier_twin(obj, lat)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=level + 1)
    T.update()
    return obj, lat, ref, mod


def parity(name, obj, lat, ref, mod):
    """Evaluated result's first V vertices == Blender's Lattice modifier."""
    got = T.positions(T.evaluated_mesh(obj))
    exp = T.positions(T.evaluated_mesh(ref))
    size = T.lattice_size(obj, lat)
    if len(got) < len(exp):
        T.check(name, False, f"{len(got)} < {len(exp)} vertices, {smooth_ffd.status(mod)}")
        return
    err = np.abs(got[:len(exp)] - exp).max() / size
    T.check(name, err <= TOL and smooth_ffd.status(mod).startswith("OK"),
            f"err {err:.2e}, {smooth_ffd.status(mod)}")


def source_digest(obj):
    me = obj.data
    return (T.positions(me).tobytes(), len(me.polygons), len(me.loops))


def test_lattice_edits():
    obj, lat, ref, mod = scene()
    before = source_digest(obj)
    parity("initial", obj, lat, ref, mod)
    lat.data.points[4].co_deform.z += 0.4
    T.update()
    parity("move lattice point", obj, lat, ref, mod)
    lat.location.x += 0.2
    lat.rotation_euler.z = 0.3
    T.update()
    parity("transform lattice", obj, lat, ref, mod)
    for o in (obj, ref):   # the twin must stay where the object is
        o.location.y -= 0.3
        o.scale = (1.2, 0.9, 1.0)
    T.update()
    parity("transform object", obj, lat, ref, mod)
    lat.data.interpolation_type_v = 'KEY_CARDINAL'
    T.update()
    parity("change interpolation", obj, lat, ref, mod)
    compat.set_modifier_input(mod, "Strength", 0.5)
    ref.modifiers[0].strength = 0.5
    obj.update_tag()
    T.update()
    parity("change strength", obj, lat, ref, mod)
    T.check("source mesh untouched by updates", source_digest(obj) == before)


def _computations(fn):
    """Runs fn (an edit + update); returns how many results were computed, and where (an
    early computation that failed is a failure of its own)."""
    before = dict(T.state.counters)
    fn()
    n = {k: T.state.counters[k] - before[k] for k in before}
    errors = n.pop("early_errors")
    if errors:
        T.check("no failed early computation", False, f"{errors} failed")
    return n


def test_update_path():
    """The live update path: plan and topology cached across lattice moves, one computation
    per edit, written before Blender evaluates the edit (depsgraph_update_pre) when the
    original data give the evaluated inputs, and parity however the result was reached."""
    import bmesh
    obj, lat, ref, mod = scene("cube")
    p = lat.data.points[4]

    def move(dz=0.2, point=None):
        def fn():
            (point or p).co_deform.z += dz
            T.update()
        return fn

    plan = T.objects.state_of(obj, mod).deformer
    n = _computations(move())
    parity("lattice move: parity", obj, lat, ref, mod)
    T.check("lattice move: one computation, before the evaluation",
            n == {"computed": 1, "early": 1, "post": 0}, str(n))
    T.check("lattice move: plan kept", T.objects.state_of(obj, mod).deformer is plan)
    n = _computations(T.update)
    T.check("no edit: no computation", n["computed"] == 0, str(n))
    # Object transform: its world matrix is its own loc/rot/scale, known before evaluation.
    def transform():
        for o in (obj, ref):
            o.location.x += 0.1
            o.rotation_euler.z += 0.2
        T.update()
    n = _computations(transform)
    parity("object transform: parity", obj, lat, ref, mod)
    T.check("object transform: computed before the evaluation", n["early"] == 1 and n["post"] == 0,
            str(n))
    # Topology edit of the source (cut one face in two), then lattice moves on the new plan.
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.faces.ensure_lookup_table()
    f = bm.faces[0]
    bmesh.utils.face_split(f, f.verts[0], f.verts[2])
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()
    n = _computations(T.update)
    parity("topology edit: parity", obj, lat, ref, mod)
    T.check("topology edit: new plan, computed once", n["computed"] == 1
            and T.objects.state_of(obj, mod).deformer is not plan, str(n))
    for i in range(3):
        n = _computations(move(0.15 if i % 2 == 0 else -0.1, lat.data.points[10 + i]))
        parity(f"lattice move {i + 1} after topology edit: parity", obj, lat, ref, mod)
        T.check(f"lattice move {i + 1} after topology edit: one early computation",
                n == {"computed": 1, "early": 1, "post": 0}, str(n))
    # Source edit and lattice move in one update: the early result used the old source, so
    # the post handler must notice the source changed and recompute.
    def both():
        obj.data.vertices[2].co.x += 0.2
        obj.data.update()
        p.co_deform.x -= 0.1
        T.update()
    n = _computations(both)
    parity("source edit + lattice move together: parity", obj, lat, ref, mod)
    # Lattice resolution change: new structure, new plan.
    lat.data.points_u = 4
    n = _computations(T.update)
    parity("lattice resized: parity", obj, lat, ref, mod)
    n = _computations(move(0.1, lat.data.points[7]))
    parity("resized lattice moved: parity", obj, lat, ref, mod)
    T.check("resized lattice moved: one computation", n["computed"] == 1, str(n))
    # An early computation that fails (here: an injected error) leaves the edit to the post
    # handler, once; later updates without edits compute nothing.
    read_lattice = latticeio.read_lattice
    def broken(lat_obj, depsgraph):
        if depsgraph is None:
            raise RuntimeError("injected")
        return read_lattice(lat_obj, depsgraph)
    latticeio.read_lattice = broken
    try:
        before = dict(T.state.counters)
        move(0.05, lat.data.points[3])()
        T.update()
        n = {k: T.state.counters[k] - before[k] for k in before}
    finally:
        latticeio.read_lattice = read_lattice
    parity("failed early computation: parity", obj, lat, ref, mod)
    T.check("failed early computation: computed after the evaluation, once",
            n == {"computed": 1, "early": 0, "post": 1, "early_errors": 1}, str(n))
    # Lattice in edit mode (how points are moved interactively): still computed early.
    bpy.context.view_layer.objects.active = lat
    bpy.ops.object.mode_set(mode='EDIT')
    def edit_move():
        lat.data.points[7].co_deform.x += 0.1
        lat.data.update_tag()
        T.update()
    n = _computations(edit_move)
    parity("lattice in edit mode moved: parity", obj, lat, ref, mod)
    T.check("lattice in edit mode moved: one early computation",
            n == {"computed": 1, "early": 1, "post": 0}, str(n))
    bpy.ops.object.mode_set(mode='OBJECT')
    T.update()
    parity("lattice edit mode left: parity", obj, lat, ref, mod)
    # Hooked lattice: the evaluated points differ from the original ones, so the pre
    # handler must leave it to the post handler.
    empty = T.link(bpy.data.objects.new("hook", None))
    hook = lat.modifiers.new("Hook", 'HOOK')
    hook.object = empty
    hook.vertex_indices_set([0, 1])
    T.update()
    def hook_move():
        empty.location.z += 0.3
        T.update()
    n = _computations(hook_move)
    parity("hook moved: parity", obj, lat, ref, mod)
    T.check("hook moved: computed after the evaluation only", n == {"computed": 1, "early": 0,
                                                                   "post": 1}, str(n))
    n = _computations(move(0.1, lat.data.points[20]))
    parity("hooked lattice point moved: parity", obj, lat, ref, mod)
    T.check("hooked lattice point moved: computed once", n["computed"] == 1, str(n))


def test_positions_only_path():
    """Viewport without exact normals (3.4-4.4: Blender shades the dense mesh from its
    geometry) asks the core for positions only; exact normals (Exact Normals, render and
    Apply, and 4.5+ always) ask for normals. Parity holds either way."""
    obj, lat, ref, mod = scene("cube")
    st = T.objects.state_of(obj, mod)
    ro = T.objects.result_object(obj, mod, create=False)

    def move(dz=0.15):
        def fn():
            lat.data.points[4].co_deform.z += dz
            T.update()
        return fn

    def exact_normals(on):
        def fn():
            compat.set_modifier_input(mod, "Exact Normals", on)
            obj.update_tag()
            T.update()
        return fn

    viewport = {"normals": 1, "positions_only": 0} if compat.CHEAP_EXACT_NORMALS else \
        {"normals": 0, "positions_only": 1}
    where = "4.5+ viewport (exact)" if compat.CHEAP_EXACT_NORMALS else "3.4-4.4 viewport"
    n = _deform_calls(move())
    parity(f"{where}: parity", obj, lat, ref, mod)
    T.check(f"{where}: {'normals' if compat.CHEAP_EXACT_NORMALS else 'positions only'}",
            n == viewport, str(n))
    T.check(f"{where}: result normals {'kept' if compat.CHEAP_EXACT_NORMALS else 'None'}",
            ((st.result.normals if meshio.is_compact(st.result) else st.result.corner_normals)
             is not None) == compat.CHEAP_EXACT_NORMALS)
    check_points(f"{where}, moved again", obj, mod, ro, move(0.05),
                 compat.POSITIONS_THROUGH_POINTS and not compat.CHEAP_EXACT_NORMALS)
    # 4.5+: exact already, the setting changes nothing (nothing recomputed).
    none = {"normals": 0, "positions_only": 0}
    n = _deform_calls(exact_normals(True))
    parity("Exact Normals on: parity", obj, lat, ref, mod)
    T.check("Exact Normals on: normals", n == (none if compat.CHEAP_EXACT_NORMALS else
                                               {"normals": 1, "positions_only": 0}), str(n))
    T.check("Exact Normals on: custom normals written", ro.data.has_custom_normals,
            smooth_ffd.status(mod))
    check_points("Exact Normals on", obj, mod, ro, lambda: None, False)
    n = _deform_calls(move(-0.1))
    parity("Exact Normals, lattice move: parity", obj, lat, ref, mod)
    T.check("Exact Normals, lattice move: normals", n == {"normals": 1, "positions_only": 0},
            str(n))
    n = _deform_calls(exact_normals(False))
    parity("Exact Normals off: parity", obj, lat, ref, mod)
    check_points("Exact Normals off, moved", obj, mod, ro, move(0.05),
                 compat.POSITIONS_THROUGH_POINTS and not compat.CHEAP_EXACT_NORMALS)
    parity("Exact Normals off, moved: parity", obj, lat, ref, mod)
    T.check("Exact Normals off: back to the viewport path",
            n == (none if compat.CHEAP_EXACT_NORMALS else viewport), str(n))
    # Render (what the render handler and Apply call): normals, in every version.
    depsgraph = bpy.context.evaluated_depsgraph_get()
    n = _deform_calls(lambda: T.pipeline.update_modifier(obj, mod, T.state.Pass(depsgraph, render=True, force=True)))
    T.check("render update: normals", n == {"normals": 1, "positions_only": 0}, str(n))
    T.check("render update: custom normals written", ro.data.has_custom_normals)
    T.update()
    n = _deform_calls(lambda: smooth_ffd.apply_smooth_ffd(obj, mod))
    T.check("apply: normals", n["normals"] >= 1 and n["positions_only"] == 0, str(n))
    T.check("apply: custom normals on the applied mesh", obj.data.has_custom_normals)


def check_points(name, obj, mod, ro, fn, sent):
    """After fn: whether the update went through the Result Points (`sent`: before 3.6, a
    positions-only update; nodegroup), what the points object holds, and that the object
    shows the result mesh's positions either way (bitwise: Set Position copies them)."""
    fn()
    po = T.objects.points_object(obj, mod, ro, create=False)
    timing = T.pipeline.last_timing(obj, mod) or {}
    T.check(f"{name}: {'through' if sent else 'not through'} the Result Points",
            timing.get("points") == sent, str(timing.get("points")))
    count = len(po.data.vertices) if po is not None else 0
    T.check(f"{name}: points object holds {'the positions' if sent else 'nothing'}",
            count == (len(ro.data.vertices) if sent else 0), f"{count}")
    if sent:
        T.check(f"{name}: points are the result mesh's",
                np.array_equal(T.positions(po.data), T.positions(ro.data)))
    shown = T.positions(T.evaluated_mesh(obj))
    T.check(f"{name}: the object shows the result mesh",
            np.array_equal(shown, T.positions(ro.data)), f"{len(shown)} vertices")


def _deform_calls(fn):
    """How many of each kind of core frame fn() ran."""
    before = dict(T.state.deform_calls)
    fn()
    return {k: T.state.deform_calls[k] - before[k] for k in before}


def _move(lat, dz):
    """An edit: lattice point 4 raised by dz, then a depsgraph update."""
    def fn():
        lat.data.points[4].co_deform.z += dz
        T.update()
    return fn


def live_editing_without_cheap_normals():
    """3.4-4.4 (Blender shades the viewport's dense mesh from its geometry): live editing
    forced on changes nothing. Every viewport edit is positions only, as without it; no settle
    timer is scheduled and the timer, run anyway, computes nothing."""
    obj, lat, ref, mod = scene("suzanne")
    live, settle_after = T.state.LIVE, T.state.settle_after[0]
    T.state.LIVE = True

    try:
        fast = {"normals": 0, "positions_only": 1}
        for i, dz in enumerate((0.1, 0.1, 0.05)):
            n = _deform_calls(_move(lat, dz))
            T.check(f"live on, 3.4-4.4: edit {i + 1} in a row is positions only", n == fast, str(n))
        parity("live on, 3.4-4.4: parity", obj, lat, ref, mod)
        T.check("live on, 3.4-4.4: no settle timer scheduled",
                T.state.settle_after[0] == settle_after
                and not bpy.app.timers.is_registered(T.handlers.settle))
        n = _deform_calls(lambda: T.handlers.settle())
        T.check("live on, 3.4-4.4: the settle timer computes nothing",
                n == {"normals": 0, "positions_only": 0}, str(n))
        n = _deform_calls(lambda: T.pipeline.update_modifier(
            obj, mod, T.state.Pass(bpy.context.evaluated_depsgraph_get(), render=True, force=True)))
        T.check("live on, 3.4-4.4: render is exact while changing",
                n == {"normals": 1, "positions_only": 0}, str(n))
    finally:
        T.state.LIVE = live


def test_live_editing():
    """4.5+ viewport (T.state.LIVE, forced on here: background mode runs no timers):
    while the result keeps changing (results less than SETTLE apart) positions only and
    Blender's own normals; after SETTLE the settle timer's update brings the exact normals,
    equal to those of an exact update of the same inputs. Exact Normals, render and LIVE off
    stay exact; an update that changes nothing computes nothing."""
    if not compat.CHEAP_EXACT_NORMALS:
        live_editing_without_cheap_normals()
        return
    obj, lat, ref, mod = scene("suzanne")
    st = T.objects.state_of(obj, mod)
    ro = T.objects.result_object(obj, mod, create=False)
    live, settle = T.state.LIVE, T.state.SETTLE
    T.state.LIVE, T.state.SETTLE = True, 0.5

    class Clock:
        """live's clock (it reads only time.perf_counter), moved by this test:
        'within SETTLE' and 'SETTLE later' are steps the test takes, not how fast this
        machine happens to run the edits in between."""
        now = T.live.time.perf_counter()

        @classmethod
        def perf_counter(cls):
            return cls.now

    real_time, T.live.time = T.live.time, Clock

    def normals_attribute():
        a = ro.data.attributes.get("custom_normal")
        return None if a is None else T.point_attribute(ro.data, "custom_normal")

    def wait_settled():
        Clock.now += T.state.SETTLE + 0.05

    try:
        wait_settled()
        exact, fast, none = ({"normals": 1, "positions_only": 0}, {"normals": 0, "positions_only": 1},
                             {"normals": 0, "positions_only": 0})
        T.check("live: a first edit is exact", _deform_calls(_move(lat, 0.1)) == exact)
        T.check("live: custom normals after it", normals_attribute() is not None)
        n = _deform_calls(_move(lat, 0.1))
        T.check("live: the next edit within SETTLE is positions only", n == fast, str(n))
        parity("live: positions only: parity", obj, lat, ref, mod)
        T.check("live: no custom normals while changing", normals_attribute() is None)
        T.check("live: status says so", "from geometry normals" in smooth_ffd.status(mod),
                smooth_ffd.status(mod))
        n = _deform_calls(_move(lat, 0.05))
        T.check("live: a third edit too", n == fast, str(n))
        fast_positions = T.positions(T.evaluated_mesh(obj)).copy()
        n = _deform_calls(T.update)
        T.check("live: an update without change computes nothing", n == none, str(n))
        # The settle timer, as a window runs it SETTLE after the last change.
        T.check("live: the timer waits while changes are recent", T.handlers.settle() is not None)
        wait_settled()
        n = _deform_calls(lambda: T.check("live: the timer then stops", T.handlers.settle() is None))
        T.check("live: the settle update is exact", n == exact, str(n))
        settled = T.positions(T.evaluated_mesh(obj))
        T.check("live: settled positions = the live ones (bitwise)",
                np.array_equal(settled, fast_positions))
        settled_normals = normals_attribute()
        T.check("live: custom normals after settling", settled_normals is not None)
        # The same inputs computed exact from scratch: the same normals.
        T.pipeline.forget(obj, mod)
        n = _deform_calls(lambda: smooth_ffd.update(obj, mod, force=True))
        T.check("live: settled normals = a fresh exact update's",
                settled_normals is not None and np.array_equal(settled_normals, normals_attribute()),
                str(n))
        wait_settled()
        _deform_calls(_move(lat, 0.1))
        n = _deform_calls(lambda: T.pipeline.update_modifier(
            obj, mod, T.state.Pass(bpy.context.evaluated_depsgraph_get(), render=True, force=True)))
        T.check("live: render is exact while changing", n == exact, str(n))
        T.update()
        wait_settled()
        compat.set_modifier_input(mod, "Exact Normals", True)
        obj.update_tag()
        _deform_calls(T.update)
        n = _deform_calls(_move(lat, -0.1))
        T.check("live: Exact Normals stays exact while changing", n == exact, str(n))
        compat.set_modifier_input(mod, "Exact Normals", False)
        obj.update_tag()
        T.update()
        T.state.LIVE = False
        _deform_calls(_move(lat, 0.1))
        n = _deform_calls(_move(lat, 0.1))
        T.check("live off (background default): exact while changing", n == exact, str(n))
        # A window registers the settle timer; disabling the add-on drops it.
        bpy.app.timers.register(T.handlers.settle, first_interval=60)
        T.handlers.unregister()
        T.check("live: the add-on's unregister drops the settle timer",
                not bpy.app.timers.is_registered(T.handlers.settle))
        T.handlers.register()
    finally:
        T.state.LIVE, T.state.SETTLE = live, settle
        T.live.time = real_time


def test_incremental_updates():
    """A lattice edit recomputes only what the moved points reach (the core's incremental
    frames, Deformer.deform(incremental=True)): on Suzanne in a 9x9x9 lattice most one-point
    edits recompute part of the patches, and after each edit of a run the core's output the
    add-on wrote is bitwise a whole frame of the same inputs, exact or not."""
    obj, lat, ref, mod = scene("suzanne", shape=(9, 9, 9))
    st = T.objects.state_of(obj, mod)
    partial = 0
    # Points (u, v, w) at u + 9 (v + 9 w): (2, 4, 4), again, (6, 4, 4), (0, 0, 0) (reaching
    # nothing of the mesh), then with exact normals (4, 2, 4), (4, 4, 6), and all at once.
    for i, (idx, exact) in enumerate(((362, False), (362, False), (366, False), (0, False),
                                      (346, True), (526, True), (None, False))):
        compat.set_modifier_input(mod, "Exact Normals", exact)
        for p in (lat.data.points if idx is None else [lat.data.points[idx]]):
            p.co_deform.z += 0.05
        obj.update_tag()
        T.update()
        name = f"edit {i + 1} ({'all points' if idx is None else f'point {idx}'}" \
               f"{', exact' if exact else ''})"
        parity(f"{name}: parity", obj, lat, ref, mod)
        d, res = st.deformer, st.result
        patches = res.stats.get("recomputed_patches")
        T.check(f"{name}: patches recomputed reported", patches is not None and
                0 <= patches <= d.plan.patches, f"{patches} of {d.plan.patches}")
        partial += patches is not None and 0 < patches < d.plan.patches
        compact = meshio.is_compact(res)
        normals = (res.normals if compact else res.corner_normals) is not None
        whole = type(d)(d.mesh, d.lattice, level=d.level, device="cpu").deform(
            normals=normals, layout=res.stats["layout"])
        same = np.array_equal(res.positions.view(np.uint32), whole.positions.view(np.uint32))
        if normals:
            nn = "normals" if compact else "corner_normals"
            same = same and np.array_equal(getattr(res, nn), getattr(whole, nn))
        T.check(f"{name}: bitwise a whole frame", same)
    T.check("incremental: one-point edits recompute part of the mesh", partial >= 4,
            f"{partial} of 7")


def test_levels():
    obj, lat, ref, mod = scene(level=1)
    for level in (1, 2, 4):
        compat.set_modifier_input(mod, "Viewport Level", level)
        obj.update_tag()
        T.update()
        n = len(T.evaluated_mesh(obj).polygons)
        npatch = T.patches(obj, mod)
        T.check(f"level {level} triangle count", n == npatch * level * level and npatch > 0,
                f"{n} vs {npatch} patches * {level}^2, {smooth_ffd.status(mod)}")
        parity(f"level {level} parity", obj, lat, ref, mod)


def test_frames_and_shape_keys():
    obj, lat, ref, mod = scene()
    p = lat.data.points[13]
    p.co_deform = (0.0, 0.0, 0.0)
    p.keyframe_insert("co_deform", frame=1)
    p.co_deform = (0.3, -0.2, 0.4)
    p.keyframe_insert("co_deform", frame=11)
    lat.keyframe_insert("location", frame=1)
    lat.location.z += 0.3
    lat.keyframe_insert("location", frame=11)
    sc = bpy.context.scene
    for f in (1, 4, 11, 6):
        sc.frame_set(f)
        parity(f"frame {f}", obj, lat, ref, mod)
    # Shape keys only show in the evaluated lattice.
    sc.frame_set(1)
    lat.shape_key_add(name="Basis")
    key = lat.shape_key_add(name="Bend")
    for i, kp in enumerate(key.data):
        kp.co = np.array(kp.co) + (0.0, 0.0, 0.1 * (i % 3))
    key.value = 0.7
    T.update()
    parity("lattice shape key", obj, lat, ref, mod)


def test_uvs_materials():
    """Output material per triangle = its source face's; UVs at original vertices = input."""
    obj, lat, ref, mod = scene("cube")
    me = obj.data
    for name in ("red", "blue"):
        me.materials.append(bpy.data.materials.new(name))
    mat = (np.arange(len(me.polygons)) % 2).astype(np.int32)
    me.polygons.foreach_set("material_index", mat)
    me.update()
    T.update()
    out = T.evaluated_mesh(obj)
    faces = np.empty(len(out.polygons), dtype=np.int32)
    out.attributes[meshio.SOURCE_FACE_ATTRIBUTE].data.foreach_get("value", faces)
    got = np.empty(len(out.polygons), dtype=np.int32)
    out.polygons.foreach_get("material_index", got)
    T.check("material index per source face", np.array_equal(got, mat[faces]),
            f"{(got != mat[faces]).sum()} differ")
    T.check("materials carried", [m.name for m in out.materials] == ["red", "blue"],
            str([m.name if m else None for m in out.materials]))
    uv_in = np.empty(len(me.loops) * 2, dtype=np.float32)
    me.uv_layers.active.data.foreach_get("uv", uv_in)
    uv_in = uv_in.reshape(-1, 2)
    uv_out = np.empty(len(out.loops) * 2, dtype=np.float32)
    out.uv_layers[0].data.foreach_get("uv", uv_out)
    uv_out = uv_out.reshape(-1, 2)
    in_verts = T.triangles_like_loops(me)
    poly_of_loop = np.repeat(np.arange(len(me.polygons)), [len(p.vertices) for p in me.polygons])
    key_in = {(int(f), int(v)): c for c, (f, v) in enumerate(zip(poly_of_loop, in_verts))}
    out_verts = T.triangles(out).ravel()
    out_face = np.repeat(faces, 3)
    nv = len(me.vertices)
    errs = [np.abs(uv_out[k] - uv_in[key_in[(int(out_face[k]), int(out_verts[k]))]]).max()
            for k in np.nonzero(out_verts < nv)[0]]
    T.check("UVs at original vertices", errs and max(errs) < 1e-6, f"max {max(errs):.1e}")


def test_hook():
    obj, lat, ref, mod = scene()
    empty = T.link(bpy.data.objects.new("hook", None))
    hook = lat.modifiers.new("Hook", 'HOOK')
    hook.object = empty
    hook.vertex_indices_set([0, 1, 3, 4])
    T.update()
    empty.location = (0.2, 0.3, -0.4)
    T.update()
    parity("lattice hook", obj, lat, ref, mod)


def test_edit_modes():
    obj, lat, ref, mod = scene("cube")
    obj.data.vertices[0].co.x -= 0.3
    obj.data.update()
    T.update()
    parity("edit source mesh", obj, lat, ref, mod)
    # Source in edit mode: BMesh edits show live.
    import bmesh
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode='EDIT')
    bm = bmesh.from_edit_mesh(obj.data)
    bm.verts.ensure_lookup_table()
    bm.verts[1].co.z += 0.25
    bmesh.update_edit_mesh(obj.data)
    T.update()
    # The twin sharing a mesh in edit mode is no reference (it shows the cage), so compare
    # the live edit-mode result with the result after leaving edit mode, then with the twin.
    live = T.positions(T.evaluated_mesh(obj))
    bpy.ops.object.mode_set(mode='OBJECT')
    T.update()
    after = T.positions(T.evaluated_mesh(obj))
    T.check("source in edit mode: live result", live.shape == after.shape
            and np.abs(live - after).max() < 1e-6, smooth_ffd.status(mod))
    parity("source edit mode left", obj, lat, ref, mod)
    # Lattice in edit mode: moving its points shows live.
    bpy.context.view_layer.objects.active = lat
    bpy.ops.object.mode_set(mode='EDIT')
    lat.data.points[7].co_deform.x += 0.3
    lat.data.update_tag()
    T.update()
    parity("lattice in edit mode", obj, lat, ref, mod)
    bpy.ops.object.mode_set(mode='OBJECT')
    parity("lattice edit mode left", obj, lat, ref, mod)


def test_errors():
    obj, lat, ref, mod = scene("cube")
    src = source_digest(obj)
    nsrc = len(obj.data.vertices)
    backend = compat.input_identifier(mod.node_group, "Backend")
    for label, name, value in (("bad backend", "Backend", "gpu9"),
                               ("non-lattice object", "Lattice", ref),
                               ("no lattice", "Lattice", None)):
        if name == "Backend" and compat.HAS_MENU_SOCKET:
            mod[backend] = 99      # a menu holds only its items: a number that is none of them
        else:
            compat.set_modifier_input(mod, name, value)
        obj.update_tag()
        T.update()
        st = smooth_ffd.status(mod)
        n = len(T.evaluated_mesh(obj).vertices)
        T.check(f"error: {label}", st.startswith("Error") and n == nsrc,
                f"status {st!r}, shows {n} vertices (source {nsrc})")
        compat.set_modifier_input(mod, "Backend", "auto")
        compat.set_modifier_input(mod, "Lattice", lat)
        obj.update_tag()
        T.update()
        T.check(f"recovers after {label}", smooth_ffd.status(mod).startswith("OK"),
                smooth_ffd.status(mod))
    # CUDA chosen: fine where the core has a device, else a clear error (never a crash).
    compat.set_modifier_input(mod, "Backend", "cuda")
    obj.update_tag()
    T.update()
    st = smooth_ffd.status(mod)
    T.check("cuda backend: OK or reported", st.startswith("OK") or st.startswith("Error"), st)
    compat.set_modifier_input(mod, "Backend", "auto")
    # The lattice object deleted.
    bpy.data.objects.remove(lat)
    T.update()
    st = smooth_ffd.status(mod)
    n = len(T.evaluated_mesh(obj).vertices)
    T.check("lattice deleted", st.startswith("Error") and n == nsrc, f"{st!r}, {n} vertices")
    T.check("source untouched by errors", source_digest(obj) == src)
    # A mesh without faces.
    me = bpy.data.meshes.new("verts")
    me.from_pydata([(0, 0, 0), (1, 0, 0)], [(0, 1)], [])
    edge_obj = T.link(bpy.data.objects.new("edges", me))
    lat2 = T.make_lattice(name="lat2")
    m2 = smooth_ffd.add_smooth_ffd(edge_obj, lat2)
    T.update()
    T.check("mesh with no faces", smooth_ffd.status(m2).startswith("Error"), smooth_ffd.status(m2))


def test_undo():
    obj, lat, ref, mod = scene()
    names = (obj.name, lat.name, ref.name)
    bpy.ops.ed.undo_push(message="before move")
    lat.data.points[0].co_deform.x -= 0.5
    T.update()
    bpy.ops.ed.undo_push(message="moved")
    obj, lat, ref = (bpy.data.objects[n] for n in names)
    parity("before undo", obj, lat, ref, obj.modifiers[mod.name])
    bpy.ops.ed.undo()
    T.update()
    obj, lat, ref = (bpy.data.objects[n] for n in names)
    parity("after undo", obj, lat, ref, obj.modifiers[0])
    bpy.ops.ed.redo()
    T.update()
    obj, lat, ref = (bpy.data.objects[n] for n in names)
    parity("after redo", obj, lat, ref, obj.modifiers[0])


def test_duplicate():
    obj, lat, ref, mod = scene("cube")
    dup = T.link(obj.copy())
    dup.location.x += 2.0
    T.update()
    r1 = T.objects.result_object(obj, obj.modifiers[0], create=False)
    r2 = T.objects.result_object(dup, dup.modifiers[0], create=False)
    T.check("duplicate gets its own result", r1 is not None and r2 is not None and r1 != r2,
            f"{r1} {r2}")
    parity("original after duplicate", obj, lat, ref, obj.modifiers[0])


def test_save_reload():
    obj, lat, ref, mod = scene()
    lat.data.points[2].co_deform.y += 0.3
    T.update()
    before = T.positions(T.evaluated_mesh(obj))
    path = os.path.join(tempfile.mkdtemp(), "sffd_live.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj, lat, ref = (bpy.data.objects[n] for n in ("src", "lat", "src.ref"))
    T.update()
    after = T.positions(T.evaluated_mesh(obj))
    T.check("reload keeps result", after.shape == before.shape and np.abs(after - before).max() < 1e-6)
    parity("reload still live: parity", obj, lat, ref, obj.modifiers[0])
    lat.data.points[5].co_deform.x += 0.2
    T.update()
    parity("reload still live: edit", obj, lat, ref, obj.modifiers[0])
    bpy.ops.wm.save_as_mainfile(filepath=path)
    last = T.positions(T.evaluated_mesh(obj))
    # Without the add-on the file still shows the last result.
    smooth_ffd.unregister()
    try:
        bpy.ops.wm.open_mainfile(filepath=path)
        obj = bpy.data.objects["src"]
        T.update()
        shown = T.positions(T.evaluated_mesh(obj))
        T.check("without add-on: last result shown",
                shown.shape == last.shape and np.abs(shown - last).max() < 1e-6)
    finally:
        smooth_ffd.register()


def test_backend_setting():
    """4.1+: Backend is a menu (Auto, CPU, CUDA) whose setting the add-on reads by item name;
    3.4-4.0: a text input. Either way the chosen backend is the one used."""
    obj, lat, ref, mod = scene("cube")
    sock = compat.input_socket(mod.node_group, "Backend")
    kind = getattr(sock, "socket_type", None) or sock.bl_socket_idname
    want = 'NodeSocketMenu' if compat.HAS_MENU_SOCKET else 'NodeSocketString'
    T.check("Backend socket type", kind == want and nodegroup.layout(mod.node_group) ==
            nodegroup.GROUP_LAYOUT, f"{kind}, layout {nodegroup.layout(mod.node_group)}")
    got = compat.get_modifier_input(mod, "Backend")
    T.check("default backend auto", str(got).lower() == "auto", repr(got))
    if compat.HAS_MENU_SOCKET:
        items = [n for n, _ in compat.menu_items(mod, sock.identifier)]
        T.check("menu items", items == ["Auto", "CPU", "CUDA"], str(items))
        try:
            compat.set_modifier_input(mod, "Backend", "gpu")
            refused = False
        except ValueError:
            refused = True
        T.check("a name that is no item is refused", refused)
    compat.set_modifier_input(mod, "Backend", "cpu")
    obj.update_tag()
    T.update()
    T.check("cpu chosen, cpu used", str(compat.get_modifier_input(mod, "Backend")).lower() == "cpu"
            and smooth_ffd.status(mod).startswith("OK cpu"), smooth_ffd.status(mod))
    parity("backend cpu: parity", obj, lat, ref, mod)


def test_text_backend_file():
    """A file whose modifier uses 3.4-4.0's group (Backend as text, layout 1) keeps working:
    on 4.1+ opening it moves the modifier to the menu group with every setting kept."""
    obj, lat, ref, mod = scene("cube")
    old = nodegroup._build_group(nodegroup.TEXT_LAYOUT)
    ro = T.objects.result_object(obj, mod, create=False)
    settings = {"Lattice": lat, "Viewport Level": 3, "Render Level": 4, "Backend": "cpu",
                "Strength": 0.75, "Result Object": ro}
    mod.node_group = old
    for name, value in settings.items():
        compat.set_modifier_input(mod, name, value)
    ref.modifiers[0].strength = 0.75
    T.update()
    T.check("text layout: backend read as text", compat.get_modifier_input(mod, "Backend") == "cpu"
            and smooth_ffd.status(mod).startswith("OK cpu"), smooth_ffd.status(mod))
    path = os.path.join(tempfile.mkdtemp(), "sffd_text_backend.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj, lat, ref = (bpy.data.objects[n] for n in ("src", "lat", "src.ref"))
    mod = obj.modifiers[0]
    T.update()
    want = nodegroup.GROUP_LAYOUT
    T.check("opened: layout of this Blender", nodegroup.layout(mod.node_group) == want and
            len([g for g in bpy.data.node_groups if nodegroup.is_smooth_ffd_group(g)]) == 1,
            f"layout {nodegroup.layout(mod.node_group)}, groups {[g.name for g in bpy.data.node_groups]}")
    kept = {n: compat.get_modifier_input(mod, n) for n in settings}
    T.check("opened: settings kept", str(kept["Backend"]).lower() == "cpu" and
            kept["Lattice"] == lat and kept["Viewport Level"] == 3 and kept["Render Level"] == 4
            and abs(kept["Strength"] - 0.75) < 1e-7
            and kept["Result Object"] == T.objects.result_object(obj, mod, create=False),
            str(kept))
    parity("opened: parity", obj, lat, ref, mod)
    T.check("opened: cpu used", smooth_ffd.status(mod).startswith("OK cpu"), smooth_ffd.status(mod))
    lat.data.points[4].co_deform.x += 0.2
    T.update()
    parity("opened: still live", obj, lat, ref, mod)


def test_apply_remove():
    obj, lat, ref, mod = scene(level=1)
    lat.data.points[0].co_deform.x += 0.1   # a live update: before 3.6 the points object too
    T.update()
    old = obj.data
    old_digest = source_digest(obj)
    render_level = compat.get_modifier_input(mod, "Render Level")
    npatch = T.patches(obj, mod)
    smooth_ffd.apply_smooth_ffd(obj, mod)
    T.update()
    n = len(obj.data.polygons)
    T.check("apply: modifier gone", len(obj.modifiers) == 0)
    T.check("apply: render-level mesh", n == npatch * render_level ** 2, f"{n} tris")
    T.check("apply: result object deleted",
            not any(o.get(T.state.OWNER_KEY) is not None for o in bpy.data.objects))
    T.check("apply: points object deleted",
            not any(o.get(T.state.POINTS_KEY) is not None for o in bpy.data.objects))
    T.check("apply: old mesh untouched", source_digest_mesh(old) == old_digest)
    # The modifier is freed by Apply: its in-memory plan must go with it.
    T.check("apply: in-memory state dropped", not T.state.states,
            str(list(T.state.states)))
    obj, lat, ref, mod = scene()
    lat.data.points[0].co_deform.x += 0.1
    T.update()
    smooth_ffd.remove_smooth_ffd(obj, mod)
    T.update()
    T.check("remove: hidden objects deleted", not any(
        o.get(k) is not None for o in bpy.data.objects
        for k in (T.state.OWNER_KEY, T.state.POINTS_KEY)))
    got = T.positions(T.evaluated_mesh(obj))
    T.check("remove: shows the source", np.array_equal(got, T.positions(obj.data)))


def source_digest_mesh(me):
    return (T.positions(me).tobytes(), len(me.polygons), len(me.loops))


def main():
    T.setup()
    for fn in (test_lattice_edits, test_update_path, test_positions_only_path, test_live_editing, test_incremental_updates, test_levels, test_frames_and_shape_keys, test_uvs_materials, test_hook, test_edit_modes,
               test_errors, test_undo, test_duplicate, test_save_reload, test_backend_setting,
               test_text_backend_file, test_apply_remove):
        T.run(fn.__name__, fn)
    T.finish()


main()
