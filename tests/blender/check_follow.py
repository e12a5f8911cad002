"""Plans that follow a moving source (plans.follow): an Armature or animated shape keys above
Smooth FFD move its input every frame without changing its faces, so the add-on moves its
plan to the new pose (smoothffd.Deformer.follow) instead of planning again.

- a rigged character (blender_scenes/character.py: an Armature modifier first), its quads and
  a triangulated copy, played over frames 1-6, and Suzanne (triangulated) with an animated
  shape key value:
  (a) one plan is built, on the first frame; every later frame follows it;
  (b) on every frame the result mesh's positions equal those of the core's own Deformer,
      built here on the first frame's posed input and made to follow the same poses, within
      1e-6 of the lattice's size; where the input is triangles (so that a plan built afresh
      triangulates it as the first one did) also the add-on's own result with its plan
      dropped on that frame (a fresh plan), compared point by point where both results have
      a point at the same rest position (95% of the points at least): within 1e-6 where the
      fresh plan's triangles are the followed one's, within FRESH_TOL where it split a clipped
      piece by another diagonal;
  (c) a pose changed slightly on the same frame (a bone turned by 1e-3 rad, a shape key value
      by 1e-4) keeps the output topology: the result mesh's topology is not written again
      (the write counters, `rebuilt`, its triangles) and its UV maps are not carried again,
      only its positions and rest positions move, by what the core's following Deformer
      gives; wherever a follow kept the topology
      during playback the same holds.
- Suzanne (triangulated) in a lattice that moves and turns over the frames (as one parented
  to a bone): the plan follows the lattice's placement, (a) and (b) as above;
- Suzanne (triangulated) under a Wave modifier and a Displace modifier with a keyframed
  strength, both above Smooth FFD: other vertex-moving modifiers take the same path, (a) and
  (b) as above;
- an imported rigged character: the fox of tests/data/real/fox.glb through Blender's own glTF
  importer (its skinned mesh, a triangle soup, under the imported armature playing the
  file's Walk action), Smooth FFD added below its Armature modifier as the operator places
  it: (a) and (b) as above;
- a bake of the shape-key animation follows the plan too: no plan built, every baked frame
  the played result;
- the posed input the add-on reads equals the twin object's evaluated mesh (the same stack
  without Smooth FFD), and the source mesh is never written;
- the pieces held (plans.hold_pieces): the character in a slight idle motion played in the
  viewport follows holding its pieces as the core's Deformer.follow(hold=True) does, and
  writes no topology where they hold; the character waving in a lattice that boxes the whole
  wave holds them on every frame, where only the sharp edges change: written alone; the
  waving character rendered with motion blur has one topology over the shutter (its
  subframes evaluated by hand after render_pre, and a real Cycles render of frame 2), where
  without the shutter known the subframes' differ; with an adaptive render tessellation
  too: the counts taken over the shutter (holdframes.hold_shutter) are per the frame's
  pieces, which every subframe holds, so they apply on every subframe.
"""
import os
import sys

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, compat, core, handlers, latticeio, live, meshio, objects, \
    pipeline, result_arrays, state  # noqa: E402

sys.path.insert(0, os.path.join(T.ROOT, "blender_scenes"))
import character as C  # noqa: E402

LEVEL = 2
TOL = 1e-6   # of the lattice's size: float32 rounding of positions around 1
# A fresh plan splits a clipped piece by the diagonal that suits the piece's current shape; a
# followed plan keeps its first plan's (so that its topology holds). Where they differ, so do
# the two fits near that piece: by 3.5e-5 of the lattice's size at most in these scenes.
FRESH_TOL = 1e-4
FRAMES = range(C.FRAMES[0], C.FRAMES[1] + 1)


def evaluated(obj):
    return obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data


def triangulate(me):
    bm = bmesh.new()
    bm.from_mesh(me)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()


def counters():
    return dict(built=state.plans_built[0], followed=state.plans_followed[0],
                kept=state.plans_followed_kept[0], held=state.plans_followed_held[0],
                topology=state.mesh_writes["topology"], sharp=state.mesh_writes["sharp"],
                values=state.mesh_writes["values"])


def delta(before):
    now = counters()
    return {k: now[k] - before[k] for k in now}


class Reference:
    """The core's Deformer on the twin's posed mesh (the stack above without Smooth FFD),
    built on the first pose and following every later one: what the add-on's plan cache
    must reproduce, computed without it. hold: following with hold=True (the pieces held)."""

    def __init__(self, a, twin, lat, hold=False):
        self.a, self.twin, self.lat, self.hold = a, twin, lat, hold
        self.deformer = None

    def source(self):
        return meshio.SourceMesh(evaluated(self.twin), None, False, [])

    def lattice(self):
        dg = bpy.context.evaluated_depsgraph_get()
        rest, pts, interp, _shape, _key, _weights = latticeio.read_lattice(self.lat, dg)
        l2o = core.lattice_to_object(latticeio.world_matrix(self.a, dg),
                                     latticeio.world_matrix(self.lat, dg))
        return T.core_module().BlenderLattice(rest, pts, interpolation=interp,
                                              lattice_to_object=l2o)

    def frame(self):
        """(positions, triangles, kept) of the current pose."""
        src, lattice = self.source(), self.lattice()
        kept = None
        if self.deformer is None:
            self.deformer = core.make_deformer(src, lattice, LEVEL, "cpu")
        else:
            kept = self.deformer.follow(core.make_mesh(src), lattice=lattice, hold=self.hold)
        res = self.deformer.deform(lattice, normals=True, layout="corners")
        self.sharp_edges = np.asarray(res.sharp_edges).reshape(-1, 2)
        return np.asarray(res.positions, np.float64), np.asarray(res.triangles), kept


def result_mesh(a, mod):
    return objects.result_object(a, mod, create=False).data


def err_of(got, exp, size):
    if got.shape != exp.shape:
        return np.inf
    return float(np.abs(got - exp).max()) / size


def shared_points(rest_a, pos_a, rest_b, pos_b, size):
    """(share, err): the points of result a whose rest position is also one of result b's
    (within 1e-7 of the lattice size), as a share of a's points, and the largest distance
    between the two results' positions of those points, relative to `size`. A fresh plan and a
    followed one agree on every point they have in common (the input's vertices, the cuts, the
    points on the edges both have); where a clipped piece is split by another diagonal (a
    followed plan keeps its first plan's), the points on that diagonal are the plan's own."""
    key_a = np.round(rest_a / (1e-7 * size)).astype(np.int64)
    key_b = np.round(rest_b / (1e-7 * size)).astype(np.int64)
    keys, inverse = np.unique(np.concatenate([key_a, key_b]), axis=0, return_inverse=True)
    inverse = inverse.ravel()
    where_b = np.full(len(keys), -1)
    where_b[inverse[len(key_a):]] = np.arange(len(key_b))
    match = where_b[inverse[:len(key_a)]]
    ok = match >= 0
    if not ok.any():
        return 0.0, np.inf
    err = float(np.abs(pos_a[ok] - pos_b[match[ok]]).max()) / size
    return float(ok.mean()), err


def play(name, a, twin, lat, mod, fresh):
    """Plays FRAMES; checks (a), (b) and the playback half of (c); returns the reference."""
    sc = bpy.context.scene
    size = T.lattice_size(a, lat)
    ref = Reference(a, twin, lat)
    src_before = T.positions(a.data).copy()
    sc.frame_set(FRAMES[0])
    T.update()
    start = counters()
    played, rests, tris_of = {}, {}, {}
    last_tris = None
    for i, f in enumerate(FRAMES):
        before = counters()
        if i:
            sc.frame_set(f)
        d = delta(before)
        st = objects.state_of(a, mod)
        twin_src = ref.source()
        T.check(f"{name}: frame {f}: the add-on's input is the posed mesh",
                st is not None and st.source is not None
                and np.array_equal(st.source.positions, twin_src.positions)
                and np.array_equal(st.source.corner_vertices, twin_src.corner_vertices),
                "" if st is None or st.source is None else
                f"{np.abs(st.source.positions - twin_src.positions).max():.1e}")
        exp, exp_tris, ref_kept = ref.frame()
        me = result_mesh(a, mod)
        got, tris = T.positions(me).astype(np.float64), T.triangles(me)
        err = err_of(got, exp, size)
        status = smooth_ffd.status(mod)
        T.check(f"{name}: frame {f}: the core's following Deformer's positions",
                err <= TOL and status.startswith("OK") and np.array_equal(tris, exp_tris),
                f"err {err:.1e} of the lattice size, {len(got)} vs {len(exp)} vertices, "
                f"{status[:60]}")
        if i:
            T.check(f"{name}: frame {f}: followed, not planned",
                    d["built"] == 0 and d["followed"] == 1 and d["kept"] == int(ref_kept),
                    f"{d}, core's follow kept {ref_kept}")
            timing = pipeline.last_timing(a, mod)
            if d["kept"]:
                T.check(f"{name}: frame {f}: topology kept, values written only",
                        d["topology"] == 0 and d["values"] == 1 and not timing["rebuilt"]
                        and timing["carry_ms"] == 0.0 and np.array_equal(tris, last_tris),
                        f"{d}, rebuilt {timing['rebuilt']}, carry {timing['carry_ms']:.2f} ms")
            else:
                T.check(f"{name}: frame {f}: new topology written",
                        d["topology"] == 1 or np.array_equal(tris, last_tris), str(d))
        played[f] = got
        rests[f] = T.point_attribute(me, meshio.REST_ATTRIBUTE).astype(np.float64)
        tris_of[f] = tris
        last_tris = tris
    d = delta(start)
    T.check(f"{name}: one plan over frames {FRAMES[0]}-{FRAMES[-1]}",
            state.plans_built[0] >= 1 and d["built"] == 0 and d["followed"] == len(FRAMES) - 1,
            f"{d}")
    print(f"{name}: {d['followed']} follows, {d['kept']} kept the topology, "
          f"{d['topology']} topology writes, {d['values']} value writes")
    if fresh:
        for f in FRAMES:
            sc.frame_set(f)
            built = state.plans_built[0]
            pipeline.forget(a, mod)
            smooth_ffd.update(a, mod)   # as the viewport: not forced (that carries groups)
            me = result_mesh(a, mod)
            got = T.positions(me).astype(np.float64)
            rest = T.point_attribute(me, meshio.REST_ATTRIBUTE).astype(np.float64)
            share, err = shared_points(rest, got, rests[f], played[f], size)
            same = np.array_equal(T.triangles(me), tris_of[f])
            T.check(f"{name}: frame {f}: a fresh plan gives the followed result",
                    share >= 0.95 and err <= (TOL if same else FRESH_TOL)
                    and state.plans_built[0] == built + 1,
                    f"{share:.1%} of its points on the followed result's, err {err:.1e} of "
                    f"the lattice size, {'the same' if same else 'other'} triangles, "
                    f"{state.plans_built[0] - built} built")
    T.check(f"{name}: the source mesh is not written",
            np.array_equal(T.positions(a.data), src_before))
    return ref, played


def bake(name, a, mod, lat, played):
    """A bake of FRAMES at the render level (= LEVEL here) follows the plan over its frames
    too: no plan built, each baked frame the played result."""
    sc = bpy.context.scene
    size = T.lattice_size(a, lat)
    before = counters()
    smooth_ffd.bake_smooth_ffd(a, mod, FRAMES[0], FRAMES[-1])
    d = delta(before)
    T.check(f"{name}: bake follows the plan", d["built"] == 0 and d["followed"] >= len(FRAMES) - 1,
            str(d))
    for f in FRAMES:
        sc.frame_set(f)
        T.update()
        err = err_of(T.positions(evaluated(a)).astype(np.float64), played[f], size)
        status = smooth_ffd.status(mod)
        T.check(f"{name}: baked frame {f} is the played result",
                err <= TOL and status.startswith("Baked"),
                f"err {err:.1e} of the lattice size, {status[:40]}")
    smooth_ffd.clear_bake(a, mod)
    T.update()


def small_change(name, a, mod, ref, lat, change):
    """(c): a slight pose change on the same frame keeps the output topology."""
    size = T.lattice_size(a, lat)
    me = result_mesh(a, mod)
    tris0, pos0 = T.triangles(me), T.positions(me).copy()
    rest0 = T.point_attribute(me, meshio.REST_ATTRIBUTE).copy()
    before = counters()
    change()
    T.update()
    d = delta(before)
    exp, exp_tris, kept = ref.frame()
    me = result_mesh(a, mod)
    got, tris = T.positions(me).astype(np.float64), T.triangles(me)
    rest = T.point_attribute(me, meshio.REST_ATTRIBUTE)
    timing = pipeline.last_timing(a, mod)
    moved = float(np.abs(got - pos0).max()) / size
    err = err_of(got, exp, size)
    T.check(f"{name}: slight change: the core keeps the topology", kept is True, str(kept))
    T.check(f"{name}: slight change: followed, topology kept, no topology write",
            d["built"] == 0 and d["followed"] == 1 and d["kept"] == 1 and d["topology"] == 0
            and d["values"] >= 1 and not timing["rebuilt"] and timing["carry_ms"] == 0.0,
            f"{d}, rebuilt {timing['rebuilt']}, carry {timing['carry_ms']:.2f} ms")
    T.check(f"{name}: slight change: same triangles, positions moved as the core's",
            np.array_equal(tris, tris0) and np.array_equal(tris, exp_tris) and moved > 1e-6
            and err <= TOL, f"moved {moved:.1e}, err {err:.1e} of the lattice size")
    T.check(f"{name}: slight change: rest positions moved with the pose",
            float(np.abs(rest - rest0).max()) > 0.0)


def test_armature(triangles):
    T.clear()
    name = "armature, " + ("triangles" if triangles else "quads")
    rig = C.armature("rig")
    a = C.character_object(1, "A", rig)
    twin = C.character_object(1, "B", rig)
    if triangles:
        triangulate(a.data)
        triangulate(twin.data)
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, backend="cpu")
    ref, _played = play(name, a, twin, lat, mod, fresh=triangles)

    def turn():   # on the last frame, where play left both
        rig.animation_data_clear()
        rig.pose.bones["arm.L"].rotation_euler.y += 1e-3
    small_change(name, a, mod, ref, lat, turn)


def test_shape_keys():
    T.clear()
    a = T.make_mesh("suzanne", "A")
    triangulate(a.data)
    a.shape_key_add(name="Basis")
    swell = a.shape_key_add(name="Swell")
    co = T.positions(a.data)
    swell.data.foreach_set("co", (co * 1.15 + [0.0, 0.0, 0.1]).astype(np.float32).ravel())
    for f, v in ((FRAMES[0], 0.0), (FRAMES[-1], 1.0)):
        swell.value = v
        swell.keyframe_insert("value", frame=f)
    twin = T.link(bpy.data.objects.new("B", a.data.copy()))
    twin.location = a.location
    T.check("shape keys: the twin has the animated key",
            twin.data.shape_keys is not None and twin.data.shape_keys != a.data.shape_keys
            and twin.data.shape_keys.animation_data is not None)
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL,
                                    backend="cpu")
    ref, played = play("shape keys", a, twin, lat, mod, fresh=True)
    bake("shape keys", a, mod, lat, played)
    ref.frame()   # the bake left the scene on the last frame, where the reference is

    def nudge():
        for obj in (a, twin):
            obj.data.shape_keys.animation_data_clear()
            obj.data.shape_keys.key_blocks["Swell"].value -= 1e-4   # at 1: the slider's top
    small_change("shape keys", a, mod, ref, lat, nudge)


def test_moving_lattice():
    """The lattice moves and turns (as one parented to a bone), the object's mesh stays: the
    plan follows the lattice's new placement (the same basis)."""
    T.clear()
    a = T.make_mesh("suzanne", "A")
    triangulate(a.data)
    twin = T.link(bpy.data.objects.new("B", a.data.copy()))
    lat = C.lattice_around([a])
    for f, dx, rz in ((FRAMES[0], 0.0, 0.0), (FRAMES[-1], 0.08, 0.12)):
        lat.location.x += dx
        lat.rotation_euler.z = rz
        lat.keyframe_insert("location", frame=f)
        lat.keyframe_insert("rotation_euler", frame=f)
        lat.location.x -= dx
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, backend="cpu")
    play("moving lattice", a, twin, lat, mod, fresh=True)


def test_wave_and_displace():
    """A Wave (moving with time) and a Displace (no texture: every vertex along its normal by
    a keyframed strength) above Smooth FFD: the faces stay, the plan follows."""
    T.clear()
    a = T.make_mesh("suzanne", "A")
    triangulate(a.data)
    wave = a.modifiers.new("Wave", 'WAVE')
    wave.height, wave.width, wave.speed = 0.06, 0.6, 0.1
    disp = a.modifiers.new("Displace", 'DISPLACE')
    for f, v in ((FRAMES[0], 0.0), (FRAMES[-1], 0.2)):
        disp.strength = v
        disp.keyframe_insert("strength", frame=f)
    twin = T.link(a.copy())   # the same stack and animation, without Smooth FFD
    twin.data = a.data.copy()
    T.check("wave and displace: the twin has both modifiers, the strength animated",
            [m.type for m in twin.modifiers] == ['WAVE', 'DISPLACE']
            and twin.animation_data is not None and twin.animation_data.action is not None)
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, backend="cpu")
    T.check("wave and displace: Smooth FFD below them",
            [m.type for m in a.modifiers][:2] == ['WAVE', 'DISPLACE'] and a.modifiers[-1] == mod)
    play("wave and displace", a, twin, lat, mod, fresh=True)


FOX = os.path.join(T.ROOT, "tests", "data", "real", "fox.glb")


def test_imported_rig():
    """The fox as Blender's glTF importer brings it: a skinned mesh (576 triangles sharing no
    vertex) parented to an armature, with the file's three actions; the Walk action plays."""
    T.clear()
    fox, _rig, _walk = C.import_rigged(FOX)
    twin = C.rigged_copy(fox, "fox twin")
    lat = C.lattice_around([fox])
    mod = smooth_ffd.add_smooth_ffd(fox, lat, viewport_level=LEVEL, backend="cpu")
    bpy.context.scene.frame_set(FRAMES[0])
    p0 = T.positions(evaluated(twin)).copy()
    bpy.context.scene.frame_set(FRAMES[-1])
    moved = float(np.abs(T.positions(evaluated(twin)) - p0).max()) / T.lattice_size(fox, lat)
    T.check("imported rig: a skinned triangle soup that walks, Smooth FFD below the Armature",
            len(fox.data.polygons) == 576 and len(fox.data.vertices) == 1728
            and fox.modifiers[-1] == mod and moved > 1e-2,
            f"{len(fox.data.polygons)} faces, {len(fox.data.vertices)} vertices, moved {moved:.1e} "
            f"of the lattice size, modifiers {[m.type for m in fox.modifiers]}")
    play("imported rig", fox, twin, lat, mod, fresh=True)


def sharp_flags(me):
    """The result mesh's sharp-edge flags, per mesh edge."""
    if compat.HAS_SHARP_EDGE_ATTRIBUTE:
        attr = me.attributes.get("sharp_edge")
        flags = np.zeros(len(me.edges), dtype=bool)
        if attr is not None:
            attr.data.foreach_get("value", flags)
        return flags
    flags = np.zeros(len(me.edges), dtype=bool)
    me.edges.foreach_get("use_edge_sharp", flags)
    return flags


def play_holding(name, amplitude, subdivisions, boxed, check_frame):
    """The docs' character (`subdivisions`, its armature's angles times `amplitude`) in a
    lattice around it (boxed: around its whole animation) and its twin, played over FRAMES
    with live.playing() true (the follows hold the pieces, plans.hold_pieces; a background
    session plays nothing), the core's Deformer following the same poses with hold=True.
    check_frame(f, d, ref, kept, me, before) on each later frame: d the counters' change, kept
    the core's, me the result mesh, before its triangles on the frame before (its positions
    and triangles are checked against the core's here). Returns the counters' change over the
    follows."""
    T.clear()
    sc = bpy.context.scene
    rig = C.armature(name, amplitude=amplitude)
    a = C.character_object(subdivisions, "A", rig)
    twin = C.character_object(subdivisions, "B", rig)
    lat = C.lattice_around([a], frames=(FRAMES[0], FRAMES[-1])) if boxed else C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL, backend="cpu")
    size = T.lattice_size(a, lat)
    ref = Reference(a, twin, lat, hold=True)
    playing = live.playing
    live.playing = lambda: True
    try:
        sc.frame_set(FRAMES[0])
        T.update()
        ref.frame()
        start = counters()
        last_tris = T.triangles(result_mesh(a, mod))
        for f in FRAMES[1:]:
            before = counters()
            sc.frame_set(f)
            d = delta(before)
            exp, exp_tris, kept = ref.frame()
            me = result_mesh(a, mod)
            got, tris = T.positions(me).astype(np.float64), T.triangles(me)
            err = err_of(got, exp, size)
            T.check(f"{name}: frame {f}: the core's Deformer following with hold=True",
                    err <= TOL and np.array_equal(tris, exp_tris),
                    f"err {err:.1e} of the lattice size, {len(got)} vs {len(exp)} vertices")
            check_frame(f, d, ref, kept, me, last_tris)
            last_tris = tris
        return delta(start)
    finally:
        live.playing = playing


def test_held_pieces():
    """(d) Played in the viewport, the docs' character in a slight idle motion follows holding
    its pieces: every frame's positions and triangles are those of the core's Deformer
    following the same poses with hold=True, it holds on the frames the core holds (most of
    them), and those that keep the topology write none. (f) The character (5,760 quads) waving
    in a lattice that boxes the whole wave (bigger knot spans: the pieces hold on every frame):
    its sharp ends change as normals split or join with the pose, its triangles do not, so the
    result mesh keeps its topology and gets the new sharp edges only, the core's. (e) With
    motion blur, the character waving: frame 2's shutter subframes (1.75, 2, 2.25) rendered
    without render_pre get other topologies; after render_pre, the frame clips and its
    subframes hold those pieces: one topology, said in the status; a real Cycles render of
    frame 2 with motion blur shows one topology on every evaluation it makes. (g) The same
    with the render tessellation adaptive (Tolerance): the counts held over the shutter
    apply on every subframe."""
    sc = bpy.context.scene

    def idle(f, d, ref, kept, me, before):
        core_held = bool(ref.deformer.plan.pieces_held)
        T.check(f"held pieces: frame {f}: followed, held as the core held",
                d["built"] == 0 and d["followed"] == 1 and d["held"] == int(core_held)
                and d["kept"] == int(kept) and (d["topology"] == 0 if kept else True)
                and (np.array_equal(T.triangles(me), before) if kept else True),
                f"{d}, core held {core_held}, kept {kept}")

    d = play_holding("held pieces", 0.02, 1, False, idle)
    print(f"held pieces: playback held the pieces on {d['held']} of {len(FRAMES) - 1} follows; "
          f"kept the topology on {d['kept']}")
    T.check("held pieces: playback holds the pieces on most frames", d["held"] >= 3, str(d))

    def wave(f, d, ref, kept, me, before):
        want = result_arrays.edge_flags(compat.get_edges(me), ref.sharp_edges, len(me.vertices))
        T.check(f"held wave: frame {f}: the core's sharp edges, pieces held, no topology write",
                np.array_equal(sharp_flags(me), want) and d["held"] == 1 and d["topology"] == 0
                and d["values"] == 1,
                f"{int(sharp_flags(me).sum())} vs {int(want.sum())} sharp edges, {d}")

    d = play_holding("held wave", 1.0, 3, True, wave)
    print(f"held wave: {d['held']} of {d['followed']} follows held the pieces, {d['kept']} kept "
          f"the topology, {d['sharp']} wrote new sharp edges only")
    T.check("held wave: some frames changed only the sharp edges", d["sharp"] >= 1, str(d))
    # (e) motion blur, the character waving
    T.clear()
    rig = C.armature("rig")
    a = C.character_object(1, "A", rig)
    lat = C.lattice_around([a])
    mod = smooth_ffd.add_smooth_ffd(a, lat, viewport_level=LEVEL, render_level=LEVEL, backend="cpu")
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = 0.5
    subframes = ((1, 0.75), (2, 0.0), (2, 0.25))

    def shutter_topologies():
        tris = {}
        for f, s in subframes:
            sc.frame_set(f, subframe=s)
            smooth_ffd.update(a, render=True)
            tris[f + s] = T.triangles(result_mesh(a, mod)).copy()
        return tris

    T.tiny_cycles()
    seen, texts = [], []

    def probe(scene):     # the render's evaluations of the frame and its subframes
        seen.append((round(scene.frame_current + scene.frame_subframe, 3),
                     len(result_mesh(a, mod).polygons)))
        texts.append(smooth_ffd.status(mod))

    def over_the_shutter(what, note, every, during=None):
        """Frame 2's subframes by hand without render_pre (their topologies differ), then
        after it (the frame first, as Cycles evaluates): one topology, `note` in the status;
        then a real Cycles render of frame 2 with motion blur: one topology on every
        evaluation it makes, `note` in the status of every one (every) or of some (the
        frame's own first evaluation clips)."""
        nonlocal subframes
        subframes = ((1, 0.75), (2, 0.0), (2, 0.25))
        free = shutter_topologies()
        sizes = {t: len(x) for t, x in free.items()}
        T.check(f"{what}motion blur, shutter unknown: the subframes' topologies differ",
                not all(np.array_equal(free[1.75], x) for x in free.values()), str(sizes))
        sc.frame_set(2)
        handlers.on_render_pre(sc)
        try:
            if during is not None:
                during()
            subframes = ((2, 0.0), (1, 0.75), (2, 0.25))
            held_tris = shutter_topologies()
            first = held_tris[2.0]
            T.check(f"{what}motion blur: one topology over the shutter",
                    all(np.array_equal(first, x) for x in held_tris.values()),
                    f"{ {t: len(x) for t, x in held_tris.items()} } (unheld {sizes})")
            T.check(f"{what}motion blur: the status says it", note in smooth_ffd.status(mod),
                    smooth_ffd.status(mod))
        finally:
            handlers.on_render_done(sc)
        T.check(f"{what}after the render: no shutter known", state.flags.render_shutter is None)
        seen.clear()
        texts.clear()
        T.render_evaluations(2, probe)
        times = sorted({t for t, _ in seen})
        said = [note in t for t in texts]
        T.check(f"{what}Cycles render with motion blur: one topology on every subframe it evaluates",
                len(times) >= 2 and len({n for _, n in seen}) == 1
                and (all(said) if every else any(said)),
                f"{seen}; {texts[-1] if texts else None}")

    over_the_shutter("", "pieces held over the shutter 1.75-2.25", False)
    # (g) The same with an adaptive render tessellation: render_pre takes the counts over the
    # shutter from the frame's pieces held on every subframe, and they apply to each.
    compat.set_modifier_input(mod, "Render Tessellation", "Tolerance")
    compat.set_modifier_input(mod, "Render Tolerance", 0.01)

    def counts_held():
        st = objects.state_of(a, mod)
        T.check("adaptive, render_pre: counts held over the moving input's shutter",
                st.shutter is not None and st.shutter[0] == (1.75, 2.25),
                f"{None if st.shutter is None else st.shutter[0]} {smooth_ffd.status(mod)}")

    over_the_shutter("adaptive, ", "counts held over the shutter 1.75-2.25", True, counts_held)
    sc.render.use_motion_blur = False


def main():
    T.setup()
    T.run("armature, quads", test_armature, False)
    T.run("armature, triangles", test_armature, True)
    T.run("shape keys", test_shape_keys)
    T.run("moving lattice", test_moving_lattice)
    T.run("wave and displace", test_wave_and_displace)
    T.run("imported rig", test_imported_rig)
    T.run("held pieces", test_held_pieces)
    T.finish()


main()
