"""Helpers for the add-on tests. Runs inside Blender (`blender -b --python`) or in a Python
that has the `bpy` module; never imported by pytest itself."""
import importlib
import math
import os
import sys
import time
import traceback

import bpy
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# A zip to install and test instead of the source tree's addon/ (tests/test_blender.py sets it,
# with BLENDER_USER_* naming a private, temporary user profile).
ADDON_ZIP = os.environ.get("SFFD_TEST_ADDON_ZIP") or None
INSTALLED = ADDON_ZIP is not None


def _install_addon(zip_path):
    """Installs and enables the zip the way users do; returns the installed module."""
    if bpy.app.version >= (4, 2):
        r = bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default",
                                                     enable_on_install=True)
        name = "bl_ext.user_default.smooth_ffd"
    else:
        bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
        r = bpy.ops.preferences.addon_enable(module="smooth_ffd")
        name = "smooth_ffd"
    if r != {'FINISHED'} or name not in sys.modules:
        raise SystemExit(f"FAIL installing {zip_path}: {r}, {name} not loaded")
    return sys.modules[name]


def _load_addon():
    if INSTALLED:
        return _install_addon(os.path.abspath(ADDON_ZIP))
    sys.path.insert(0, os.path.join(ROOT, "addon"))
    return importlib.import_module("smooth_ffd")


# The add-on and its modules: check scripts import them from here, never by name, so that
# they test whichever copy this is (installed: bl_ext.user_default.smooth_ffd on 4.2+).
smooth_ffd = _load_addon()
MODULES = ("api", "bake", "carry", "compat", "core", "frames", "gather", "handlers", "inputs",
           "latticeio", "linked", "live", "meshio", "nodegroup", "objects", "pipeline", "plans",
           "result_arrays", "stack_input", "state", "statusline", "write")
(api, bake, carry, compat, core, frames, gather, handlers, inputs, latticeio, linked, live, meshio,
 nodegroup, objects, pipeline, plans, result_arrays, stack_input, state, statusline, write) = (
    importlib.import_module(f"{smooth_ffd.__name__}.{m}") for m in MODULES)

_registered = INSTALLED   # enabling an installed add-on registers it
_results = []


def core_module():
    """The smoothffd package the add-on runs."""
    getter = getattr(core, "smoothffd", None)
    if getter is not None:
        return getter()
    return importlib.import_module("smoothffd")


def setup():
    global _registered
    if not _registered:
        smooth_ffd.register()
        _registered = True
    print(f"blender {bpy.app.version_string}, python {sys.version.split()[0]}, "
          f"numpy {np.__version__}")
    print("add-on:", smooth_ffd.__file__)
    sf = core_module()
    print("core:", getattr(sf, "__file__", sf))
    if INSTALLED:
        here = os.path.realpath(ROOT) + os.sep
        used = [os.path.realpath(f) for f in (smooth_ffd.__file__, getattr(sf, "__file__", ""))]
        check("installed add-on and core used, not the source tree's",
              not any(f.startswith(here) for f in used), str(used))


def args():
    """Arguments after `--` (blender) or after the script (python)."""
    argv = sys.argv
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    return [] if "--python" in argv else argv[1:]   # blender's own flags are not ours


def clear():
    pipeline.forget()
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.lattices, bpy.data.node_groups,
                 bpy.data.materials, bpy.data.actions, bpy.data.shape_keys):
        for item in list(coll):
            try:
                coll.remove(item)
            except Exception:   # shape keys go with their owner
                pass
    bpy.context.scene.frame_set(1)


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def tiny_cycles(location=(0, -8, 1)):
    """The scene set for a 16 x 16 Cycles render on the CPU (one sample, no denoising) through
    a new camera at `location` looking along +y. Returns the camera."""
    sc = bpy.context.scene
    cam = link(bpy.data.objects.new("cam", bpy.data.cameras.new("cam")))
    cam.location, cam.rotation_euler = location, (math.pi / 2, 0, 0)
    sc.camera = cam
    sc.render.engine = 'CYCLES'
    sc.cycles.samples = 1
    sc.cycles.use_denoising = False
    sc.cycles.device = 'CPU'
    sc.render.resolution_x = sc.render.resolution_y = 16
    sc.render.resolution_percentage = 100
    return cam


def render_evaluations(frame, probe):
    """Renders `frame` (not written) and calls probe(scene) on every frame change the render
    makes after render_pre (the frame and its motion-blur subframes): after the add-on's own
    render_pre handler, which comes first."""
    rendering = [False]

    def started(scene, *_):
        rendering[0] = True

    def ended(scene, *_):
        rendering[0] = False

    def changed(scene, *_):
        if rendering[0]:
            probe(scene)

    hooks = ((bpy.app.handlers.render_pre, started), (bpy.app.handlers.render_post, ended),
             (bpy.app.handlers.frame_change_post, changed))
    for handlers, fn in hooks:
        handlers.append(fn)
    try:
        bpy.context.scene.frame_set(frame)
        bpy.ops.render.render(write_still=False)
    finally:
        for handlers, fn in hooks:
            handlers.remove(fn)


def make_mesh(kind, name="src"):
    """Meshes Blender makes: suzanne, uvsphere, cylinder (sharp rim edges), cube."""
    if kind == "suzanne":
        bpy.ops.mesh.primitive_monkey_add(size=1.6)
    elif kind == "uvsphere":
        bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=0.8)
    elif kind == "cylinder":
        bpy.ops.mesh.primitive_cylinder_add(vertices=12, radius=0.7, depth=1.4)
    elif kind == "cube":
        bpy.ops.mesh.primitive_cube_add(size=1.3)
    else:
        raise ValueError(kind)
    obj = bpy.context.active_object
    obj.name = name
    me = obj.data
    if kind in ("suzanne", "uvsphere"):
        shade_smooth(me)
    elif kind == "cylinder":
        shade_smooth(me)
        mark_sharp_by_angle(me, math.radians(30))
    return obj


def shade_smooth(me):
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()


def mark_sharp_by_angle(me, angle):
    """Sharp edges where the dihedral angle exceeds `angle` (the cylinder's rims)."""
    if compat.HAS_CORNER_NORMALS:
        me.set_sharp_from_angle(angle=angle)
        return
    me.use_auto_smooth = True
    me.auto_smooth_angle = angle


def make_lattice(shape=(3, 3, 3), interp="KEY_BSPLINE", loc=(0, 0, 0), rot=(0, 0, 0),
                 scale=(1.5, 1.5, 1.5), jitter=0.15, seed=0, name="lat"):
    lt = bpy.data.lattices.new(name)
    lt.points_u, lt.points_v, lt.points_w = shape
    lt.interpolation_type_u = lt.interpolation_type_v = lt.interpolation_type_w = interp
    obj = link(bpy.data.objects.new(name, lt))
    obj.location, obj.rotation_euler, obj.scale = loc, rot, scale
    rng = np.random.default_rng(seed)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-jitter, jitter, 3)
    return obj


def lattice_modifier_twin(obj, lat, strength=1.0, vertex_group="", invert=False):
    """An object sharing obj's mesh, with Blender's own Lattice modifier: the reference."""
    ref = link(bpy.data.objects.new(obj.name + ".ref", obj.data))
    ref.matrix_world = obj.matrix_world
    for vg in obj.vertex_groups:
        ref.vertex_groups.new(name=vg.name)
    mod = ref.modifiers.new("Lattice", 'LATTICE')
    mod.object = lat
    mod.strength = strength
    mod.vertex_group = vertex_group
    mod.invert_vertex_group = invert
    return ref


def evaluated_mesh(obj):
    dg = bpy.context.evaluated_depsgraph_get()
    return obj.evaluated_get(dg).data


def positions(mesh):
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def triangles(mesh):
    loops = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", loops)
    return loops.reshape(-1, 3)


def corner_normals(mesh):
    return compat.read_corner_normals(mesh).astype(np.float64)


def lattice_size(obj, lat):
    """Largest extent of the lattice, measured in obj's local space (tolerances scale by it)."""
    l2o = np.linalg.solve(np.array(obj.matrix_world), np.array(lat.matrix_world))
    return float(np.max(np.linalg.norm(l2o[:3, :3], axis=0)))


def update():
    bpy.context.view_layer.update()


def check(name, ok, detail=""):
    _results.append((name, bool(ok)))
    print(f"{'PASS' if ok else 'FAIL'} {name} {detail}")
    sys.stdout.flush()


def run(name, fn, *a, **kw):
    """Runs one test function; an exception is a failure, not an abort of the whole script."""
    try:
        fn(*a, **kw)
    except Exception:
        traceback.print_exc()
        check(name, False, "(exception)")


def exit_now(code):
    """Ends the process. As a Python module (PyPI bpy) skip the C++ static destructors: bpy
    4.5.15 sometimes hangs for ever in exit() (GlobalState::~GlobalState destroys a condition
    variable its delayed_close_thread still waits on; seen here with every script passed).
    Inside the blender binary, a normal SystemExit (--python-exit-code)."""
    sys.stdout.flush()
    sys.stderr.flush()
    if not bpy.app.binary_path:
        os._exit(code)
    if code:
        raise SystemExit(code)


def finish():
    failed = [n for n, ok in _results if not ok]
    print(f"{len(_results) - len(failed)} passed, {len(failed)} failed")
    exit_now(1 if failed or not _results else 0)


def timed(fn, *a, **kw):
    t = time.perf_counter()
    out = fn(*a, **kw)
    return out, 1e3 * (time.perf_counter() - t)


def triangles_like_loops(mesh):
    """(C,) vertex index of every corner (loop), for polygon meshes."""
    loops = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", loops)
    return loops


def point_attribute(mesh, name):
    a = mesh.attributes[name]
    out = np.empty(len(a.data) * 3, dtype=np.float32)
    a.data.foreach_get("vector", out)
    return out.reshape(-1, 3)


def points_twin(points, obj, lat, strength=1.0):
    """A vertices-only object at obj's transform with Blender's Lattice modifier."""
    me = bpy.data.meshes.new("points")
    me.vertices.add(len(points))
    me.vertices.foreach_set("co", np.ascontiguousarray(points, np.float32).ravel())
    me.update()
    twin = link(bpy.data.objects.new("points", me))
    twin.matrix_world = obj.matrix_world
    mod = twin.modifiers.new("Lattice", 'LATTICE')
    mod.object = lat
    mod.strength = strength
    return twin


def patches(obj, mod):
    """Patches of the modifier's current plan: input triangles cut by the lattice's knot
    planes. Each patch is tessellated into level^2 output triangles."""
    t = pipeline.last_timing(obj, mod)
    return int(t["stats"]["patches"]) if t else -1


def run_without_addon(blend, frames=(), objects=(), renders=()):
    """Runs noaddon_eval.py on `blend` in a fresh Blender of this version that does not load
    the add-on (empty user profile; 3.4: --factory-startup); returns its .npz."""
    import json
    import subprocess
    import tempfile
    tmp = tempfile.mkdtemp()
    spec = {"blend": blend, "out": os.path.join(tmp, "out.npz"), "frames": list(frames),
            "objects": list(objects), "renders": list(renders)}
    spec_path = os.path.join(tmp, "spec.json")
    with open(spec_path, "w") as f:
        json.dump(spec, f)
    env = dict(os.environ)
    env.pop("SFFD_TEST_ADDON_ZIP", None)
    profile = os.path.join(tmp, "profile")
    env.update({"BLENDER_USER_RESOURCES": profile, "BLENDER_USER_SCRIPTS": profile + "/scripts",
                "BLENDER_USER_CONFIG": profile + "/config",
                "BLENDER_USER_EXTENSIONS": profile + "/extensions"})
    script = os.path.join(os.path.dirname(os.path.abspath(__file__)), "noaddon_eval.py")
    if bpy.app.binary_path:
        cmd = [bpy.app.binary_path, "-b", "--factory-startup", blend, "--python-exit-code", "1",
               "--python", script, "--", spec_path]
    else:
        cmd = [sys.executable, script, spec_path]
    proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    if proc.returncode != 0 or not os.path.exists(spec["out"]):
        print(proc.stdout[-3000:], proc.stderr[-3000:])
        raise RuntimeError(f"no-add-on Blender failed (rc {proc.returncode})")
    return np.load(spec["out"])
