"""The modifier's tessellation modes (Level, Tolerance, Screen; tessellation.py) and the counts
held over frames (holds.py, holdframes.py):

- Tolerance: the result's triangle count differs from the level mode's, the status says it
  and "tolerance met"; the result equals the core's adaptive Deformer on the same inputs, and
  every result triangle's corners, edge midpoints and centroid lie within the tolerance of a
  much denser level-mode result of the same modifier (plus that mesh's own spacing); a max
  level too low says "tolerance not met at max level";
- Screen: the object-space tolerance is one pixel's world size at the object's nearest
  depth (checked against the formula) and shrinks when the camera moves closer; no camera:
  the plain tolerance and a note;
- a frame range held: identical topology on every frame of it, and each frame's own again
  after Clear; a render with motion blur: one topology over the shutter's subframes;
- Apply and Bake in tolerance mode; a Smooth FFD below one in tolerance mode (stacking) on
  frames of changing topology; the source mesh never written.
"""
import importlib
import os
import re
import sys
import tempfile

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd  # noqa: E402

holds = importlib.import_module(f"{smooth_ffd.__name__}.holds")
tessellation = importlib.import_module(f"{smooth_ffd.__name__}.tessellation")
compat, core, latticeio, meshio = T.compat, T.core, T.latticeio, T.meshio

TOL = 0.004


def scene():
    """Suzanne in a jittered 3x3x3 lattice, one lattice point animated over frames 1-4."""
    T.clear()
    obj = T.make_mesh("suzanne")
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    p = lat.data.points[13]
    for f, z in ((1, 0.0), (4, 0.9)):
        p.co_deform = (0.0, 0.0, z)
        p.keyframe_insert("co_deform", frame=f)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=3, render_level=4)
    return obj, lat, mod


def setting(mod, **kw):
    for name, value in kw.items():
        compat.set_modifier_input(mod, name.replace("_", " "), value)


def status(mod):
    return compat.get_modifier_input(mod, "Status")


def tris_in_status(text):
    m = re.search(r"(\d+) tris", text)
    return int(m.group(1)) if m else -1


def tolerance_in_status(text):
    m = re.search(r"tolerance ([0-9.e+-]+)", text)
    return float(m.group(1)) if m else None


def mesh_arrays(obj):
    me = T.evaluated_mesh(obj)
    return T.positions(me), T.triangles(me)


def core_result(obj, lat, tol, max_level):
    """The core's adaptive Deformer on the inputs the modifier reads (its own mesh, the
    evaluated lattice), built here, not the add-on's plan."""
    dg = bpy.context.evaluated_depsgraph_get()
    rest, pts, interp, _shape, _key, weights = latticeio.read_lattice(lat, dg)
    l2o = core.lattice_to_object(latticeio.world_matrix(obj, dg), latticeio.world_matrix(lat, dg))
    sf = T.core_module()
    lattice = sf.BlenderLattice(rest, pts, interpolation=interp, lattice_to_object=l2o)
    src = meshio.SourceMesh(obj.data, None, False, [])
    d = core.make_deformer(src, lattice, 1, "cpu", tol, max_level)
    return d.deform(normals=True, layout="corners")


def nearest_distance(points, cloud, chunk=512):
    """Per point, the distance to the nearest point of cloud (brute force, numpy)."""
    out = np.empty(len(points))
    c2 = (cloud * cloud).sum(1)
    for s in range(0, len(points), chunk):
        p = points[s:s + chunk]
        d2 = (p * p).sum(1)[:, None] - 2 * p @ cloud.T + c2[None, :]
        out[s:s + chunk] = np.sqrt(np.maximum(d2.min(axis=1), 0.0))
    return out


def test_tolerance():
    obj, lat, mod = scene()
    src_before = T.positions(obj.data).copy()
    bpy.context.scene.frame_set(4)
    smooth_ffd.update(obj)
    n_level = len(T.evaluated_mesh(obj).polygons)
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL,
            Viewport_Max_Level=32)
    smooth_ffd.update(obj)
    pos, tri = mesh_arrays(obj)
    text = status(mod)
    print("status:", text)
    T.check("tolerance mode: status says the tolerance, the triangles and 'tolerance met'",
            text.startswith("OK cpu, tolerance 0.004") and "tolerance met" in text
            and tris_in_status(text) == len(tri), text)
    T.check("tolerance mode: another triangle count than level 3", len(tri) != n_level,
            f"{len(tri)} against {n_level} at level 3")
    ref = core_result(obj, lat, TOL, 32)
    T.check("tolerance mode: the result is the core's adaptive Deformer's",
            np.array_equal(np.asarray(ref.triangles), tri)
            and np.abs(np.asarray(ref.positions, np.float64) - pos).max() <= 1e-6,
            f"{len(ref.triangles)} core triangles, bound {ref.stats['max_tessellation_bound']:.2e}")
    T.check("tolerance mode: the core's bound is within the tolerance",
            ref.stats["max_tessellation_bound"] <= TOL and ref.stats["tolerance_met"],
            f"{ref.stats['max_tessellation_bound']:.3e} <= {TOL}")
    # Against a dense level-mode result of the same modifier: the adaptive triangles'
    # corners, edge midpoints and centroids within TOL of it, up to its own spacing.
    dense_level = 12
    setting(mod, Viewport_Tessellation="Level", Viewport_Level=dense_level)
    smooth_ffd.update(obj)
    dpos, dtri = mesh_arrays(obj)
    spacing = float(np.linalg.norm(dpos[dtri[:, 0]] - dpos[dtri[:, 1]], axis=1).max())
    c = pos[tri]
    samples = np.concatenate([c[:, 0], (c[:, 0] + c[:, 1]) / 2, (c[:, 1] + c[:, 2]) / 2,
                              (c[:, 2] + c[:, 0]) / 2, c.mean(axis=1)])
    dist = nearest_distance(samples, dpos)
    # The nearest dense vertex is at most spacing/sqrt(3) from the dense surface's nearest
    # point, and the dense surface within its own (much smaller) level-12 error of the patches.
    slack = spacing / np.sqrt(3)
    T.check("tolerance mode: every triangle within the tolerance of a level-12 result",
            dist.max() <= TOL + slack,
            f"max {dist.max():.4f} <= {TOL} + {slack:.4f} (level 12: {len(dtri)} tris, "
            f"edges up to {spacing:.4f}; adaptive {len(tri)} tris)")
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=1e-6,
            Viewport_Max_Level=2)
    smooth_ffd.update(obj)
    T.check("max level too low: 'tolerance not met at max level 2'",
            "tolerance not met at max level 2" in status(mod), status(mod))
    T.check("tolerance mode: the source mesh is never written",
            np.array_equal(T.positions(obj.data), src_before))


def test_screen():
    obj, lat, mod = scene()
    sc = bpy.context.scene
    setting(mod, Render_Tessellation="Screen", Render_Pixel_Size=1.0, Render_Tolerance=0.01,
            Render_Max_Level=32)
    sc.camera = None
    smooth_ffd.update(obj, render=True)
    T.check("screen mode without a camera: the plain tolerance, with a note",
            "no render camera: tolerance 0.01 used" in status(mod)
            and tolerance_in_status(status(mod)) == 0.01, status(mod))
    cam = T.link(bpy.data.objects.new("cam", bpy.data.cameras.new("cam")))
    cam.rotation_euler = (np.pi / 2, 0, 0)
    sc.camera = cam
    sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = 640, 480, 100
    got = {}
    for dist in (8.0, 4.0):
        cam.location = (0, -dist, 0)
        T.update()
        smooth_ffd.update(obj, render=True)
        got[dist] = (tolerance_in_status(status(mod)), tris_in_status(status(mod)))
        print(f"camera at {dist}: {status(mod)}")
    # The formula, here: the nearest depth of the box around the mesh and the lattice.
    dg = bpy.context.evaluated_depsgraph_get()
    rest, pts, *_ = latticeio.read_lattice(lat, dg)
    l2o = core.lattice_to_object(latticeio.world_matrix(obj, dg), latticeio.world_matrix(lat, dg))
    box = tessellation.bounding_box(T.positions(obj.data), pts, l2o)
    depth = 4.0 - float(box[:, 1].max())  # camera on -y looking along +y, object at the origin
    want = depth * cam.data.sensor_width / cam.data.lens / 640
    T.check("screen mode: one pixel's size at the object's nearest depth",
            abs(got[4.0][0] - want) <= 5e-3 * want,   # the status's 3 significant digits
            f"{got[4.0][0]:.4g} against {want:.4g}")
    T.check("screen mode: the tolerance shrinks when the camera moves closer",
            got[4.0][0] < 0.7 * got[8.0][0] and got[4.0][1] > got[8.0][1],
            f"camera at 8: {got[8.0]}, at 4: {got[4.0]} (tolerance, tris)")
    obj.scale = (2, 2, 2)
    T.update()
    smooth_ffd.update(obj, render=True)
    t2 = tolerance_in_status(status(mod))
    T.check("screen mode: divided by the object's scale", t2 < got[4.0][0] / 1.5,
            f"{t2:.4g} at scale 2 against {got[4.0][0]:.4g}")


def topologies(obj, frames):
    sc = bpy.context.scene
    out = {}
    for f in frames:
        sc.frame_set(f)
        smooth_ffd.update(obj)
        out[f] = mesh_arrays(obj)[1].copy()
    return out


def test_hold():
    obj, lat, mod = scene()
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL, Viewport_Max_Level=32,
            Render_Tessellation="Tolerance", Render_Tolerance=TOL, Render_Max_Level=32)
    frames = (1, 2, 3, 4)
    free = topologies(obj, frames)
    counts = {f: len(t) for f, t in free.items()}
    T.check("unheld: the topology changes from frame to frame", len(set(counts.values())) > 1,
            str(counts))
    kinds = smooth_ffd.hold_tessellation(obj, mod, 1, 4)
    T.check("hold: render and viewport held", kinds == ["render", "viewport"], str(kinds))
    held = topologies(obj, frames)
    T.check("hold: identical topology on frames 1-4",
            all(np.array_equal(held[1], held[f]) for f in frames)
            and len(held[1]) >= max(counts.values()),
            f"{len(held[1])} tris on every frame (unheld {counts})")
    stats = T.pipeline.last_timing(obj, mod)["stats"]
    T.check("hold: the status says it, and whether the held counts met the tolerance",
            "counts held over frames 1-4" in status(mod)
            and ("tolerance met" in status(mod)) == bool(stats["tolerance_met"]),
            f"{status(mod)}; core: bound {stats['max_tessellation_bound']:.3e}, "
            f"{stats['capped']} capped")
    bpy.context.scene.frame_set(6)
    smooth_ffd.update(obj)
    T.check("hold: a frame outside the range is not held",
            "held" not in status(mod), status(mod))
    # Saved with the file: the held counts are on the hidden result object.
    ro = T.objects.result_object(obj, mod, create=False)
    T.check("hold: saved on the result object", holds.held_range(ro, "render") == (1, 4))
    smooth_ffd.clear_hold(obj, mod)
    again = topologies(obj, frames)
    T.check("clear hold: each frame's own topology again",
            all(np.array_equal(again[f], free[f]) for f in frames))
    # Another tolerance than the held one: not used, said.
    smooth_ffd.hold_tessellation(obj, mod, 1, 4)
    setting(mod, Viewport_Tolerance=2 * TOL)
    bpy.context.scene.frame_set(2)
    smooth_ffd.update(obj)
    T.check("hold: another tolerance setting is not held, and the status says so",
            "not used" in status(mod), status(mod))


def test_motion_blur():
    obj, lat, mod = scene()
    sc = bpy.context.scene
    setting(mod, Render_Tessellation="Tolerance", Render_Tolerance=TOL, Render_Max_Level=32)
    sc.render.use_motion_blur = True
    sc.render.motion_blur_shutter = 1.0
    T.handlers.smooth_ffd_modifiers(sc)
    sub = {}
    for f, s in ((1, 0.5), (2, 0.0), (2, 0.5)):
        sc.frame_set(f, subframe=s)
        smooth_ffd.update(obj, render=True)
        sub[f + s] = mesh_arrays(obj)[1].copy()
    sizes = {k: len(v) for k, v in sub.items()}
    T.check("motion blur, unheld: the shutter's subframes differ", len(set(sizes.values())) > 1,
            str(sizes))
    sc.frame_set(2)
    T.handlers.on_render_pre(sc)
    try:
        st = T.objects.state_of(obj, mod)
        T.check("render_pre with motion blur: counts held over the shutter",
                st.shutter is not None and st.shutter[0] == (1.5, 2.5),
                str(None if st.shutter is None else st.shutter[0]))
        held = {}
        for f, s in ((1, 0.5), (2, 0.0), (2, 0.5), (1, 0.75)):
            sc.frame_set(f, subframe=s)
            smooth_ffd.update(obj, render=True)
            held[f + s] = mesh_arrays(obj)[1].copy()
        first = next(iter(held.values()))
        T.check("motion blur: one topology over the shutter",
                all(np.array_equal(first, t) for t in held.values()),
                f"{len(first)} tris on subframes {sorted(held)} (unheld {sizes})")
        T.check("motion blur: the status says it",
                "counts held over the shutter 1.5-2.5" in status(mod), status(mod))
    finally:
        T.handlers.on_render_done(sc)
    T.check("after the render: no shutter hold", T.objects.state_of(obj, mod).shutter is None)
    # A real Cycles render of frame 2 with motion blur: every evaluation the render makes
    # (the frame and its shutter's subframes) shows the same topology.
    T.tiny_cycles((0, -6, 0))
    seen, texts = [], []

    def probe(scene):     # the render's evaluations of the frame and its subframes
        ro = T.objects.result_object(obj, mod, create=False)
        seen.append((round(scene.frame_current + scene.frame_subframe, 3), len(ro.data.polygons)))
        texts.append(status(mod))

    T.render_evaluations(2, probe)
    times = sorted({t for t, _ in seen})
    T.check("Cycles render with motion blur: one topology on every subframe it evaluates",
            len(times) >= 2 and len({n for _, n in seen}) == 1
            and all("counts held over the shutter 1.5-2.5" in t for t in texts),
            f"{seen}; {texts[-1] if texts else None}")
    # With a held range: it serves a shutter it covers whole; one that ends inside the
    # shutter (frames 1-2, shutter 1.5-2.5) gives way to the shutter's hold.
    for last, shutter_held in ((3, False), (2, True)):
        smooth_ffd.hold_tessellation(obj, mod, 1, last)
        sc.frame_set(2)
        T.handlers.on_render_pre(sc)
        try:
            st = T.objects.state_of(obj, mod)
            got = (st.shutter is not None) == shutter_held
            held = []
            for f, s in ((1, 0.5), (2, 0.0), (2, 0.5)):
                sc.frame_set(f, subframe=s)
                smooth_ffd.update(obj, render=True)
                held.append(mesh_arrays(obj)[1].copy())
            T.check(f"motion blur with frames 1-{last} held: one topology over the shutter "
                    f"({'the shutter' if shutter_held else 'the range'} holds it)",
                    got and all(np.array_equal(held[0], t) for t in held), status(mod))
        finally:
            T.handlers.on_render_done(sc)
        smooth_ffd.clear_hold(obj, mod)
    sc.render.use_motion_blur = False


def test_apply_and_bake():
    obj, lat, mod = scene()
    source_before, n_faces = T.positions(obj.data).copy(), len(obj.data.polygons)
    setting(mod, Render_Tessellation="Tolerance", Render_Tolerance=TOL, Render_Max_Level=32)
    sc = bpy.context.scene
    render_tris = {}
    for f in (1, 2, 3):
        sc.frame_set(f)
        smooth_ffd.update(obj, render=True)
        render_tris[f] = tris_in_status(status(mod))
    meshes = smooth_ffd.bake_smooth_ffd(obj, mod, 1, 3)
    baked = {}
    for f in (1, 2, 3):
        sc.frame_set(f)
        T.update()
        baked[f] = len(T.evaluated_mesh(obj).polygons)
    T.check("bake in tolerance mode: each frame its own render-tolerance topology",
            baked == render_tris and meshes == 3, f"baked {baked}, render {render_tris}")
    smooth_ffd.clear_bake(obj, mod)
    T.check("the source mesh is never written (renders, bake)",
            np.array_equal(T.positions(obj.data), source_before)
            and len(obj.data.polygons) == n_faces)
    sc.frame_set(3)
    smooth_ffd.apply_smooth_ffd(obj, mod)
    T.check("Apply in tolerance mode: the render-tolerance result",
            len(obj.data.polygons) == render_tris[3] and not obj.modifiers,
            f"{len(obj.data.polygons)} faces against {render_tris[3]}")


def test_stacked():
    obj, lat, upper = scene()
    lat2 = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.8, 1.8, 1.8), seed=9, name="lat2")
    setting(upper, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL,
            Viewport_Max_Level=32)
    lower = smooth_ffd.add_smooth_ffd(obj, lat2, viewport_level=1, name="Smooth FFD 2")
    sc = bpy.context.scene
    seen = {}
    for f in (1, 3, 4, 2):
        sc.frame_set(f)
        smooth_ffd.update(obj)
        n_upper = tris_in_status(status(upper))
        n = len(T.evaluated_mesh(obj).polygons)
        ok = status(lower).startswith("OK") and n >= n_upper
        seen[f] = (n_upper, n, ok)
    T.check("a Smooth FFD below a tolerance-mode one: every frame",
            all(v[2] for v in seen.values()) and len({v[0] for v in seen.values()}) > 1,
            str(seen))


def test_carried():
    """UV maps and vertex groups on an adaptive result (carry.AdaptiveSources): a UV map
    that is the corner's x, y and a group weight 0.5 + 0.3 x, both linear, come out as the
    same functions of each output vertex's rest position (barycentric interpolation keeps
    linear functions); the source's vertices keep their weights exactly."""
    T.clear()
    obj = T.make_mesh("uvsphere")
    me = obj.data
    co = T.positions(me)
    cv = T.triangles_like_loops(me)
    layer = me.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", np.ascontiguousarray(co[cv][:, :2] * 0.4 + 0.5, np.float32).ravel())
    second = me.uv_layers.new(name="xy")
    second.data.foreach_set("uv", np.ascontiguousarray(co[cv][:, :2], np.float32).ravel())
    me.uv_layers["UVMap"].active_render = True
    grp = obj.vertex_groups.new(name="grp")
    weights = 0.5 + 0.3 * co[:, 0]
    for i, w in enumerate(weights):
        grp.add([i], float(w), 'REPLACE')
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2)
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL, Viewport_Max_Level=32)
    smooth_ffd.update(obj, render=True)   # vertex groups are carried for render
    ro = T.objects.result_object(obj, mod, create=False)
    rme = ro.data
    rest = T.point_attribute(rme, "smooth_ffd_rest_position").astype(np.float64)
    rcv = T.triangles_like_loops(rme)
    xy = np.empty(len(rme.loops) * 2, np.float32)
    rme.uv_layers["xy"].data.foreach_get("uv", xy)
    err_uv = np.abs(xy.reshape(-1, 2) - rest[rcv][:, :2]).max()
    T.check("adaptive: a second UV map carried (linear in the rest position)",
            err_uv < 2e-5 and len(rme.polygons) != 2 * 2 * T.patches(obj, mod),
            f"max err {err_uv:.1e} on {len(rme.loops)} corners")
    gi = ro.vertex_groups["grp"].index
    w_out = np.array([next((g.weight for g in v.groups if g.group == gi), -1.0)
                      for v in rme.vertices])
    nv = len(co)
    err_w = np.abs(w_out[nv:] - (0.5 + 0.3 * rest[nv:, 0])).max()
    T.check("adaptive: vertex group weights carried (source vertices exact, others linear)",
            np.array_equal(w_out[:nv].astype(np.float32), weights.astype(np.float32))
            and err_w < 2e-5, f"max err {err_w:.1e} on {len(w_out) - nv} new vertices")


def test_live():
    """4.5+ live editing (positions only while a result keeps changing) on an adaptive
    result: the same triangles and positions as an exact update of the same inputs."""
    if not compat.CHEAP_EXACT_NORMALS:
        return   # before 4.5 the viewport is positions only anyway (test_tolerance's status)
    obj, lat, mod = scene()
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL, Viewport_Max_Level=32)
    live, settle = T.state.LIVE, T.state.SETTLE
    T.state.LIVE, T.state.SETTLE = True, 30.0
    try:
        for dz in (0.1, 0.1):
            lat.data.points[4].co_deform.z += dz
            T.update()
        text = status(mod)
        pos, tri = mesh_arrays(obj)
        pos, tri = pos.copy(), tri.copy()
        smooth_ffd.update(obj, force=True)
        T.state.LIVE = False
        smooth_ffd.update(obj, force=True)
        pos2, tri2 = mesh_arrays(obj)
        T.check("adaptive while changing: positions only, the exact update's mesh",
                "from geometry normals" in text and np.array_equal(tri, tri2)
                and np.array_equal(pos, pos2), f"{text}; then {status(mod)}")
    finally:
        T.state.LIVE, T.state.SETTLE = live, settle


def test_saved_hold():
    """A held range is saved with the file: reopened, frames 1-4 still share a topology."""
    obj, lat, mod = scene()
    setting(mod, Viewport_Tessellation="Tolerance", Viewport_Tolerance=TOL, Viewport_Max_Level=32)
    smooth_ffd.hold_tessellation(obj, mod, 1, 4)
    before = topologies(obj, (1, 4))
    path = os.path.join(tempfile.mkdtemp(), "held.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    obj = bpy.data.objects["src"]
    mod = obj.modifiers[0]
    after = topologies(obj, (1, 2, 4))
    T.check("a held range saved and reopened: the same topology on frames 1-4",
            all(np.array_equal(before[1], t) for t in after.values())
            and "counts held over frames 1-4" in status(mod), status(mod))


def main():
    T.setup()
    T.run("tolerance", test_tolerance)
    T.run("screen", test_screen)
    T.run("hold", test_hold)
    T.run("motion blur", test_motion_blur)
    T.run("apply and bake", test_apply_and_bake)
    T.run("stacked", test_stacked)
    T.run("carried", test_carried)
    T.run("live", test_live)
    T.run("saved hold", test_saved_hold)
    T.finish()


main()
