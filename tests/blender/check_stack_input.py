"""The stack's geometry as Smooth FFD's input, against Blender's own Lattice
modifier at the same position (an object B with the same stack and Lattice where A has Smooth
FFD): the first V output vertices within 1e-5 of the lattice size, on every frame of a short
animation.

- a character-like mesh rigged to an armature that waves over frames 1-6 (Armature above),
  its UV map, material indices and split normals coming from the posed geometry; edits on
  the same frame (a pose, a lattice point) and the fast path when nothing is above;
- Mirror (vertex groups and UVs mirrored: the Vertex Group setting weights by the mirrored
  groups), Subdivision Surface, Array above; a modifier setting changed above (new topology);
- relative shape keys with an animated value, and a value changed on the same frame;
- two Smooth FFD modifiers in a row against two Lattice modifiers (the lower one's Vertex
  Group read from the upper one's result);
- modifiers other than Smooth FFD below it (Subdivision Surface, a Displace weighted by a
  vertex group): the posed input, every frame, and they get the result; two Smooth FFD
  with Subdivision Surface between them and a Displace below;
- a render reads the render stack (a Subdivision Surface whose render level differs);
- an edit the group's input check misses, read on the next evaluation; the check without the
  add-on; Apply (the own mesh, as Blender's Apply of a modifier that is not first);
- the rig linked from a library and overridden;
- the rig after a round trip through Blender's FBX export and import;
- how often the object is evaluated per frame of playback, counted with Blender's
  depsgraph debug output: at most once more than the object with the Lattice modifier.
"""
import ctypes
import os
import sys
import tempfile

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, compat, stack_input  # noqa: E402

sys.path.insert(0, os.path.join(T.ROOT, "blender_scenes"))
import character as C  # noqa: E402

TOL = 1e-5
LEVEL = 2
FRAMES = range(C.FRAMES[0], C.FRAMES[1] + 1)


# --- helpers --------------------------------------------------------------------------------

def evaluated(obj):
    return obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data


def first_v_err(got, exp, size):
    """Max distance of the first V output positions from the V reference positions, in units
    of size; inf when the output has no more vertices than the reference."""
    return float(np.abs(got[:len(exp)] - exp).max()) / size if len(got) > len(exp) else np.inf


def applied_to_copy(mesh, add_modifiers):
    """Evaluated positions of a temporary object holding a copy of `mesh` with the modifiers
    add_modifiers(obj) puts on it (an independent evaluation of what follows a result)."""
    d = T.link(bpy.data.objects.new("ref_copy", mesh.copy()))
    add_modifiers(d)
    pos = T.positions(evaluated(d))
    data = d.data
    bpy.data.objects.remove(d)
    bpy.data.meshes.remove(data)
    return pos


def parity(name, a, b, lat, mods):
    """A's first V evaluated vertices against B's (its stack with Lattice modifiers), in
    units of the lattice's size; every Smooth FFD status OK."""
    got, exp = T.positions(evaluated(a)), T.positions(evaluated(b))
    size = T.lattice_size(a, lat)
    statuses = [smooth_ffd.status(m) for m in mods]
    ok_status = all(s.startswith("OK") and "warning" not in s for s in statuses)
    if len(got) <= len(exp):
        T.check(name, False, f"{len(got)} <= {len(exp)} vertices: {statuses}")
        return None
    err = float(np.abs(got[:len(exp)] - exp).max()) / size
    T.check(name, err <= TOL and ok_status, f"err {err:.2e} ({len(exp)} of {len(got)} "
                                            f"vertices) {statuses[-1][:70]}")
    return err


def reads():
    return dict(T.state.stack_counters)


def with_lattice(obj, lat, name="Lattice", vertex_group=""):
    m = obj.modifiers.new(name, 'LATTICE')
    m.object = lat
    m.vertex_group = vertex_group
    return m


def rig_pair(subdivisions=2):
    """The same character twice on one rig (A for Smooth FFD, B for Lattice), each with its
    own mesh; two materials on alternate faces."""
    rig = C.armature("rig")
    a = C.character_object(subdivisions, "A", rig)
    b = C.character_object(subdivisions, "B", rig)
    for obj in (a, b):
        me = obj.data
        for name in ("Skin", "Cloth"):
            me.materials.append(bpy.data.materials.get(name) or bpy.data.materials.new(name))
        me.polygons.foreach_set("material_index",
                                (np.arange(len(me.polygons)) % 2).astype(np.int32))
        me.update()
    return rig, a, b


def corner_map(mesh, face_attr=None):
    """{(face, vertex): corner} of a mesh (face: the source face attribute when given)."""
    loops = T.triangles_like_loops(mesh)
    starts = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("loop_start", starts)
    face = np.repeat(np.arange(len(mesh.polygons)),
                     np.diff(np.append(starts, len(loops))))
    if face_attr is not None:
        src = np.empty(len(mesh.polygons), np.int32)
        mesh.attributes[face_attr].data.foreach_get("value", src)
        face = src[face]
    return face, loops


def uvs(mesh, name):
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers[name].data.foreach_get("uv", uv)
    return uv.reshape(-1, 2)


def materials(mesh):
    mat = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", mat)
    return mat


def at_source_corners(a_mesh, b_mesh, values_a, values_b):
    """Max difference of per-corner values between A's output corners at source vertices and
    B's corner of the same source face and vertex."""
    fa, va = corner_map(a_mesh, T.meshio.SOURCE_FACE_ATTRIBUTE)
    fb, vb = corner_map(b_mesh)
    index = {(int(f), int(v)): c for c, (f, v) in enumerate(zip(fb, vb))}
    nv = len(b_mesh.vertices)
    sel = np.nonzero(va < nv)[0]
    other = np.array([index[(int(fa[c]), int(va[c]))] for c in sel])
    return float(np.abs(values_a[sel] - values_b[other]).max()), len(sel)


# --- the rigged character ---------------------------------------------------------------------

def test_armature():
    T.clear()
    rig, a, b = rig_pair()
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    plain = C.character_object(1, "plain")          # nothing above: the object's own mesh
    plain_mod = smooth_ffd.add_smooth_ffd(plain, lat, viewport_level=LEVEL)
    sc = bpy.context.scene
    sc.frame_set(FRAMES[0])
    T.update()
    before = reads()
    errs = []
    for f in FRAMES[1:]:
        sc.frame_set(f)
        errs.append(parity(f"armature: frame {f}", a, b, lat, [mod]))
    after = reads()
    T.check("playback: one reading a frame, in the frame's first evaluation (none forced or "
            "deferred)", after["reads"] - before["reads"] == len(FRAMES) - 1
            and after["forced"] == before["forced"] and after["deferred"] == before["deferred"],
            f"{before} -> {after}")
    T.check("playback: the result belongs to its frame",
            T.frames.get_frames(mod, "Result") == (FRAMES[-1] - 0.5, FRAMES[-1] + 0.5),
            str(T.frames.get_frames(mod, "Result")))
    T.check("nothing above: status without warning, own mesh read",
            smooth_ffd.status(plain_mod).startswith("OK") and
            T.objects.state_of(plain, plain_mod).source_kind == stack_input.OWN,
            smooth_ffd.status(plain_mod))

    # What comes with the posed geometry: UVs and material indices at the source corners.
    sc.frame_set(3)
    ea, eb = evaluated(a), evaluated(b)
    d_uv, n = at_source_corners(ea, eb, uvs(ea, "UVMap"), uvs(eb, "UVMap"))
    T.check("UV map from the stack at source corners", d_uv <= 1e-6, f"{d_uv:.1e} over {n}")
    fa = np.empty(len(ea.polygons), np.int32)
    ea.attributes[T.meshio.SOURCE_FACE_ATTRIBUTE].data.foreach_get("value", fa)
    T.check("material indices from the stack", np.array_equal(materials(ea), materials(eb)[fa]))

    # Same frame: a pose edit reads the stack again (one more evaluation), a lattice edit not.
    r0 = reads()
    rig.pose.bones["arm.L"].rotation_euler = (0.0, 0.9, 0.0)
    T.update()
    parity("pose edit on the same frame", a, b, lat, [mod])
    r1 = reads()
    T.check("pose edit: read once, in the evaluation the edit made (the group passed its "
            "changed input through)", r1["reads"] == r0["reads"] + 1 and
            r1["forced"] == r0["forced"] and r1["deferred"] == r0["deferred"], f"{r0} -> {r1}")
    lat.data.points[21].co_deform.z += 0.15
    T.update()
    parity("lattice edit with a pose", a, b, lat, [mod])
    T.check("lattice edit: the stack is not read", reads() == r1, f"{r1} -> {reads()}")
    T.check("nothing above: never read from the stack",
            T.objects.state_of(plain, plain_mod).source_kind == stack_input.OWN)

    # Vertex groups: only carried to the result where something reads them (none below).
    eobj = a.evaluated_get(bpy.context.evaluated_depsgraph_get())
    T.check("no vertex groups carried without a reader below", len(eobj.vertex_groups) == 0,
            str([g.name for g in eobj.vertex_groups]))


def _core_corner_normals(mesh, obj, lat):
    """The core's corner normals for `mesh` (the geometry the add-on should read) deformed by
    lat at LEVEL: an independent run of the same computation."""
    dg = bpy.context.evaluated_depsgraph_get()
    source = T.meshio.SourceMesh(mesh)
    rest, pts, interp, _shape, _key, _weights = T.latticeio.read_lattice(lat, dg)
    l2o = T.core.lattice_to_object(
        T.latticeio.world_matrix(obj, dg),
        T.latticeio.world_matrix(lat, dg))
    lattice = T.core_module().BlenderLattice(rest, pts, interpolation=interp,
                                             lattice_to_object=l2o)
    res = T.core.make_deformer(source, lattice, LEVEL, "cpu").deform(lattice)
    return np.asarray(res.corner_normals, np.float64).reshape(-1, 3)


def test_split_normals():
    """Split normals come from the stack: a Normal Edit modifier above (custom normals bent
    toward radial ones), exact normals on: A's corner normals are the core's for the stack's
    geometry (B's evaluated mesh, the same Normal Edit), not for its own mesh's."""
    T.clear()
    a = C.character_object(1, "A")
    b = C.character_object(1, "B")
    for obj in (a, b):
        ne = obj.modifiers.new("NormalEdit", 'NORMAL_EDIT')
        ne.mode = 'RADIAL'
        ne.mix_factor = 0.5
        if hasattr(obj.data, "use_auto_smooth"):
            obj.data.use_auto_smooth = True
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    compat.set_modifier_input(mod, "Exact Normals", True)
    a.update_tag()
    T.update()
    got = T.corner_normals(evaluated(a))
    exp = _core_corner_normals(evaluated(b), a, lat)
    own = _core_corner_normals(b.data, a, lat)
    if got.shape != exp.shape:
        T.check("split normals from the stack", False, f"{got.shape} vs {exp.shape}")
        return
    d = np.linalg.norm(got - exp, axis=1)
    d_own = float(np.linalg.norm(own - exp, axis=1).max()) if own.shape == exp.shape else 1.0
    # 3.4-4.4 store custom normals as 16-bit angles (docs/addon.md): about 2e-3 rad.
    ok = d.max() <= 1e-5 if compat.HAS_FREE_NORMAL_ATTRIBUTE else \
        (np.median(d) <= 2e-3 and d.max() <= 5e-2)
    T.check("split normals from the stack", ok and d_own > 0.05,
            f"max {d.max():.1e}, median {np.median(d):.1e} over {len(d)} corners (the own "
            f"mesh's normals differ by up to {d_own:.2f})")


# --- Mirror, Subdivision Surface, Array -------------------------------------------------------

def half_character(name):
    """The body's right half (x >= 0) with weights, for a Mirror modifier."""
    obj = C.character_object(1, name)
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bmesh.ops.delete(bm, geom=[v for v in bm.verts if v.co.x < -1e-5], context='VERTS')
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()
    return obj


def test_modifiers_above():
    for kind in ("MIRROR", "SUBSURF", "ARRAY"):
        T.clear()
        objs = [half_character(n) if kind == "MIRROR" else C.character_object(1, n)
                for n in ("A", "B")]
        for obj in objs:
            m = obj.modifiers.new(kind.title(), kind)
            if kind == "MIRROR":
                m.use_clip = True
                m.use_mirror_merge = True
                m.use_mirror_u = True          # the mirrored half's UVs differ from the mesh's
            elif kind == "SUBSURF":
                m.levels = 1
            else:
                m.count = 2
                m.relative_offset_displace = (1.1, 0.0, 0.0)
        a, b = objs
        lat = C.lattice_around([a])
        # Mirror: weight by "arm.R", which only the mirrored half has (use_mirror_vertex_groups).
        group = "arm.R" if kind == "MIRROR" else ""
        with_lattice(b, lat, vertex_group=group)
        mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, vertex_group=group)
        T.update()
        parity(f"{kind.lower()} above", a, b, lat, [mod])
        if kind == "MIRROR":
            ea, eb = evaluated(a), evaluated(b)
            d_uv, n = at_source_corners(ea, eb, uvs(ea, "UVMap"), uvs(eb, "UVMap"))
            T.check("mirror: mirrored UVs from the stack", d_uv <= 1e-6, f"{d_uv:.1e} over {n}")
        T.check(f"{kind.lower()}: nothing animated, the result holds for every frame",
                T.frames.get_frames(mod, "Result") == T.state.ALWAYS)
        plans = T.state.plans_built[0]
        for obj in objs:   # a setting above changes the topology: a new plan
            m = obj.modifiers[kind.title()]
            if kind == "MIRROR":
                m.use_axis = (True, True, False)
            elif kind == "SUBSURF":
                m.levels = 2
            else:
                m.count = 3
        T.update()
        parity(f"{kind.lower()} above, setting changed", a, b, lat, [mod])
        T.check(f"{kind.lower()}: new plan", T.state.plans_built[0] == plans + 1,
                f"{T.state.plans_built[0] - plans} plans built")


def test_shape_keys():
    T.clear()
    objs = [C.character_object(1, n) for n in ("A", "B")]
    for obj in objs:
        obj.shape_key_add(name="Basis")
        bulge = obj.shape_key_add(name="Bulge")
        lift = obj.shape_key_add(name="Lift")
        co = np.empty(len(obj.data.vertices) * 3, np.float32)
        obj.data.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)
        grow = co.copy()
        grow[:, :2] *= 1.0 + 0.4 * np.exp(-((co[:, 2] - 1.2) / 0.3) ** 2)[:, None]
        bulge.data.foreach_set("co", grow.ravel())
        up = co.copy()
        up[:, 2] += 0.3 * np.clip(np.abs(co[:, 0]) - 0.3, 0, None)
        lift.data.foreach_set("co", up.ravel())
        lift.value = 0.0
        lift.keyframe_insert("value", frame=FRAMES[0])
        lift.value = 1.0
        lift.keyframe_insert("value", frame=FRAMES[-1])
        bulge.value = 0.5
    a, b = objs
    lat = C.lattice_around([a], margin=0.2)
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    sc = bpy.context.scene
    for f in (1, 3, 6):
        sc.frame_set(f)
        parity(f"shape keys, animated value: frame {f}", a, b, lat, [mod])
    for obj in objs:
        obj.data.shape_keys.key_blocks["Bulge"].value = 1.0
    T.update()
    parity("shape key value changed on the same frame", a, b, lat, [mod])


def test_two_smooth_ffd():
    T.clear()
    rig, a, b = rig_pair()
    lat1 = C.lattice_around([a], name="lat1")
    lat2 = C.lattice_around([a], shape=(3, 3, 3), margin=0.3, jitter=0.1, seed=7, name="lat2")
    with_lattice(b, lat1, "Lattice 1")
    with_lattice(b, lat2, "Lattice 2", vertex_group="arm.L")
    m1 = smooth_ffd.add_smooth_ffd(a, lat1, viewport_level=LEVEL, name="Smooth FFD 1")
    m2 = smooth_ffd.add_smooth_ffd(a, lat2, viewport_level=LEVEL, vertex_group="arm.L",
                                   name="Smooth FFD 2")
    sc = bpy.context.scene
    for f in FRAMES:
        sc.frame_set(f)
        parity(f"two in a row: frame {f}", a, b, lat2, [m1, m2])
    T.check("the lower one reads the upper one's result",
            T.objects.state_of(a, m2).source_kind == stack_input.CHAIN)
    lat1.data.points[4].co_deform.x += 0.2
    T.update()
    parity("two in a row: upper lattice edited", a, b, lat2, [m1, m2])


def _below(obj):
    """The modifiers below Smooth FFD in test_modifiers_below: Subdivision Surface, and a
    Displace weighted by a vertex group (it reads the groups carried onto the result)."""
    obj.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    d = obj.modifiers.new("Displace", 'DISPLACE')
    d.strength, d.vertex_group = 0.2, "arm.L"


def _stack_below_matches(name, a, ro, tol=1e-6):
    """A's evaluated mesh against the same modifiers below applied to a copy of its Smooth FFD
    result in another object (an independent evaluation of what should follow it)."""
    got, exp = T.positions(evaluated(a)), applied_to_copy(ro.data, _below)
    err = float(np.abs(got - exp).max()) if got.shape == exp.shape else np.inf
    T.check(name, err <= tol, f"err {err:.1e}, {len(got)} vs {len(exp)} vertices")


def test_modifiers_below():
    """Armature above, Subdivision Surface and a Displace weighted by a vertex group below:
    Smooth FFD deforms the posed geometry (its result against Lattice at the same position,
    every frame), and what follows it gets its result (against the same modifiers applied to
    the result in another object); the input copy is read in the frame's first evaluation."""
    T.clear()
    rig, a, b = rig_pair(1)
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL)
    _below(a)
    sc = bpy.context.scene
    sc.frame_set(FRAMES[0])
    T.update()
    ro = T.objects.result_object(a, mod, create=False)
    size = T.lattice_size(a, lat)
    before = reads()
    for f in FRAMES[1:]:
        sc.frame_set(f)
        err = first_v_err(T.positions(ro.data), T.positions(evaluated(b)), size)
        status = smooth_ffd.status(mod)
        T.check(f"modifiers below: frame {f} against Lattice", err <= TOL and
                status.startswith("OK") and "warning" not in status,
                f"err {err:.2e}, {status[:80]}")
        if f in (2, FRAMES[-1]):
            _stack_below_matches(f"modifiers below: frame {f}, they get the result", a, ro)
    # What comes with the posed geometry through the copy: UVs and material indices.
    rm, eb = ro.data, evaluated(b)
    d_uv, n = at_source_corners(rm, eb, uvs(rm, "UVMap"), uvs(eb, "UVMap"))
    T.check("modifiers below: UV map from the stack at source corners", d_uv <= 1e-6,
            f"{d_uv:.1e} over {n}")
    fa = np.empty(len(rm.polygons), np.int32)
    rm.attributes[T.meshio.SOURCE_FACE_ATTRIBUTE].data.foreach_get("value", fa)
    T.check("modifiers below: material indices from the stack",
            np.array_equal(materials(rm), materials(eb)[fa]))
    after = reads()
    T.check("modifiers below: one reading a frame, none forced or deferred",
            after["reads"] - before["reads"] == len(FRAMES) - 1
            and after["forced"] == before["forced"] and after["deferred"] == before["deferred"],
            f"{before} -> {after}")
    T.check("modifiers below: Input Copy set to the modifier's place",
            compat.get_modifier_input(mod, "Input Copy") == 2,
            str(compat.get_modifier_input(mod, "Input Copy")))
    # Same frame: a pose edit, then a lattice edit.
    rig.pose.bones["arm.L"].rotation_euler = (0.0, 0.9, 0.0)
    T.update()
    parity_err = first_v_err(T.positions(ro.data), T.positions(evaluated(b)), size)
    T.check("modifiers below: pose edit on the same frame", parity_err <= TOL,
            f"err {parity_err:.2e}")
    lat.data.points[21].co_deform.z += 0.15
    T.update()
    parity_err = first_v_err(T.positions(ro.data), T.positions(evaluated(b)), size)
    T.check("modifiers below: lattice edit", parity_err <= TOL, f"err {parity_err:.2e}")
    _stack_below_matches("modifiers below: after the edits, they get the result", a, ro)
    # The result shown: no input copy left among the evaluated instances.
    dg = bpy.context.evaluated_depsgraph_get()
    T.check("modifiers below: no input copy once the result shows",
            stack_input.input_copy(a, 2, dg, lambda m: True) is None)
    # A bake (render level = viewport level here) goes through the modifiers below as well.
    live = {}
    for f in (2, 3):
        sc.frame_set(f)
        live[f] = T.positions(evaluated(a))
    smooth_ffd.bake_smooth_ffd(a, mod, 2, 3)
    for f in (3, 2):
        sc.frame_set(f)
        got = T.positions(evaluated(a))
        err = float(np.abs(got - live[f]).max()) if got.shape == live[f].shape else np.inf
        T.check(f"modifiers below: baked frame {f} equals the live one", err <= 1e-6,
                f"err {err:.1e}")
    smooth_ffd.clear_bake(a, mod)
    # The modifiers below removed: back to the evaluated object, the copy turned off.
    for name in ("Subsurf", "Displace"):
        a.modifiers.remove(a.modifiers[name])
    T.update()
    smooth_ffd.update(a)
    parity("modifiers below removed: the evaluated object", a, b, lat, [mod])
    T.check("modifiers below removed: Input Copy 0",
            compat.get_modifier_input(mod, "Input Copy") == 0)


def test_modifiers_between():
    """Armature, Smooth FFD 1, Subdivision Surface, Smooth FFD 2, Displace: both read the
    stack through their input copies (places 2 and 4) in the same evaluations. Smooth FFD 1
    against Lattice on B; Smooth FFD 2 against an independent evaluation of its position:
    an object D holding Smooth FFD 1's result with Subdivision Surface and Lattice 2 (D's
    Lattice output is what Smooth FFD 2 must give for its first V vertices)."""
    T.clear()
    rig, a, b = rig_pair(1)
    lat1 = C.lattice_around([a], name="lat1")
    lat2 = C.lattice_around([a], shape=(3, 3, 3), margin=0.3, jitter=0.1, seed=7, name="lat2")
    with_lattice(b, lat1)
    m1 = smooth_ffd.add_smooth_ffd(a, lat1, viewport_level=LEVEL, render_level=LEVEL,
                                   name="Smooth FFD 1")
    a.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    m2 = smooth_ffd.add_smooth_ffd(a, lat2, viewport_level=LEVEL, render_level=LEVEL,
                                   name="Smooth FFD 2")
    a.modifiers.new("Displace", 'DISPLACE').strength = 0.1
    sc = bpy.context.scene
    sc.frame_set(FRAMES[0])
    T.update()
    r1 = T.objects.result_object(a, m1, create=False)
    r2 = T.objects.result_object(a, m2, create=False)
    for f in (2, 4, FRAMES[-1]):
        deferred = T.state.stack_counters["deferred"]
        sc.frame_set(f)
        # Inside frame_change_post the upper one writes its result, and the lower one's input
        # (below it) is shown only by the next evaluation: it waits for it (defer), showing
        # its input meanwhile; in a window a timer runs that update at once.
        T.check(f"modifiers between: frame {f}, the lower one waits for the next update",
                T.state.stack_counters["deferred"] == deferred + 1 and
                T.frames.get_frames(m1, "Result") == (f - 0.5, f + 0.5) and
                T.frames.get_frames(m2, "Result") == (1.0, 0.0),
                f"{T.state.stack_counters}, {T.frames.get_frames(m2, 'Result')}")
        smooth_ffd.update(a)   # what the timer runs
        statuses = [smooth_ffd.status(m) for m in (m1, m2)]
        got, got2 = T.positions(r1.data), T.positions(r2.data)   # before any evaluation
        e1 = first_v_err(got, T.positions(evaluated(b)), T.lattice_size(a, lat1))

        def subsurf_lattice2(d):
            d.modifiers.new("Subsurf", 'SUBSURF').levels = 1
            with_lattice(d, lat2)
        e2 = first_v_err(got2, applied_to_copy(r1.data, subsurf_lattice2),
                         T.lattice_size(a, lat2))
        T.check(f"modifiers between: frame {f}, Smooth FFD 1 against Lattice, Smooth FFD 2 "
                f"against Lattice on 1's result + Subsurf", e1 <= TOL and e2 <= TOL and
                all(s.startswith("OK") and f"frame {f}," in s for s in statuses),
                f"err {e1:.2e}, {e2:.2e}; {[s[:40] for s in statuses]}")
    # A bake of the lower one evaluates as often as it needs: frame 3 baked equals frame 3
    # computed live (with the update the timer would run).
    sc.frame_set(3)
    smooth_ffd.update(a)
    live = T.positions(evaluated(a))
    smooth_ffd.bake_smooth_ffd(a, m2, 3, 3)
    sc.frame_set(2)
    sc.frame_set(3)
    got = T.positions(evaluated(a))
    err = float(np.abs(got - live).max()) if got.shape == live.shape else np.inf
    T.check("modifiers between: the lower one baked on frame 3 equals its live result",
            err <= 1e-6, f"err {err:.1e}, {len(got)} vs {len(live)} vertices")
    smooth_ffd.clear_bake(a, m2)
    T.check("modifiers between: Input Copy 2 and 4",
            (compat.get_modifier_input(m1, "Input Copy"),
             compat.get_modifier_input(m2, "Input Copy")) == (2, 4))


def test_render_stack():
    """A render reads the render stack: Subdivision Surface above with render level 1,
    viewport level 0."""
    T.clear()
    a = C.character_object(1, "A")
    sub = a.modifiers.new("Subsurf", 'SUBSURF')
    sub.levels, sub.render_levels = 0, 1
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL)
    ref = C.character_object(1, "ref")              # the render stack, in the viewport
    ref.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    with_lattice(ref, lat)
    ref.hide_render = True
    sc = bpy.context.scene
    T.tiny_cycles()
    T.update()
    seen = {}
    ro = T.objects.result_object(a, mod, create=False)

    def grab(scene, *_args):
        seen["pos"] = T.positions(ro.data)
    bpy.app.handlers.render_post.append(grab)
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        bpy.app.handlers.render_post.remove(grab)
    exp = T.positions(evaluated(ref))
    got = seen.get("pos")
    err = first_v_err(got, exp, T.lattice_size(a, lat)) if got is not None else np.inf
    T.check("render: the render stack (Subsurf render level)", err <= TOL,
            f"err {err:.2e}, {len(exp)} vertices at the render level")
    view = T.positions(evaluated(a))
    T.check("after the render: the viewport stack again", len(view) < len(got) and
            smooth_ffd.status(mod).startswith("OK"), f"{len(view)} vs {len(got)}")
    # A modifier below (the input copy): the render reads the render stack through it too.
    a.modifiers.new("Displace", 'DISPLACE').strength = 0.1
    T.update()
    seen.clear()
    bpy.app.handlers.render_post.append(grab)
    try:
        bpy.ops.render.render(write_still=False)
    finally:
        bpy.app.handlers.render_post.remove(grab)
    got = seen.get("pos")
    err = first_v_err(got, exp, T.lattice_size(a, lat)) if got is not None else np.inf
    T.check("render with a modifier below: the render stack", err <= TOL,
            f"err {err:.2e}, {len(exp)} vertices at the render level")


def test_edits_the_check_misses():
    """An edit that moves no vertex (Mirror's UV offset: only the mirrored UVs change): the
    group still shows the result, so the handler reads the input on the next evaluation
    (stack_input.defer; in a window a timer runs it at once, here the timer's function is
    called), and the UVs follow."""
    T.clear()
    objs = [half_character(n) for n in ("A", "B")]
    for obj in objs:
        m = obj.modifiers.new("Mirror", 'MIRROR')
        m.use_clip = m.use_mirror_merge = m.use_mirror_u = True
    a, b = objs
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    T.update()
    r0 = reads()
    for obj in objs:
        obj.modifiers["Mirror"].mirror_offset_u = 0.25
    T.update()
    r1 = reads()
    T.check("UV-only edit above: read on the next evaluation", r1["deferred"] == r0["deferred"] + 1
            and len(evaluated(a).vertices) == len(evaluated(b).vertices), f"{r0} -> {r1}")
    T.handlers._deferred_update()
    ea, eb = evaluated(a), evaluated(b)
    d_uv, n = at_source_corners(ea, eb, uvs(ea, "UVMap"), uvs(eb, "UVMap"))
    T.check("UV-only edit above: UVs follow", d_uv <= 1e-6 and reads()["reads"] == r1["reads"] + 1,
            f"{d_uv:.1e} over {n}, {reads()}")
    parity("UV-only edit above: parity", a, b, lat, [mod])


def test_check_without_addon():
    """Without the add-on's handlers the group shows a result only for the input it was
    computed from: a pose edit then shows the posed input, not the old result."""
    T.clear()
    rig, a, b = rig_pair(1)
    rig.animation_data_clear()            # a static pose: the result holds for every frame
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    T.update()
    T.check("static pose: the result holds for every frame",
            T.frames.get_frames(mod, "Result") == T.state.ALWAYS)
    smooth_ffd.unregister()
    before = tuple(rig.pose.bones["arm.L"].rotation_euler)
    try:
        rig.pose.bones["arm.L"].rotation_euler = (0.0, 0.7, 0.0)
        T.update()
        got, exp = T.positions(evaluated(a)), T.positions(evaluated(b))
        T.check("without the add-on, another pose shows the input, not the old result",
                got.shape == exp.shape and np.abs(got - exp).max() == 0.0,
                f"{got.shape} vs {exp.shape}")
        rig.pose.bones["arm.L"].rotation_euler = before
        T.update()
        T.check("the pose it was computed for: the result again",
                len(evaluated(a).vertices) > len(evaluated(b).vertices))
    finally:
        smooth_ffd.register()


def test_apply():
    """Apply takes the object's own mesh, as Blender's Apply of a modifier that is not first:
    the applied mesh is the rest pose deformed, the Armature above stays."""
    T.clear()
    rig, a, b = rig_pair(1)
    b.modifiers.remove(b.modifiers["Armature"])
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL)
    bpy.context.scene.frame_set(3)
    smooth_ffd.apply_smooth_ffd(a, mod)
    got, exp = T.positions(a.data), T.positions(evaluated(b))
    err = float(np.abs(got[:len(exp)] - exp).max()) / T.lattice_size(a, lat)
    T.check("apply with a modifier above: the own mesh, the Armature kept",
            err <= TOL and [m.type for m in a.modifiers] == ['ARMATURE'] and
            not any(o.get(T.state.STACK_KEY) for o in bpy.data.objects),
            f"err {err:.2e}, {[m.type for m in a.modifiers]}")


def test_linked_rig_override():
    """A rig linked from a library file and overridden (Object > Library Override > Make, as
    production shots take characters): the override reads its own stack on every frame, into
    its own result and stack objects, the library's never written."""
    folder = tempfile.mkdtemp()
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    coll = bpy.data.collections.new("Character")
    sc.collection.children.link(coll)
    rig, a, b = rig_pair(1)
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    sc.frame_set(2)
    T.update()
    for ob in (rig, a, b, lat):
        for c in list(ob.users_collection):
            c.objects.unlink(ob)
        coll.objects.link(ob)
    path = os.path.join(folder, "rig.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    saved = open(path, "rb").read()
    bpy.ops.wm.read_homefile(use_empty=True)
    sc = bpy.context.scene
    with bpy.data.libraries.load(path, link=True) as (_src, dst):
        dst.collections = ["Character"]
    empty = T.link(bpy.data.objects.new("Character", None))
    empty.instance_type = 'COLLECTION'
    empty.instance_collection = dst.collections[0]
    dst.collections[0].override_hierarchy_create(sc, bpy.context.view_layer, reference=empty)
    bpy.data.objects.remove(empty)
    over = {o.name: o for o in bpy.data.objects if o.override_library is not None}
    a, b, lat = over.get("A"), over.get("B"), over.get("lat")
    if a is None or b is None or lat is None:
        T.check("linked rig: overridden", False, str(sorted(over)))
        return
    mod = a.modifiers["Smooth FFD"]
    posed = []
    for f in FRAMES:
        sc.frame_set(f)
        parity(f"linked rig, overridden: frame {f}", a, b, lat, [mod])
        posed.append(T.positions(evaluated(b)))
    T.check("linked rig: the linked action plays", np.abs(posed[2] - posed[0]).max() > 0.1,
            f"{np.abs(posed[2] - posed[0]).max():.2f}")
    so = compat.get_modifier_input(mod, "Stack Object")
    ro = compat.get_modifier_input(mod, "Result Object")
    T.check("linked rig: the override's own result and stack objects",
            so is not None and ro is not None and so.library is None and ro.library is None
            and so.override_library is None and ro.override_library is None,
            f"{so and so.name_full}, {ro and ro.name_full}")
    T.check("linked rig: the library file untouched", open(path, "rb").read() == saved)


# --- a rig from another tool: FBX round trip ---------------------------------------------------

def test_fbx_round_trip():
    T.clear()
    obj, rig = C.rigged_character(2, "char")
    path = os.path.join(tempfile.mkdtemp(), "character.fbx")
    for o in bpy.context.scene.objects:
        o.select_set(o.name in ("char", "char.rig"))
    bpy.context.view_layer.objects.active = obj
    r = bpy.ops.export_scene.fbx(filepath=path, use_selection=True, bake_anim=True,
                                 add_leaf_bones=False)
    T.check("FBX export", r == {'FINISHED'} and os.path.getsize(path) > 0)
    T.clear()
    r = bpy.ops.import_scene.fbx(filepath=path)
    meshes = [o for o in bpy.context.scene.objects if o.type == 'MESH']
    rigs = [o for o in bpy.context.scene.objects if o.type == 'ARMATURE']
    T.check("FBX import: a mesh parented to an animated rig, with an Armature modifier and "
            "custom normals", r == {'FINISHED'} and len(meshes) == 1 and len(rigs) == 1 and
            any(m.type == 'ARMATURE' for m in meshes[0].modifiers) and
            meshes[0].parent == rigs[0] and meshes[0].data.has_custom_normals and
            rigs[0].animation_data is not None, str([(o.name, o.type) for o in meshes + rigs]))
    a = meshes[0]
    b = a.copy()
    b.data = a.data.copy()
    b.name = "B"
    T.link(b)
    if b.parent is None:
        b.matrix_world = a.matrix_world
    sc = bpy.context.scene
    sc.frame_set(FRAMES[0])
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    for f in FRAMES:
        sc.frame_set(f)
        parity(f"FBX round trip: frame {f}", a, b, lat, [mod])


# --- evaluations per frame -------------------------------------------------------------------

_libc = ctypes.CDLL(None)


def _counted(fn, names):
    """How often Blender evaluated each object's geometry while fn ran (the depsgraph's
    evaluation debug output on stdout, captured at the file descriptor)."""
    _libc.fflush(None)
    sys.stdout.flush()
    saved = os.dup(1)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 1)
        try:
            fn()
        finally:
            _libc.fflush(None)
            sys.stdout.flush()
            os.dup2(saved, 1)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read().decode(errors="replace")
    return {n: text.count(f"BKE_object_handle_data_update on OB{n} ") for n in names}


def test_evaluations_per_frame():
    """Runs last: it reloads the file with Blender's depsgraph evaluation debugging on (the
    flag is read when a depsgraph is made)."""
    T.clear()
    rig, a, b = rig_pair()
    lat = C.lattice_around([a])
    with_lattice(b, lat)
    smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL)
    # The same with modifiers below: C (Smooth FFD) against D (Lattice).
    c = C.character_object(2, "C", rig)
    d = C.character_object(2, "D", rig)
    smooth_ffd.add_smooth_ffd(c, lat, viewport_level=LEVEL)
    with_lattice(d, lat)
    for obj in (c, d):
        obj.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    path = os.path.join(tempfile.mkdtemp(), "count.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.app.debug_depsgraph_eval = True
    try:
        bpy.ops.wm.open_mainfile(filepath=path)
        sc = bpy.context.scene
        sc.frame_set(FRAMES[0])
        per_frame = [_counted(lambda f=f: sc.frame_set(f), ("A", "B", "C", "D"))
                     for f in FRAMES[1:]]
        rig = bpy.data.objects["rig"]

        def pose():
            rig.pose.bones["arm.R"].rotation_euler = (0.0, -0.8, 0.0)
            bpy.context.view_layer.update()

        def lattice_edit():
            bpy.data.objects["lat"].data.points[5].co_deform.z += 0.1
            bpy.context.view_layer.update()
        parity("reopened: the stack read again", bpy.data.objects["A"], bpy.data.objects["B"],
               bpy.data.objects["lat"], [bpy.data.objects["A"].modifiers["Smooth FFD"]])
        posed = _counted(pose, ("A", "B"))
        edited = _counted(lattice_edit, ("A", "B"))
    finally:
        bpy.app.debug_depsgraph_eval = False
    extra = [c["A"] - c["B"] for c in per_frame]
    print(f"evaluations per frame of playback (Smooth FFD object, Lattice object): "
          f"{[(c['A'], c['B']) for c in per_frame]}; pose edit {posed}; lattice edit {edited}")
    T.check("playback: at most one more evaluation of the stack above than Lattice",
            all(c["B"] >= 1 for c in per_frame) and max(extra) <= 1, str(per_frame))
    extra_below = [c["C"] - c["D"] for c in per_frame]
    print(f"with Subdivision Surface below (Smooth FFD object, Lattice object): "
          f"{[(c['C'], c['D']) for c in per_frame]}")
    T.check("playback with modifiers below: at most one more evaluation than Lattice",
            all(c["D"] >= 1 for c in per_frame) and max(extra_below) <= 1,
            str([(c['C'], c['D']) for c in per_frame]))
    T.check("pose edit on the same frame: at most two more", posed["A"] - posed["B"] <= 2,
            str(posed))
    T.check("lattice edit: no more than before", edited["A"] <= 2 and edited["B"] >= 1,
            str(edited))


def main():
    T.setup()
    for fn in (test_armature, test_split_normals, test_modifiers_above, test_shape_keys,
               test_two_smooth_ffd, test_modifiers_below, test_modifiers_between,
               test_render_stack,
               test_edits_the_check_misses, test_check_without_addon, test_apply,
               test_linked_rig_override, test_fbx_round_trip, test_evaluations_per_frame):
        T.run(fn.__name__, fn)
    T.finish()


main()
