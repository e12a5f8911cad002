"""Opens a .blend in a Blender WITHOUT the Smooth FFD add-on and records what it evaluates and
renders: the machine of a render farm node, a colleague without the add-on, `--factory-startup`.

Run by check_stack.py as a separate process:
  blender -b --factory-startup FILE.blend --python noaddon_eval.py -- SPEC.json   (3.4)
  python noaddon_eval.py SPEC.json                                                (bpy)
SPEC: {"blend": path (bpy only), "out": .npz path, "frames": [...], "objects": [...],
"renders": [{"frame": f, "show": object name, "name": key}]}. The .npz holds, per object and
frame, the evaluated mesh (positions, corner vertices, corner normals, UV maps, material
indices), the Smooth FFD modifier's Status text and (4.5+) the warnings its panel shows, and
per render the alpha mask. This
script only reads: it never imports the add-on, and checks that nothing did.
"""
import json
import os
import sys

import bpy
import numpy as np

argv = sys.argv
spec_path = argv[argv.index("--") + 1] if "--" in argv else argv[1]
spec = json.load(open(spec_path))
if not bpy.data.filepath:
    bpy.ops.wm.open_mainfile(filepath=spec["blend"])

loaded = sorted(m for m in sys.modules if "smooth_ffd" in m)
handlers = [fn.__module__ for name in ("depsgraph_update_post", "frame_change_post", "load_post")
            for fn in getattr(bpy.app.handlers, name)]
out = {"addon_modules": np.array(json.dumps(loaded)),
       "addon_handlers": np.array(json.dumps([h for h in handlers if "smooth_ffd" in h]))}


def corner_normals(mesh):
    buf = np.empty(len(mesh.loops) * 3, np.float32)
    if bpy.app.version >= (4, 1):
        mesh.corner_normals.foreach_get("vector", buf)
    else:
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", buf)
    return buf.reshape(-1, 3)


def status(obj):
    """The Status input of the object's first Geometry Nodes modifier, by the socket's name."""
    for mod in obj.modifiers:
        if mod.type != 'NODES' or mod.node_group is None:
            continue
        group = mod.node_group
        sockets = ([i for i in group.interface.items_tree if getattr(i, "in_out", "") == 'INPUT']
                   if hasattr(group, "interface") else list(group.inputs))
        for s in sockets:
            if s.name == "Status":
                if hasattr(mod, "properties") and bpy.app.version >= (5, 2):
                    return getattr(mod.properties.inputs, s.identifier).value
                return mod[s.identifier]
    return ""


def record(obj, frame):
    mesh = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    key = f"{obj.name}/{frame}"
    pos = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", pos)
    cv = np.empty(len(mesh.loops), np.int32)
    mesh.loops.foreach_get("vertex_index", cv)
    mat = np.empty(len(mesh.polygons), np.int32)
    mesh.polygons.foreach_get("material_index", mat)
    out[key + "/pos"] = pos.reshape(-1, 3)
    out[key + "/cv"] = cv
    out[key + "/nrm"] = corner_normals(mesh)
    out[key + "/mat"] = mat
    out[key + "/mats"] = np.array(json.dumps([m.name if m else "" for m in mesh.materials]))
    out[key + "/uvnames"] = np.array(json.dumps([l.name for l in mesh.uv_layers]))
    for i, layer in enumerate(mesh.uv_layers):
        uv = np.empty(len(mesh.loops) * 2, np.float32)
        layer.data.foreach_get("uv", uv)
        out[f"{key}/uv{i}"] = uv.reshape(-1, 2)
    out[key + "/status"] = np.array(status(obj))
    warnings = []   # what the modifier panel's Warnings show (4.5+ API)
    for mod in obj.modifiers:
        if mod.type == 'NODES' and hasattr(mod, "node_warnings"):
            warnings += [w.message for w in mod.node_warnings]
    out[key + "/warnings"] = np.array(json.dumps(warnings))


scene = bpy.context.scene
for frame in spec.get("frames", []):
    scene.frame_set(frame)
    for name in spec.get("objects", []):
        record(bpy.data.objects[name], frame)

for r in spec.get("renders", []):
    scene.frame_set(r["frame"])
    for o in scene.objects:
        if o.type == 'MESH':
            o.hide_render = o.name != r["show"]
    scene.render.filepath = os.path.join(os.path.dirname(spec["out"]), r["name"] + ".png")
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(scene.render.filepath)
    out["render/" + r["name"]] = np.array(img.pixels[:], np.float32).reshape(-1, 4)[:, 3]

np.savez(spec["out"], **out)
print("noaddon_eval: wrote", spec["out"])
sys.stdout.flush()
if not bpy.app.binary_path:
    os._exit(0)   # bpy as a module: skip the static destructors (sffd_testlib.exit_now)
