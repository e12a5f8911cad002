"""Cost of carrying vertex groups and extra UV maps onto the result (carry.py), on the
46.8k-triangle sphere at level 4, quads (UV sphere as made) and triangulated. Prints, asserts
nothing.

    blender -b --factory-startup --python blender_scenes/bench_carry.py [-- REPEATS]
    build/venv-bpy/bin/python blender_scenes/bench_carry.py [REPEATS]

Per case: the first update (plan + write), the carry part of it, a lattice edit (must not
carry again), an edit of one weight (carry only, same plan), reading the source, and Apply.
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
from smooth_ffd import meshio, pipeline  # noqa: E402



def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


def lattice():
    """5x5x5 B-spline lattice around the sphere, slightly jittered (as bench_addon.py)."""
    lt = bpy.data.lattices.new("lat")
    lt.points_u = lt.points_v = lt.points_w = 5
    obj = bpy.data.objects.new("lat", lt)
    obj.scale = (2.4, 2.4, 2.4)
    bpy.context.scene.collection.objects.link(obj)
    rng = np.random.default_rng(1)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-0.03, 0.03, 3)
    return obj


def only_visible(obj):
    for o in bpy.context.scene.objects:
        if o.type == 'MESH':
            o.hide_viewport = o is not obj


def time_edit(lat, obj, repeats):
    """ms from moving one lattice point to the evaluated mesh being ready (median)."""
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


REPEATS = int(argv()[0]) if argv() else 3
LEVEL = 4


def sphere(name, triangulate):
    """UV sphere 180 x 131: 46,800 triangles (23,220 quads + 360 triangles, or triangulated)."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")   # calc_uvs fills an existing layer
    bmesh.ops.create_uvsphere(bm, u_segments=180, v_segments=131, radius=1.0, calc_uvs=True)
    if triangulate:
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_data(obj):
    """Two groups with smooth gradients (every weight distinct: the worst case for
    VertexGroup.add's one weight per call), one on half the sphere; a second UV map."""
    me = obj.data
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    full = obj.vertex_groups.new(name="full")
    half = obj.vertex_groups.new(name="half")
    for i, (x, y, z) in enumerate(co):
        full.add([i], float(0.5 + 0.5 * z), 'REPLACE')
        if x > 0:
            half.add([i], float(x), 'REPLACE')
    uv = me.uv_layers.new(name="second")
    rng = np.random.default_rng(0)
    uv.data.foreach_set("uv", rng.uniform(0, 1, len(me.loops) * 2).astype(np.float32))
    me.update()


def run_case(lat, triangulate, with_data):
    obj = sphere("s", triangulate)
    if with_data:
        add_data(obj)
    only_visible(obj)
    names = [g.name for g in obj.vertex_groups]
    t = time.perf_counter()
    src = meshio.SourceMesh(obj.data, None, False, names)
    read_ms = 1e3 * (time.perf_counter() - t)
    t = time.perf_counter()
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=LEVEL, render_level=LEVEL)
    bpy.context.view_layer.update()
    first = 1e3 * (time.perf_counter() - t)
    lt = dict(pipeline.last_timing(obj, mod) or {})
    edit = time_edit(lat, obj, REPEATS)
    le = pipeline.last_timing(obj, mod) or {}
    weight_ms = None
    if with_data:
        obj.vertex_groups["full"].add([5], 0.123, 'REPLACE')
        obj.data.update()
        t = time.perf_counter()
        bpy.context.view_layer.update()
        weight_ms = 1e3 * (time.perf_counter() - t)
        lw = pipeline.last_timing(obj, mod) or {}
    t = time.perf_counter()
    smooth_ffd.apply_smooth_ffd(obj, mod)
    apply_ms = 1e3 * (time.perf_counter() - t)
    kind = "triangulated" if triangulate else "quads"
    print(f"{kind:12s} {'groups+2 UV' if with_data else 'no groups, 1 UV':16s} "
          f"out {lt.get('triangles', 0):7d} tris; source read {read_ms:6.1f} ms; first update "
          f"{first:7.0f} ms (carry {lt.get('carry_ms', 0):6.0f} ms, "
          f"{lt.get('carry_add_calls', 0)} VertexGroup.add calls); lattice edit {edit:5.0f} ms "
          f"(carry {le.get('carry_ms', 0):.0f} ms)"
          + (f"; weight edit {weight_ms:5.0f} ms (carry {lw.get('carry_ms', 0):.0f}, "
             f"rebuilt {lw.get('rebuilt')})" if weight_ms is not None else "")
          + f"; Apply {apply_ms:6.0f} ms")
    sys.stdout.flush()
    bpy.data.objects.remove(obj)


def main():
    smooth_ffd.register()
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)
    lat = lattice()
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs; sphere 46,800 triangles, "
          f"level {LEVEL}, lattice 5x5x5 B-spline")
    for triangulate in (False, True):
        for with_data in (False, True):
            run_case(lat, triangulate, with_data)


main()
