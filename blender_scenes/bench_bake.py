"""Cost of the bake (bake.py) and of the frame ranges (nodegroup) on the 46.8k-triangle
sphere (triangulated UV sphere, 5x5x5 B-spline lattice whose middle point moves every frame).
Prints, asserts nothing.

    blender -b --factory-startup --python blender_scenes/bench_bake.py [-- FRAMES LEVEL]
    ~/.cache/smoothffd/venv-bpy-5.0/bin/python blender_scenes/bench_bake.py [FRAMES LEVEL]

- bake: seconds per frame (render level, exact normals), .blend bytes per baked frame,
  the process's peak memory before and after;
- playback inside the bake: one frame change until the evaluated mesh is ready;
- a frame change in a scene where nothing is animated, with the group of this add-on
  (its Scene Time node makes the modifier depend on the frame) against the older group
  without frame ranges (nodegroup layout 1/2), which Blender did not re-evaluate.
"""
import os
import resource
import sys
import tempfile
import time

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "python")]
import smooth_ffd  # noqa: E402
from smooth_ffd import compat, nodegroup  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


ARGS = argv()
FRAMES = int(ARGS[0]) if ARGS else 4
LEVEL = int(ARGS[1]) if len(ARGS) > 1 else 4


def rss_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def scene(animated):
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.lattices, bpy.data.node_groups):
        for item in list(coll):
            coll.remove(item)
    me = bpy.data.meshes.new("sphere")
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")
    bmesh.ops.create_uvsphere(bm, u_segments=180, v_segments=131, radius=1.0, calc_uvs=True)
    bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), bool))
    obj = bpy.data.objects.new("sphere", me)
    bpy.context.scene.collection.objects.link(obj)
    lt = bpy.data.lattices.new("lat")
    lt.points_u = lt.points_v = lt.points_w = 5
    lat = bpy.data.objects.new("lat", lt)
    lat.scale = (2.4, 2.4, 2.4)
    bpy.context.scene.collection.objects.link(lat)
    rng = np.random.default_rng(1)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-0.03, 0.03, 3)
    if animated:
        p = lt.points[62]
        for f in range(1, FRAMES + 1):
            p.co_deform.z = 0.05 * f
            p.keyframe_insert("co_deform", frame=f)
    sc = bpy.context.scene
    sc.frame_start, sc.frame_end = 1, FRAMES
    sc.frame_set(1)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2, render_level=LEVEL,
                                    backend="cpu")
    return obj, lat, mod


def frame_change_ms(obj, frames):
    sc = bpy.context.scene
    times = []
    for f in frames:
        t = time.perf_counter()
        sc.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        len(obj.evaluated_get(dg).data.vertices)
        times.append(1e3 * (time.perf_counter() - t))
    return float(np.median(times))


def main():
    print(f"blender {bpy.app.version_string}, {FRAMES} frames, render level {LEVEL}")
    smooth_ffd.register()
    obj, lat, mod = scene(True)
    before = rss_mb()
    t = time.perf_counter()
    meshes = smooth_ffd.bake_smooth_ffd(obj, mod, 1, FRAMES)
    per_frame = (time.perf_counter() - t) / FRAMES
    tris = len(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.polygons)
    path = os.path.join(tempfile.mkdtemp(), "bake.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    size = os.path.getsize(path)
    smooth_ffd.clear_bake(obj, mod)
    bpy.ops.wm.save_as_mainfile(filepath=path)
    unbaked = os.path.getsize(path)
    print(f"bake: {per_frame:.2f} s per frame, {meshes} meshes of {tris} triangles; "
          f".blend {size / 1e6:.1f} MB baked, {unbaked / 1e6:.1f} MB without the bake "
          f"({(size - unbaked) / FRAMES / 1e6:.1f} MB per frame); peak memory "
          f"{before:.0f} MB before, {rss_mb():.0f} MB after")
    smooth_ffd.bake_smooth_ffd(obj, mod, 1, FRAMES)
    ms = frame_change_ms(obj, [(i % FRAMES) + 1 for i in range(1, 2 * FRAMES + 1)])
    print(f"playback inside the bake: {ms:.1f} ms per frame change (median)")

    # A static scene: what the Scene Time node costs on a frame change.
    obj, lat, mod = scene(False)
    bpy.context.view_layer.update()
    with_ranges = frame_change_ms(obj, range(2, 12))
    old = nodegroup._build_group(nodegroup.TEXT_LAYOUT if not compat.HAS_MENU_SOCKET
                                 else nodegroup.MENU_LAYOUT)
    values = {n: compat.get_modifier_input(mod, n) for n in ("Lattice", "Viewport Level",
                                                             "Render Level", "Result Object")}
    mod.node_group = old
    for n, v in values.items():
        compat.set_modifier_input(mod, n, v)
    compat.set_modifier_input(mod, "Backend", "cpu")
    obj.update_tag()
    bpy.context.view_layer.update()
    without = frame_change_ms(obj, range(12, 22))
    print(f"static scene, frame change: {with_ranges:.1f} ms with frame ranges (Scene Time), "
          f"{without:.1f} ms with the older group (median of 10)")
    sys.stdout.flush()
    if not bpy.app.binary_path:
        os._exit(0)


main()
