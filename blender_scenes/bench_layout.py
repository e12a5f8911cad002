"""The core's two output layouts in the add-on, update by update in one run: "compact" (a normal
per render vertex: written per vertex where nothing splits, else gathered per corner through
render_triangles), "corners" (a normal per triangle corner from the core), and the add-on's
own choice per plan (plans.layout). Prints, asserts nothing.

    blender -b --factory-startup --python blender_scenes/bench_layout.py [-- REPEATS]
    ~/.cache/smoothffd/venv-bpy-5.0/bin/python blender_scenes/bench_layout.py [REPEATS]

Scenes: the 46.8k-triangle sphere of bench_addon.py (smooth: nothing splits) and the same
sphere with two meridians (the great circle y = 0) marked sharp (its normals split there), exact normals (the
Exact Normals option on 3.4-4.4, where exact normals are slow: level 4 only there; 4.5+
writes them on every update: levels 4 and 10). One update = move a lattice point until the
evaluated mesh is ready; the layouts alternate update by update (state.LAYOUT), so
both see the same machine load. Per row: median update, the core's deform, the normals
write (with the gather, where there is one) and the path used.
"""
import os
import sys
import time

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "python")]
import smooth_ffd  # noqa: E402
from smooth_ffd import compat, objects, pipeline, plans, state  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


REPEATS = int(argv()[0]) if argv() else 5
LAYOUTS = ("corners", "compact", None)   # None: the add-on's choice (plans.layout)


def sphere(name, sharp=False):
    """UV sphere 180 x 131, triangulated (46,800 triangles), smooth; sharp=True marks the
    edges of the great circle y = 0 (two meridians) sharp."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=180, v_segments=131, radius=1.0)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    if sharp:
        for e in bm.edges:
            if all(abs(v.co.y) < 1e-5 for v in e.verts):
                e.smooth = False
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    if not compat.HAS_CORNER_NORMALS:
        me.use_auto_smooth = True   # 3.4-4.0: sharp edges count only with auto smooth
        me.auto_smooth_angle = np.pi
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def lattice():
    lt = bpy.data.lattices.new("lat")
    lt.points_u = lt.points_v = lt.points_w = 5
    obj = bpy.data.objects.new("lat", lt)
    obj.scale = (2.4, 2.4, 2.4)
    bpy.context.scene.collection.objects.link(obj)
    rng = np.random.default_rng(1)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-0.03, 0.03, 3)
    return obj


def run(lat, obj, mod):
    """{layout: [(update ms, timing dict)]}, the layouts alternating update by update."""
    out = {layout: [] for layout in LAYOUTS}
    p = lat.data.points[62]
    for i in range(REPEATS + 1):          # the first round warms both layouts up
        for layout in LAYOUTS:
            state.LAYOUT = layout   # None: the add-on's own choice
            p.co_deform.z += 0.01 * (1 if i % 2 == 0 else -1)
            t = time.perf_counter()
            bpy.context.view_layer.update()
            dg = bpy.context.evaluated_depsgraph_get()
            len(obj.evaluated_get(dg).data.vertices)
            ms = 1e3 * (time.perf_counter() - t)
            if i:
                out[layout].append((ms, dict(pipeline.last_timing(obj, mod))))
    state.LAYOUT = None
    return out


def main():
    smooth_ffd.register()
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    lat = lattice()
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs, load average "
          f"{' '.join(f'{x:.2f}' for x in os.getloadavg())}; 46,800-triangle sphere, 5x5x5 "
          f"B-spline lattice, CPU backend, exact normals; median of {REPEATS} updates a row")
    levels = (4, 10) if compat.CHEAP_EXACT_NORMALS else (4,)
    med = lambda xs: float(np.median(xs))
    for sharp in (False, True):
        for level in levels:
            obj = sphere("s", sharp)
            mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=level,
                                            backend="cpu")
            compat.set_modifier_input(mod, "Exact Normals", True)
            obj.update_tag()
            bpy.context.view_layer.update()
            res = objects.state_of(obj, mod).result
            got = run(lat, obj, mod)
            rv = objects.state_of(obj, mod).deformer.plan.render_vertices()[0]
            scene = "sharp meridians" if sharp else "smooth"
            chosen = plans.layout(objects.state_of(obj, mod).deformer)
            print(f"{scene}, level {level}: {len(res.triangles)} triangles, "
                  f"{len(res.positions)} vertices, {len(rv)} render vertices")
            for layout in LAYOUTS:
                rows = got[layout]
                name = layout or f"add-on ({chosen})"
                print(f"  {name:18s} update {med([r[0] for r in rows]):8.1f} ms  "
                      f"deform {med([r[1]['deform_ms'] for r in rows]):7.1f}  "
                      f"(core {med([r[1]['stats']['deform_ms'] for r in rows]):7.1f})  "
                      f"normals {med([r[1]['normals_ms'] for r in rows]):7.1f} "
                      f"[{rows[-1][1]['normals']}]  mesh write "
                      f"{med([r[1]['mesh_write_ms'] for r in rows]):5.1f}")
            sys.stdout.flush()
            smooth_ffd.remove_smooth_ffd(obj, mod)
            bpy.data.objects.remove(obj)


main()
