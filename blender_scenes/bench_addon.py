"""Timing of one live update (a lattice point moved) on a 46.8k-triangle sphere: Smooth FFD at
viewport levels 4 and 10 beside Blender's Lattice + Subdivision Surface at the same density
(levels 2 and 3), in the same run. Prints, asserts nothing.

    blender -b --factory-startup --python blender_scenes/bench_addon.py [-- REPEATS [ab] [noexact]]
    ~/.cache/smoothffd/venv-bpy-5.0/bin/python blender_scenes/bench_addon.py [REPEATS [ab] [noexact]]

Each row splits its median update into where the time went, from marker handlers placed
first and last in depsgraph_update_pre/post: "pre" (Smooth FFD's work in
depsgraph_update_pre), "eval1" (Blender's evaluation before depsgraph_update_post), "post"
(Smooth FFD's work in depsgraph_update_post) and "eval2" (the second evaluation Blender runs
when a post handler tagged something, plus reading the mesh); inside the Smooth FFD work:
deform (core), mesh write, normals.
"""
import os
import sys
import time

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The add-on and the core from the source tree (a development build: scripts/build.sh).
sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "python")]
import smooth_ffd  # noqa: E402
from smooth_ffd import compat, handlers, modifier_update  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


REPEATS = int(argv()[0]) if argv() else 5
# "ab": Smooth FFD rows also without the add-on's depsgraph_update_pre handler, interleaved.
AB = "ab" in argv()[1:]
# "noexact": skip the exact-normals rows on 3.4-4.0 (minutes at level 10; the tests use it).
NO_EXACT = "noexact" in argv()[1:]


def sphere(name):
    """UV sphere 180 x 131, triangulated: 2 * 180 * 130 = 46,800 triangles, smooth."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=180, v_segments=131, radius=1.0)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def lattice():
    lt = bpy.data.lattices.new("lat")
    lt.points_u = lt.points_v = lt.points_w = 5   # the paper's 5x5x5 control points
    obj = bpy.data.objects.new("lat", lt)
    obj.scale = (2.4, 2.4, 2.4)
    bpy.context.scene.collection.objects.link(obj)
    rng = np.random.default_rng(1)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-0.03, 0.03, 3)
    return obj


def only_visible(obj):
    """Hidden objects are not evaluated, so each timing sees one object's work."""
    for o in bpy.context.scene.objects:
        if o.type == 'MESH':
            o.hide_viewport = o is not obj


_marks = []


def _mark(name):
    def handler(*_args):
        _marks.append((name, time.perf_counter()))
    handler.__name__ = f"bench_mark_{name}"
    return handler


_MARKERS = (("depsgraph_update_pre", 0, _mark("pre_begin")),
            ("depsgraph_update_pre", None, _mark("pre_end")),
            ("depsgraph_update_post", 0, _mark("post_begin")),
            ("depsgraph_update_post", None, _mark("post_end")))


def _install_markers():
    """Markers first and last in the handler lists (after the add-on registered its own)."""
    for name, index, fn in _MARKERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
        if index is None:
            lst.append(fn)
        else:
            lst.insert(index, fn)


def _phases(t0, t_end):
    """ms per phase of one update from the markers (first pre/post call of the update)."""
    first = {}
    for name, t in _marks:
        first.setdefault(name, t)
    pre_b, pre_e = first.get("pre_begin", t0), first.get("pre_end", t0)
    post_b, post_e = first.get("post_begin", t_end), first.get("post_end", t_end)
    return {"pre": pre_e - pre_b, "eval1": post_b - pre_e, "post": post_e - post_b,
            "eval2": t_end - post_e}


def _set_early(on):
    """Installs or removes the add-on's depsgraph_update_pre handler (A/B runs only)."""
    lst = bpy.app.handlers.depsgraph_update_pre
    fn = handlers.on_depsgraph_update_pre
    if on and fn not in lst:
        lst.append(fn)
    elif not on and fn in lst:
        lst.remove(fn)


def time_edit(lat, obj, repeats, mod=None, early_modes=(True,)):
    """{early: (median ms, split)}: ms from moving one lattice point to the evaluated mesh
    being ready, and the median of each phase (see the module docstring) and of Smooth
    FFD's own timings. With early_modes=(True, False) the updates alternate between the
    add-on as shipped and the add-on without its depsgraph_update_pre handler (interleaved,
    so that both see the same machine load).

    Blender 4.x/5.x evaluate a final Subdivision Surface lazily, when the mesh is first
    accessed, so the timing includes that access (len(vertices)) for both stacks."""
    samples = {e: ([], [], []) for e in early_modes}
    p = lat.data.points[62]
    for i in range(repeats):
        for early in early_modes:
            _set_early(early)
            _install_markers()
            times, phases, own = samples[early]
            p.co_deform.z += 0.01 * (1 if i % 2 == 0 else -1)
            _marks.clear()
            t = time.perf_counter()
            bpy.context.view_layer.update()
            dg = bpy.context.evaluated_depsgraph_get()
            len(obj.evaluated_get(dg).data.vertices)
            t_end = time.perf_counter()
            times.append(1e3 * (t_end - t))
            phases.append({k: 1e3 * v for k, v in _phases(t, t_end).items()})
            lt = modifier_update.last_timing(obj, mod) if mod is not None else None
            if lt:
                own.append(lt)
    _set_early(True)
    med = lambda xs: float(np.median(xs)) if xs else 0.0
    out = {}
    for early, (times, phases, own) in samples.items():
        split = {k: med([ph[k] for ph in phases]) for k in phases[0]}
        for k in ("deform_ms", "mesh_write_ms", "normals_ms"):
            split[k] = med([lt.get(k, 0.0) for lt in own])
        split["core_ms"] = med([lt.get("stats", {}).get("deform_ms", 0.0) for lt in own])
        split["normals_path"] = own[-1].get("normals") if own else None
        split["device"] = own[-1].get("stats", {}).get("device") if own else None
        out[early] = (med(times), split)
    return out


def _phase_text(split):
    return (f"pre {split['pre']:.0f} + eval1 {split['eval1']:.0f} + post {split['post']:.0f}"
            f" + eval2 {split['eval2']:.0f}")


def evaluated_tris(obj):
    """Triangles of the evaluated mesh (Subdivision Surface makes quads: 2 each)."""
    dg = bpy.context.evaluated_depsgraph_get()
    me = obj.evaluated_get(dg).data
    return len(me.loops) - 2 * len(me.polygons)


def main():
    smooth_ffd.register()
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    lat = lattice()
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs; sphere 46,800 triangles, "
          f"lattice 5x5x5 B-spline; one live update = move a lattice point + depsgraph update; "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    rows = []
    for level in (2, 3):
        ref = sphere(f"stack{level}")
        ref.modifiers.new("Lattice", 'LATTICE').object = lat
        ref.modifiers.new("Subsurf", 'SUBSURF').levels = level
        only_visible(ref)
        bpy.context.view_layer.update()
        ms, split = time_edit(lat, ref, REPEATS)[True]
        rows.append((f"Lattice + Subsurf level {level}", evaluated_tris(ref), ms, _phase_text(split)))
        bpy.data.objects.remove(ref)

    # 3.4-4.0: viewport mode (normals from the geometry) and exact normals; 4.1+: exact only.
    modes = [False] if compat.HAS_CORNER_NORMALS or NO_EXACT else [False, True]
    for exact in modes:
        for level in (4, 10):
            obj = sphere(f"sffd{level}")
            only_visible(obj)
            t = time.perf_counter()
            mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=level,
                                            backend="cpu")
            compat.set_modifier_input(mod, "Exact Normals", exact)
            obj.update_tag()
            bpy.context.view_layer.update()
            first = 1e3 * (time.perf_counter() - t)
            timed = time_edit(lat, obj, REPEATS, mod, (True, False) if AB else (True,))
            for early, (ms, split) in timed.items():
                detail = (f"{_phase_text(split)}; deform {split['deform_ms']:.0f} (core "
                          f"{split['core_ms']:.0f}), mesh write {split['mesh_write_ms']:.0f}, "
                          f"normals {split['normals_ms']:.0f} [{split['normals_path']}]; first "
                          f"update (plan) {first:.0f} ms, device {split['device']}")
                name = f"Smooth FFD level {level}" + (" exact normals" if exact else "") + \
                    ("" if early else " no pre")
                rows.append((name, evaluated_tris(obj), ms, detail))
            smooth_ffd.remove_smooth_ffd(obj, mod)
            bpy.data.objects.remove(obj)
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
          f"median of {REPEATS} updates; phases in ms (medians, so they need not add up)")
    print(f"{'':34s} {'triangles':>10s} {'update ms':>10s} {'ns/tri':>7s}")
    for name, tris, ms, detail in rows:
        print(f"{name:34s} {tris:10d} {ms:10.0f} {1e6 * ms / tris:7.0f}   {detail}")
    # The comparison: viewport level 4 vs Subsurf level 2, level 10 vs level 3.
    by_name = {name: (tris, ms) for name, tris, ms, _ in rows}
    for level, sub in ((4, 2), (10, 3)):
        (t1, m1), (t0, m0) = by_name[f"Smooth FFD level {level}"], by_name[f"Lattice + Subsurf level {sub}"]
        print(f"speedup level {level} vs Lattice + Subsurf level {sub}: {m0 / m1:.2f}x in time, "
              f"{(m0 / t0) / (m1 / t1):.2f}x per triangle")
    sys.stdout.flush()


main()
