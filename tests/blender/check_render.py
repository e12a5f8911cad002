"""Final render with Cycles in background mode: the render level and the right frame are
used, the image shows the object, and the viewport level comes back afterwards.

Optional argument: a .blend path to save the scene to (for the command-line render check,
cli_render_check.py, which pytest runs as `blender -b FILE --python ... -f 2`)."""
import os
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd  # noqa: E402

VIEWPORT, RENDER = 1, 3
RES = 48


def build_scene():
    T.clear()
    sc = bpy.context.scene
    obj = T.make_mesh("suzanne")
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    p = lat.data.points[13]
    p.co_deform = (0.0, 0.0, 0.0)
    p.keyframe_insert("co_deform", frame=1)
    p.co_deform = (0.0, 0.0, 1.2)
    p.keyframe_insert("co_deform", frame=3)
    ref = T.lattice_modifier_twin(obj, lat)
    ref.hide_render = True
    smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=VIEWPORT, render_level=RENDER)
    cam_data = bpy.data.cameras.new("cam")
    cam = T.link(bpy.data.objects.new("cam", cam_data))
    cam.location = (0, -5, 0)
    cam.rotation_euler = (np.pi / 2, 0, 0)
    sc.camera = cam
    light = T.link(bpy.data.objects.new("light", bpy.data.lights.new("light", 'SUN')))
    light.rotation_euler = (0.5, 0.2, 0)
    sc.render.engine = 'CYCLES'
    sc.cycles.samples = 4
    sc.cycles.use_denoising = False   # Debian's build has no OpenImageDenoise
    sc.cycles.device = 'CPU'
    sc.render.resolution_x = sc.render.resolution_y = RES
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = True
    sc.render.image_settings.file_format = 'PNG'
    sc.render.image_settings.color_mode = 'RGBA'
    sc.frame_start, sc.frame_end = 1, 3
    sc.frame_set(1)
    T.update()
    return obj, lat, ref


def install_probe(obj, record):
    """Records what the result mesh holds while the frame renders."""
    def probe(scene, *_):
        mod = obj.modifiers[0]
        ro = T.objects.result_object(obj, mod, create=False)
        record.append({"frame": scene.frame_current, "tris": len(ro.data.polygons),
                       "positions": T.positions(ro.data)[:len(obj.data.vertices)].tolist(),
                       "status": smooth_ffd.status(mod)})
    bpy.app.handlers.render_post.append(probe)
    return probe


def main():
    T.setup()
    obj, lat, ref = build_scene()
    npatch = T.patches(obj, obj.modifiers[0])
    sc = bpy.context.scene
    record = []
    probe = install_probe(obj, record)
    out = os.path.join(tempfile.mkdtemp(), "frame.png")
    sc.render.filepath = out
    sc.frame_set(2)
    bpy.ops.render.render(write_still=True)
    bpy.app.handlers.render_post.remove(probe)
    T.check("render ran", len(record) == 1, str(len(record)))
    if record:
        r = record[0]
        T.check("render uses render level", r["tris"] == npatch * RENDER ** 2,
                f"{r['tris']} tris (level-{RENDER} count {npatch * RENDER ** 2}), {r['status']}")
        T.check("render uses its frame", r["frame"] == 2)
        expect = T.positions(T.evaluated_mesh(ref))
        err = np.abs(np.array(r["positions"]) - expect).max() / T.lattice_size(obj, lat)
        T.check("rendered geometry matches the Lattice modifier at that frame", err <= 1e-5,
                f"err {err:.2e}")
    img = bpy.data.images.load(out)
    px = np.array(img.pixels[:]).reshape(-1, 4)
    coverage = float((px[:, 3] > 0.5).mean())
    T.check("image shows the object", 0.02 < coverage < 0.98, f"coverage {coverage:.2f}")
    # What Cycles drew: alpha masks of our object vs the Lattice-modifier twin at frame 3
    # (strongly deformed), against frame 1 to show the check can see a stale frame.
    def mask(frame, show):
        for o in (obj, ref):
            o.hide_render = o is not show
        sc.frame_set(frame)
        sc.render.filepath = os.path.join(os.path.dirname(out), f"m{frame}{show.name}.png")
        bpy.ops.render.render(write_still=True)
        im = bpy.data.images.load(sc.render.filepath)
        return np.array(im.pixels[:]).reshape(-1, 4)[:, 3] > 0.5
    ours3, twin3, twin1 = mask(3, obj), mask(3, ref), mask(1, ref)
    diff, stale = float((ours3 != twin3).mean()), float((twin1 != twin3).mean())
    T.check("render draws the current frame's geometry", diff < stale / 3,
            f"mask mismatch {diff:.3f} (vs frame 1: {stale:.3f})")
    ref.hide_render, obj.hide_render = True, False
    n_after = len(T.evaluated_mesh(obj).polygons)
    T.check("viewport level after render", n_after == npatch * VIEWPORT ** 2, f"{n_after} tris")
    save = T.args()
    if save:
        bpy.ops.wm.save_as_mainfile(filepath=save[0])
        print("saved", save[0])
    T.finish()


main()
