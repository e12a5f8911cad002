"""Timing of one live update (a lattice point moved) on a 46.8k-triangle sphere: Smooth FFD at
viewport levels 4 and 10 beside Blender's Lattice + Subdivision Surface at the same density
(levels 2 and 3), in the same run. Prints, asserts nothing.

    blender -b --factory-startup --python blender_scenes/bench_addon.py [-- REPEATS]
    build/venv-bpy/bin/python blender_scenes/bench_addon.py [REPEATS]
"""
import os
import sys
import time

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "addon"))
import smooth_ffd  # noqa: E402
from smooth_ffd import compat, engine  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


REPEATS = int(argv()[0]) if argv() else 3


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


def time_edit(lat, obj, repeats):
    """ms from moving one lattice point to the evaluated mesh being ready (median).

    Blender 4.x/5.x evaluate a final Subdivision Surface lazily, when the mesh is first
    accessed, so the timing includes that access (len(vertices)) for both stacks."""
    times = []
    p = lat.data.points[62]
    for i in range(repeats):
        p.co_deform.z += 0.01 * (1 if i % 2 == 0 else -1)
        t = time.perf_counter()
        bpy.context.view_layer.update()
        dg = bpy.context.evaluated_depsgraph_get()
        len(obj.evaluated_get(dg).data.vertices)
        times.append(1e3 * (time.perf_counter() - t))
    return float(np.median(times))


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
          f"lattice 5x5x5 B-spline; one live update = move a lattice point + depsgraph update")
    rows = []
    for level in (2, 3):
        ref = sphere(f"stack{level}")
        ref.modifiers.new("Lattice", 'LATTICE').object = lat
        ref.modifiers.new("Subsurf", 'SUBSURF').levels = level
        only_visible(ref)
        bpy.context.view_layer.update()
        ms = time_edit(lat, ref, REPEATS)
        rows.append((f"Lattice + Subsurf level {level}", evaluated_tris(ref), ms, ""))
        bpy.data.objects.remove(ref)

    modes = [False] if compat.HAS_CORNER_NORMALS else [False, True]   # 3.4-4.0: fast + exact
    for exact in modes:
        for level in (4, 10):
            obj = sphere(f"sffd{level}")
            only_visible(obj)
            t = time.perf_counter()
            mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=level)
            compat.set_modifier_input(mod, "Exact Normals", exact)
            obj.update_tag()
            bpy.context.view_layer.update()
            first = 1e3 * (time.perf_counter() - t)
            ms = time_edit(lat, obj, REPEATS)
            lt = engine.last_timing(obj, mod) or {}
            st = lt.get("stats", {})
            detail = (f"deform {lt.get('deform_ms', 0):.0f} (core {st.get('deform_ms', 0):.0f}) + "
                      f"mesh write {lt.get('mesh_write_ms', 0):.0f} + normals "
                      f"{lt.get('normals_ms', 0):.0f} [{lt.get('normals')}] + tag "
                      f"{lt.get('tag_ms', 0):.0f}; first update (plan) {first:.0f} ms, "
                      f"device {st.get('device')}")
            name = f"Smooth FFD level {level}" + (" exact normals" if exact else "")
            rows.append((name, evaluated_tris(obj), ms, detail))
            smooth_ffd.remove_smooth_ffd(obj, mod)
            bpy.data.objects.remove(obj)
    print(f"{'':34s} {'triangles':>10s} {'update ms':>10s}")
    for name, tris, ms, detail in rows:
        print(f"{name:34s} {tris:10d} {ms:10.0f}   {detail}")
    sys.stdout.flush()


main()
