"""Playback of a rigged character: Armature + Smooth FFD at viewport level 3
against Armature + Lattice + Subdivision Surface at the same density, in the same run. Prints
frames per second, asserts nothing.

Smooth FFD runs as shipped (its plan follows each new pose, plans.follow) and, on a second
object, with a new plan every frame (following turned off for that object only): what
following saves.

    blender -b --factory-startup --python blender_scenes/bench_playback.py [-- ROUNDS [CHARACTER [MODE [AMPLITUDE]]]]
    ~/.cache/smoothffd/venv-bpy-5.0/bin/python blender_scenes/bench_playback.py [ROUNDS [CHARACTER [MODE [AMPLITUDE]]]]

CHARACTER: a number, the docs' character at that many subdivisions (default 3), or the path of
a rigged glTF or FBX file (e.g. tests/data/real/fox.glb), imported with Blender's own importer
at its defaults, as a user would: its first skinned mesh plays its Walk action (else its
active one) over the action's frames, Smooth FFD below its Armature modifier.

MODE "window" (default): the add-on runs as while a window plays the animation (live editing
on: positions only on 4.5+, Blender's own normals as always on 3.4-4.4; no fit error bound),
what an artist sees. "background": as a script or farm evaluates frames (exact normals on
4.5+ and the fit error bound each frame, an estimate costing more than the frame itself).
AMPLITUDE scales the docs' character's angles (default 1, the wave: its arms swing up to 0.7
rad; 0.02, a slight idle motion). The last lines say how many follows held the pieces (in
"window" mode, as during playback: plans.hold_pieces), how many kept the output topology
(values written only) and how many wrote a new one (some face crossing the lattice's knot
planes differently than on the frame before, or a piece held past its box).

The docs' character (blender_scenes/character.py, 3 subdivisions: 5,760 quads) waves over
frames 1-6; a 4x4x4 B-spline lattice boxes it (an imported one too, over its action's frames). Playback = scene.frame_set(f) for f = 1..6, then the
evaluated mesh read (Blender 4.x/5.x evaluate a final Subdivision Surface when the mesh is
first accessed, so that counts for both stacks). The two stacks run on two objects, one shown
(hide_viewport) at a time, interleaved round by round so that both see the same machine load;
each round's first frame (the switch) is not timed. Smooth FFD runs with its handlers, as in
the viewport (CPU backend; 3.4-4.4 shade the dense result from its geometry, 4.5+ writes exact
normals). The Subdivision Surface level is the one whose triangle count is closest to Smooth
FFD's; the other level is timed too.
"""
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "python"), HERE]
import smooth_ffd  # noqa: E402
from smooth_ffd import live, objects as sffd_objects, pipeline, plans, state  # noqa: E402
import character as C  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


ARGS = argv()
ROUNDS = int(ARGS[0]) if ARGS else 5
CHARACTER = ARGS[1] if len(ARGS) > 1 else "3"
MODE = ARGS[2] if len(ARGS) > 2 else "window"
AMPLITUDE = float(ARGS[3]) if len(ARGS) > 3 else 1.0
LEVEL = 3
FRAMES = list(range(C.FRAMES[0], C.FRAMES[1] + 1))


def docs_character():
    """(make(name) -> a new rigged copy, description) for the docs' character."""
    subdivisions = int(CHARACTER)
    rig = C.armature("rig", AMPLITUDE)

    def make(name):
        return C.character_object(subdivisions, name, rig)
    return make, lambda obj: f"the docs' character, {len(obj.data.polygons)} quads, armature 3 bones"


def imported_character(path):
    """(make, describe) for a rigged file through Blender's importer (character.import_rigged);
    sets FRAMES to the frames of the action it plays."""
    global FRAMES
    try:
        first, rig, act = C.import_rigged(path)
    except ValueError as exc:
        sys.exit(f"bench_playback: {exc}")
    lo, hi = act.frame_range
    FRAMES = list(range(int(lo), int(hi) + 1))
    first.hide_viewport = True   # the imported object stays hidden; copies of it play

    def make(name):
        return C.rigged_copy(first, name)
    bones = len(rig.data.bones)
    return make, lambda obj: (f"{os.path.basename(path)} imported, {len(obj.data.polygons)} faces "
                              f"({len(obj.data.vertices)} vertices), armature {bones} bones, "
                              f"action {act.name}")


def triangles(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    me = obj.evaluated_get(dg).data
    return len(me.loops) - 2 * len(me.polygons)


def show_only(obj, objects):
    for o in objects:
        o.hide_viewport = o is not obj
    bpy.context.view_layer.update()


def play(obj, sc):
    """ms per frame for one pass over FRAMES (the first frame, a switch, untimed)."""
    out = []
    sc.frame_set(FRAMES[-1])
    for f in FRAMES:
        t = time.perf_counter()
        sc.frame_set(f)
        len(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices)
        out.append(1e3 * (time.perf_counter() - t))
    return out


def replanning(obj, mod):
    """Turns plan following off for one modifier (every new pose builds a new plan)."""
    follow = plans.follow

    def no_follow(st, *args):
        return False if st is sffd_objects.state_of(obj, mod) else follow(st, *args)
    plans.follow = no_follow


def main():
    smooth_ffd.register()
    if MODE == "window":   # as while a window plays (live.py)
        state.LIVE = True
        live.playing = lambda: True
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    sc = bpy.context.scene
    if CHARACTER.isdigit():
        make, describe = docs_character()
    else:
        make, describe = imported_character(os.path.abspath(CHARACTER))
    sffd = make("smooth_ffd")
    lat = C.lattice_around([sffd], frames=(FRAMES[0], FRAMES[-1]))
    mod = smooth_ffd.add_smooth_ffd(sffd, lat, viewport_level=LEVEL, backend="cpu")
    replan = make("smooth_ffd_replan")
    replan_mod = smooth_ffd.add_smooth_ffd(replan, lat, viewport_level=LEVEL, backend="cpu")
    replanning(replan, replan_mod)
    subs = {}
    for level in (1, 2):
        obj = make(f"subsurf{level}")
        obj.modifiers.new("Lattice", 'LATTICE').object = lat
        obj.modifiers.new("Subsurf", 'SUBSURF').levels = level
        subs[level] = obj
    objects = [sffd, replan] + list(subs.values())
    counts = {}
    for obj in objects:
        show_only(obj, objects)
        sc.frame_set(FRAMES[0])
        counts[obj.name] = triangles(obj)
    target = counts["smooth_ffd"]
    closest = min(subs, key=lambda lv: abs(counts[f"subsurf{lv}"] - target))
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs; {describe(sffd)}, lattice 4x4x4 B-spline, frames "
          f"{FRAMES[0]}-{FRAMES[-1]}, {ROUNDS} rounds interleaved, mode {MODE}, amplitude {AMPLITUDE:g}; load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    times = {o.name: [] for o in objects}
    reads0 = dict(state.stack_counters)
    timings = []
    follow = [0] * 6
    for r in range(ROUNDS):
        for obj in objects:
            show_only(obj, objects)
            was = (state.plans_built[0], state.plans_followed[0], state.plans_followed_kept[0],
                   state.mesh_writes["topology"], state.mesh_writes["values"],
                   state.plans_followed_held[0])
            ms = play(obj, sc)
            times[obj.name] += ms[1:]
            if obj is sffd:
                timings.append(pipeline.last_timing(sffd, mod))
                now = (state.plans_built[0], state.plans_followed[0],
                       state.plans_followed_kept[0], state.mesh_writes["topology"],
                       state.mesh_writes["values"], state.plans_followed_held[0])
                follow = [f + n - w for f, n, w in zip(follow, now, was)]
    reads = {k: state.stack_counters[k] - reads0[k] for k in reads0}
    frames_sffd = ROUNDS * (len(FRAMES) - 1)
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"median ms per frame over {frames_sffd} frames each")
    print(f"{'':34s} {'triangles':>10s} {'ms/frame':>9s} {'fps':>6s}")
    rows = [("Armature + Smooth FFD level 3", "smooth_ffd"),
            ("  the same, a new plan every frame", "smooth_ffd_replan")] + \
        [(f"Armature + Lattice + Subsurf {lv}" + (" (closest)" if lv == closest else ""),
          f"subsurf{lv}") for lv in subs]
    med = {}
    for label, name in rows:
        m = float(np.median(times[name]))
        med[name] = m
        print(f"{label:34s} {counts[name]:10d} {m:9.1f} {1e3 / m:6.1f}   "
              f"(min {min(times[name]):.1f}, max {max(times[name]):.1f})")
    lt = [t for t in timings if t]
    split = {k: float(np.median([t[k] for t in lt])) for k in
             ("deform_ms", "write_ms", "mesh_write_ms", "carry_ms", "normals_ms")} if lt else {}
    print(f"Smooth FFD per frame (median of the rounds' last frames): plan + deform "
          f"{split.get('deform_ms', 0):.1f} ms, write {split.get('write_ms', 0):.1f} ms "
          f"(mesh {split.get('mesh_write_ms', 0):.1f}, carry {split.get('carry_ms', 0):.1f}, "
          f"normals {split.get('normals_ms', 0):.1f}); stack readings {reads['reads']} for "
          f"{2 * (frames_sffd + ROUNDS)} frames shown (both Smooth FFD objects), forced "
          f"evaluations {reads['forced']}, deferred {reads['deferred']}")
    print(f"Smooth FFD (following) over {frames_sffd + ROUNDS} frames: plans built {follow[0]}, "
          f"followed {follow[1]} (pieces held {follow[5]}, topology kept {follow[2]}), result mesh "
          f"written: topology {follow[3]}, values only {follow[4]}")
    m0, m1 = med[f"subsurf{closest}"], med["smooth_ffd"]
    print(f"fps Smooth FFD following / a new plan every frame: "
          f"{med['smooth_ffd_replan'] / m1:.2f}x")
    print(f"fps Smooth FFD / Lattice + Subsurf {closest}: {m0 / m1:.2f}x "
          f"({1e3 / m1:.1f} vs {1e3 / m0:.1f} fps; triangles {target} vs "
          f"{counts[f'subsurf{closest}']})")
    sys.stdout.flush()


main()
if not bpy.app.binary_path:   # bpy 4.5 can hang in exit() (tests/blender/sffd_testlib.py)
    os._exit(0)
