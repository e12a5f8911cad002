"""Shared scene building for the demo scenes (runs inside Blender: `blender -b --python`).

Every scene holds one object four ways, side by side along x (left to right):

    original | Lattice modifier | Lattice + Subdivision Surface | Smooth FFD (the add-on)

The four objects share one mesh (edit it and all four follow) and the three deformed ones have
their own lattice object, all three sharing one lattice data-block (move a point and all three
follow). What render_demo.py needs (which object is which, camera framing, close-up) is stored
as JSON in the scene's custom property "sffd_demo".
"""
import json
import math
import os
import sys
import time

import bpy
import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
for p in (os.path.join(ROOT, "addon"), os.path.join(ROOT, "python"), HERE):
    if p not in sys.path:
        sys.path.insert(0, p)

import smooth_ffd  # noqa: E402

VARIANTS = ("original", "lattice", "lattice_subsurf", "smooth_ffd")
LABELS = {"original": "Original", "lattice": "Lattice modifier",
          "lattice_subsurf": "Lattice + Subsurf", "smooth_ffd": "Smooth FFD"}
VIEWPORT_LEVEL, RENDER_LEVEL = 3, 10    # the paper tessellates each patch into 100 triangles
SUBSURF_LEVEL = 2

_registered = False


def enable_addon():
    """Registers the add-on from the source tree (once per Blender session)."""
    global _registered
    if not _registered:
        try:
            smooth_ffd.register()
        except ValueError:   # already registered (e.g. enabled as an installed add-on)
            pass
        _registered = True


def script_args():
    """Arguments after `--`: [--out DIR] (default out/scenes under the repository)."""
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    out = os.path.join(ROOT, "out", "scenes")
    if "--out" in argv:
        out = argv[argv.index("--out") + 1]
    return {"out": out}


def clear():
    """Empties the file (factory startup's cube, camera and light included)."""
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.lattices, bpy.data.materials,
                 bpy.data.cameras, bpy.data.lights, bpy.data.curves, bpy.data.node_groups,
                 bpy.data.worlds, bpy.data.images):
        for item in list(coll):
            coll.remove(item)


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


# --- meshes --------------------------------------------------------------------------------

def mesh_from_shape(shape, smooth=True):
    """A Blender mesh from a shapes.py dict; its `sharp` edges are marked sharp."""
    me = bpy.data.meshes.new(shape["name"])
    me.from_pydata([tuple(map(float, p)) for p in shape["positions"]], [],
                   [list(map(int, f)) for f in shape["polygons"]])
    me.validate()
    me.update()
    if smooth:
        me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    mark_sharp(me, shape.get("sharp", ()))
    return me


def _edge_keys(me):
    ev = np.empty(len(me.edges) * 2, dtype=np.int32)
    me.edges.foreach_get("vertices", ev)
    return np.sort(ev.reshape(-1, 2), axis=1)


def mark_sharp(me, pairs):
    """Marks the edges between the given vertex pairs sharp (and turns on auto smooth at 180
    degrees on Blender < 4.1, where sharp edges only count with auto smooth)."""
    keys = _edge_keys(me)
    want = {tuple(sorted(map(int, p))) for p in pairs}
    flags = np.empty(len(me.edges), dtype=bool)
    me.edges.foreach_get("use_edge_sharp", flags)
    for e, (a, b) in enumerate(keys):
        if (int(a), int(b)) in want:
            flags[e] = True
    me.edges.foreach_set("use_edge_sharp", flags)
    if hasattr(me, "use_auto_smooth"):
        me.use_auto_smooth = True
        me.auto_smooth_angle = math.pi
    me.update()
    return int(flags.sum())


def sharp_pairs_by_angle(me, degrees):
    """Vertex pairs of the edges whose dihedral angle exceeds `degrees` (or with one face)."""
    me.update()
    n = np.empty(len(me.polygons) * 3)
    me.polygons.foreach_get("normal", n)
    n = n.reshape(-1, 3)
    faces_of = {}
    for f, poly in enumerate(me.polygons):
        for ek in poly.edge_keys:
            faces_of.setdefault(tuple(sorted(ek)), []).append(f)
    limit = math.cos(math.radians(degrees))
    return [k for k, fs in faces_of.items()
            if len(fs) != 2 or float(n[fs[0]] @ n[fs[1]]) < limit]


def mesh_triangles(me):
    me.calc_loop_triangles()
    return len(me.loop_triangles)


# --- materials and world -------------------------------------------------------------------

def surface_material():
    """One material for every object, with two looks: "clay" (a glossy principled surface
    under the lights) and "zebra" (reflection lines: an emission of stripes along the view
    vector reflected about the shading normal, showing every kink of the normal field).
    set_look() switches the output between them."""
    mat = bpy.data.materials.new("sffd_surface")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.name = "clay"
    bsdf.inputs["Base Color"].default_value = (0.62, 0.66, 0.74, 1)
    bsdf.inputs["Roughness"].default_value = 0.28
    bsdf.inputs["Specular"].default_value = 0.6
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    refl = nt.nodes.new("ShaderNodeVectorMath")
    refl.operation = 'REFLECT'
    nt.links.new(geo.outputs["Incoming"], refl.inputs[0])
    nt.links.new(geo.outputs["Normal"], refl.inputs[1])
    sep = nt.nodes.new("ShaderNodeSeparateXYZ")
    nt.links.new(refl.outputs["Vector"], sep.inputs[0])
    stripes = nt.nodes.new("ShaderNodeMath")
    stripes.operation = 'SINE'
    mul = nt.nodes.new("ShaderNodeMath")
    mul.operation = 'MULTIPLY'
    mul.inputs[1].default_value = 28.0
    nt.links.new(sep.outputs["Z"], mul.inputs[0])
    nt.links.new(mul.outputs[0], stripes.inputs[0])
    ramp = nt.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].position = 0.0
    ramp.color_ramp.elements[0].color = (0.02, 0.02, 0.03, 1)
    ramp.color_ramp.elements[1].position = 0.12
    ramp.color_ramp.elements[1].color = (0.95, 0.95, 0.9, 1)
    nt.links.new(stripes.outputs[0], ramp.inputs[0])
    emit = nt.nodes.new("ShaderNodeEmission")
    emit.name = "zebra"
    nt.links.new(ramp.outputs[0], emit.inputs["Color"])
    nt.links.new(bsdf.outputs[0], out.inputs["Surface"])
    return mat


def set_look(look):
    """'clay' or 'zebra' for every object (they share the material)."""
    mat = bpy.data.materials["sffd_surface"]
    nt = mat.node_tree
    out = next(n for n in nt.nodes if n.type == 'OUTPUT_MATERIAL')
    nt.links.new(nt.nodes[look].outputs[0], out.inputs["Surface"])


def world_and_lights():
    world = bpy.data.worlds.new("sffd_world")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.35, 0.37, 0.4, 1)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.6
    bpy.context.scene.world = world
    key = link(bpy.data.objects.new("key_light", bpy.data.lights.new("key_light", 'SUN')))
    key.data.energy = 3.0
    key.data.angle = math.radians(8)
    key.rotation_euler = (math.radians(50), 0, math.radians(-35))
    rim = link(bpy.data.objects.new("rim_light", bpy.data.lights.new("rim_light", 'SUN')))
    rim.data.energy = 1.5
    rim.rotation_euler = (math.radians(-60), 0, math.radians(20))


def render_settings(scene, width=320, height=240, samples=16):
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False          # Debian's Blender has no OpenImageDenoise
    if hasattr(scene.cycles, "use_preview_denoising"):
        scene.cycles.use_preview_denoising = False
    scene.cycles.max_bounces = 4
    scene.render.resolution_x, scene.render.resolution_y = width, height
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = True
    scene.render.image_settings.file_format = 'PNG'
    scene.render.image_settings.color_mode = 'RGBA'
    scene.view_settings.view_transform = 'Standard'


# --- the four-way comparison ---------------------------------------------------------------

def lattice_object(name, lattice_data, center, size, offset):
    """A lattice object spanning the box `size` around `center` (+ offset). Blender's rest
    points (co) of a new lattice are not always in [-0.5, 0.5] (a resized one gets unit
    spacing), so the scale divides by their actual extent."""
    obj = link(bpy.data.objects.new(name, lattice_data))
    lo, hi = rest_extent(lattice_data)
    scale = np.asarray(size, float) / np.where(hi > lo, hi - lo, 1.0)
    obj.scale = tuple(scale)
    obj.location = tuple(np.asarray(center) + offset - scale * (lo + hi) / 2)
    obj.hide_render = True
    return obj


def rest_extent(lattice_data):
    co = np.empty(len(lattice_data.points) * 3, dtype=np.float32)
    lattice_data.points.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(np.float64)
    return co.min(0), co.max(0)


def make_lattice_data(name, points, interpolation, deform):
    """Lattice data with `points` (nu, nv, nw) and co_deform = deform(co) where co is taken
    to [-0.5, 0.5]^3 (its box) and back."""
    lt = bpy.data.lattices.new(name)
    lt.points_u, lt.points_v, lt.points_w = points
    lt.interpolation_type_u = lt.interpolation_type_v = lt.interpolation_type_w = interpolation
    co = np.empty(len(lt.points) * 3, dtype=np.float32)
    lt.points.foreach_get("co", co)
    co = co.reshape(-1, 3).astype(np.float64)
    lo, hi = co.min(0), co.max(0)
    mid, ext = (lo + hi) / 2, np.where(hi > lo, hi - lo, 1.0)
    moved = mid + ext * deform((co - mid) / ext)
    lt.points.foreach_set("co_deform", moved.astype(np.float32).ravel())
    return lt


def bbox(points):
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return p.min(0), p.max(0)


def evaluated_positions(obj):
    me = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    co = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def build_comparison(name, mesh, lattice_points, deform, interpolation='KEY_BSPLINE',
                     margin=0.08, view=(35, 20), closeup=((0.5, 0.5, 1.0), 0.45),
                     description="", lattice_center=None, lattice_size=None):
    """Builds the four variants of `mesh` and everything render_demo.py needs.

    lattice_points (nu, nv, nw) and interpolation: the Blender lattice, fitted around the mesh
    with `margin` (a fraction of the size on each side) unless lattice_center/lattice_size
    are given; deform(co) -> co_deform in the lattice's space. view = (azimuth, elevation) in
    degrees of the camera direction; closeup = (point given as a fraction of the deformed
    bounding box, distance as a fraction of the full view's distance[, look: "zebra" (the
    default) or "clay"]).
    """
    scene = bpy.context.scene
    mat = bpy.data.materials.get("sffd_surface") or surface_material()
    mesh.materials.clear()
    mesh.materials.append(mat)
    P = np.array([v.co for v in mesh.vertices])
    lo, hi = bbox(P)
    center = (lo + hi) / 2 if lattice_center is None else np.asarray(lattice_center, float)
    size = (hi - lo) * (1 + 2 * margin) if lattice_size is None else np.asarray(lattice_size, float)
    size = np.maximum(size, 1e-3)
    lt = make_lattice_data(f"{name}.lattice", lattice_points, interpolation, deform)
    spacing = 1.6 * float(max(hi - lo))
    objs, offsets, lattices = {}, {}, {}
    t_ffd = 0.0
    for k, variant in enumerate(VARIANTS):
        off = np.array([k * spacing, 0.0, 0.0])
        obj = link(bpy.data.objects.new(f"{name}.{variant}", mesh))
        obj.location = tuple(off)
        objs[variant], offsets[variant] = obj, off
        if variant == "original":
            continue
        lat = lattice_object(f"{name}.{variant}.lattice", lt, center, size, off)
        lattices[variant] = lat
        if variant in ("lattice", "lattice_subsurf"):
            mod = obj.modifiers.new("Lattice", 'LATTICE')
            mod.object = lat
        if variant == "lattice_subsurf":
            sub = obj.modifiers.new("Subdivision", 'SUBSURF')
            sub.levels = sub.render_levels = SUBSURF_LEVEL
        if variant == "smooth_ffd":
            t0 = time.perf_counter()
            mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=VIEWPORT_LEVEL,
                                            render_level=RENDER_LEVEL, backend="cpu")
            t_ffd = time.perf_counter() - t0
            status = smooth_ffd.status(mod)
            if not str(status).startswith("OK"):
                raise RuntimeError(f"{name}: Smooth FFD failed: {status}")
    bpy.context.view_layer.update()
    # Labels above the objects, for the interactive file only (not rendered).
    for variant, obj in objs.items():
        cu = bpy.data.curves.new(f"{name}.{variant}.label", 'FONT')
        cu.body = LABELS[variant]
        cu.align_x = 'CENTER'
        cu.size = 0.12 * spacing
        txt = link(bpy.data.objects.new(cu.name, cu))
        txt.location = tuple(offsets[variant] + [center[0], center[1], hi[2] + 0.25 * spacing])
        txt.rotation_euler = (math.radians(90), 0, 0)
        txt.hide_render = True
    # Framing: the union of every variant's evaluated bounding box, in the variant's frame.
    local = {v: evaluated_positions(o) for v, o in objs.items()}
    pts = np.concatenate(list(local.values()))
    blo, bhi = bbox(pts)
    target = (blo + bhi) / 2
    az, el = (math.radians(a) for a in view)
    direction = np.array([math.sin(az) * math.cos(el), -math.cos(az) * math.cos(el), math.sin(el)])
    cam_data = bpy.data.cameras.new("camera")
    cam_data.lens = 50
    cam = link(bpy.data.objects.new("camera", cam_data))
    scene.camera = cam
    distance = fit_distance(pts - target, direction, cam_data, margin=1.08)
    # The overview camera (the file opens looking at all four).
    world_pts = np.concatenate([local[v] + offsets[v] for v in VARIANTS])
    mid = (world_pts.min(0) + world_pts.max(0)) / 2
    place_camera(cam, mid, direction, fit_distance(world_pts - mid, direction, cam_data, 1.1))
    world_and_lights()
    render_settings(scene)
    frac, zoom = closeup[:2]
    look = closeup[2] if len(closeup) > 2 else "zebra"
    demo = {
        "name": name, "description": description,
        "objects": {v: o.name for v, o in objs.items()},
        "lattices": {v: o.name for v, o in lattices.items()},
        "offsets": {v: list(map(float, offsets[v])) for v in VARIANTS},
        "target": list(map(float, target)), "direction": list(map(float, direction)),
        "distance": float(distance),
        "closeup_target": list(map(float, blo + np.asarray(frac) * (bhi - blo))),
        "closeup_distance": float(distance * zoom), "closeup_look": look,
        "lattice_points": list(lattice_points), "interpolation": interpolation,
        "viewport_level": VIEWPORT_LEVEL, "render_level": RENDER_LEVEL,
        "subsurf_level": SUBSURF_LEVEL,
        "input_triangles": mesh_triangles(mesh),
        "add_smooth_ffd_s": t_ffd,
    }
    scene["sffd_demo"] = json.dumps(demo)
    return demo


def camera_basis(direction):
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    right = np.cross([0.0, 0.0, 1.0], d)
    right /= np.linalg.norm(right)
    return right, np.cross(d, right), d


def fit_distance(points, direction, cam_data, margin=1.05, aspect=4 / 3):
    """Smallest camera distance along `direction` from the origin that keeps every point in
    a frame of `aspect` (points relative to the aim point)."""
    right, up, back = camera_basis(direction)
    tan_h = cam_data.sensor_width / 2 / cam_data.lens
    tan_v = tan_h / aspect
    x, y, z = points @ right, points @ up, points @ back
    need = np.maximum(z + margin * np.abs(x) / tan_h, z + margin * np.abs(y) / tan_v)
    return float(need.max())


def place_camera(cam, target, direction, distance):
    from mathutils import Vector
    cam.location = tuple(np.asarray(target) + np.asarray(direction) * distance)
    cam.rotation_euler = (-Vector(direction)).to_track_quat('-Z', 'Y').to_euler()


def save(demo, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(os.path.abspath(out_dir), demo["name"] + ".blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, compress=False)
    print(f"scene {demo['name']}: saved {path} ({demo['input_triangles']} input triangles, "
          f"Smooth FFD added in {demo['add_smooth_ffd_s']:.2f} s)")
    return path


def run(build):
    """Entry point of a scene script: build(), then save into --out."""
    args = script_args()
    enable_addon()
    clear()
    demo = build()
    return save(demo, args["out"])
