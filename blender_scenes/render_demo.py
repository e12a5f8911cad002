"""Renders one demo scene made by a scene script, and exports its Smooth FFD result as OBJ.

    blender -b out/scenes/vase.blend --python-exit-code 1 --python blender_scenes/render_demo.py \
        -- --out out/demo [--samples 16] [--size 320x240]

Writes into OUT/<scene>/: <variant>.png (Cycles on the CPU, each variant framed the same way),
<variant>_closeup.png (a close-up, shaded or with reflection lines), summary.json (triangle counts, timings);
and OUT/<scene>_smooth_ffd.obj (the core run directly at the render level, with its normals).
The pictures are put side by side by blender_scenes/composite.py.
"""
import json
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import smooth_ffd  # noqa: E402
from smooth_ffd import pipeline  # noqa: E402

import smoothffd  # noqa: E402  (python/ is on sys.path through common)
from smoothffd import io as sffd_io  # noqa: E402


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"out": os.path.join(common.ROOT, "out", "demo"), "samples": 16, "size": "320x240",
            "zebra_samples": 4}
    for key in list(opts):
        flag = "--" + key.replace("_", "-")
        if flag in argv:
            opts[key] = type(opts[key])(argv[argv.index(flag) + 1])
    return opts


def smooth_ffd_modifier(obj):
    return next(m for m in obj.modifiers if m.type == 'NODES')


def render_to(path):
    bpy.context.scene.render.filepath = path
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - t0


def show_only(demo, variant):
    for v, name in demo["objects"].items():
        bpy.data.objects[name].hide_render = v != variant


def core_inputs(obj, lat):
    """smoothffd.Mesh and BlenderLattice for obj deformed by lat, read with plain bpy (an
    independent path from the add-on's own readers)."""
    me = obj.data
    nv, nl, nf = len(me.vertices), len(me.loops), len(me.polygons)
    co = np.empty(nv * 3, np.float32)
    me.vertices.foreach_get("co", co)
    cv = np.empty(nl, np.int32)
    me.loops.foreach_get("vertex_index", cv)
    starts = np.empty(nf, np.int32)
    me.polygons.foreach_get("loop_start", starts)
    if hasattr(me, "calc_normals_split"):
        me.calc_normals_split()
    cn = np.empty(nl * 3, np.float32)
    if hasattr(me, "corner_normals"):
        me.corner_normals.foreach_get("vector", cn)
    else:
        me.loops.foreach_get("normal", cn)
    mesh = smoothffd.Mesh(co.reshape(-1, 3), (cv, np.append(starts, nl)),
                          corner_normals=cn.reshape(-1, 3))
    lt = lat.data
    shape = (lt.points_u, lt.points_v, lt.points_w)
    n = len(lt.points)
    rest, pts = np.empty(n * 3, np.float32), np.empty(n * 3, np.float32)
    lt.points.foreach_get("co", rest)
    lt.points.foreach_get("co_deform", pts)
    grid = lambda a: a.reshape(shape[2], shape[1], shape[0], 3).transpose(2, 1, 0, 3)
    interp = tuple(t[len("KEY_"):] for t in (lt.interpolation_type_u, lt.interpolation_type_v,
                                               lt.interpolation_type_w))
    l2o = np.linalg.inv(np.array(obj.matrix_world)) @ np.array(lat.matrix_world)
    lattice = smoothffd.BlenderLattice(grid(rest), grid(pts), interpolation=interp,
                                       lattice_to_object=l2o)
    return mesh, lattice


def main():
    opts = parse_args()
    common.enable_addon()
    scene = bpy.context.scene
    demo = json.loads(scene["sffd_demo"])
    name = demo["name"]
    out_dir = os.path.join(os.path.abspath(opts["out"]), name)
    os.makedirs(out_dir, exist_ok=True)
    w, h = (int(x) for x in opts["size"].split("x"))
    common.render_settings(scene, w, h, opts["samples"])
    smooth_ffd.update(force=True)   # the file was opened before the add-on was enabled
    ffd_obj = bpy.data.objects[demo["objects"]["smooth_ffd"]]
    mod = smooth_ffd_modifier(ffd_obj)
    at_render = {}

    def record(_scene, *_):
        t = pipeline.last_timing(ffd_obj, mod)
        if t and not ffd_obj.hide_render:
            at_render.update(triangles=t["triangles"], deform_ms=t["deform_ms"],
                             write_ms=t["write_ms"], level=t["level"],
                             patches=int(t["stats"].get("patches", -1)))
    bpy.app.handlers.render_post.append(record)

    cam = scene.camera
    direction = np.array(demo["direction"])
    times = {}
    common.set_look("clay")
    for v in common.VARIANTS:
        show_only(demo, v)
        common.place_camera(cam, np.array(demo["offsets"][v]) + demo["target"], direction,
                            demo["distance"])
        times[v] = render_to(os.path.join(out_dir, f"{v}.png"))
    look = demo.get("closeup_look", "zebra")
    common.set_look(look)
    if look == "zebra":   # emission only: a few samples are enough
        scene.cycles.samples = opts["zebra_samples"]
    for v in common.VARIANTS:
        show_only(demo, v)
        common.place_camera(cam, np.array(demo["offsets"][v]) + demo["closeup_target"],
                            direction, demo["closeup_distance"])
        times[v + "_closeup"] = render_to(os.path.join(out_dir, f"{v}_closeup.png"))
    common.set_look("clay")
    bpy.app.handlers.render_post.remove(record)

    dg = bpy.context.evaluated_depsgraph_get()
    tris = {}
    for v in ("original", "lattice", "lattice_subsurf"):
        me = bpy.data.objects[demo["objects"][v]].evaluated_get(dg).data
        tris[v] = common.mesh_triangles(me)
    tris["smooth_ffd"] = at_render.get("triangles")

    # The OBJ: the core itself at the render level (same numbers as the add-on's result).
    lat = bpy.data.objects[demo["lattices"]["smooth_ffd"]]
    mesh, lattice = core_inputs(ffd_obj, lat)
    t0 = time.perf_counter()
    deformer = smoothffd.Deformer(mesh, lattice, level=demo["render_level"], device="cpu")
    t_plan = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = deformer.deform(lattice)
    t_deform = time.perf_counter() - t0
    obj_path = os.path.join(os.path.abspath(opts["out"]), f"{name}_smooth_ffd.obj")
    sffd_io.write_result(obj_path, res, header=f"smoothffd demo: {name}, level "
                                               f"{demo['render_level']}")
    # Cross-check against Blender's Lattice modifier at the original vertices.
    ref = bpy.data.objects[demo["objects"]["lattice"]].evaluated_get(dg).data
    ref_co = np.array([v.co for v in ref.vertices])
    err = float(np.abs(res.positions[:len(ref_co)] - ref_co).max())

    summary = dict(demo, render_s=times, triangles=tris, smooth_ffd_at_render=at_render,
                   core_plan_ms=1e3 * t_plan, core_deform_ms=1e3 * t_deform,
                   core_triangles=int(len(res.triangles)), core_patches=int(res.stats.get(
                       "patches", -1)), vertices_vs_lattice_modifier=err, obj=obj_path,
                   samples=opts["samples"], size=[w, h], blender=bpy.app.version_string)
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"render {name}: {sum(times.values()):.1f} s for {len(times)} images; triangles "
          f"{tris}; core level {demo['render_level']}: plan {1e3 * t_plan:.0f} ms, deform "
          f"{1e3 * t_deform:.0f} ms; |vertices - Lattice modifier| = {err:.1e}")


main()
