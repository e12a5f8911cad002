"""Runs before a command-line render: `blender -b FILE --python cli_render_check.py -f N -- OUT.json`.

Enables the add-on (as an installed add-on would be) and records, per rendered frame, the
result mesh's triangle count and its original vertices next to Blender's Lattice modifier
twin (object "src.ref") at that frame, into OUT.json for pytest to check."""
import json
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd  # noqa: E402

OUT = T.args()[0]
records = []


def on_post(scene, *_):
    obj, ref = bpy.data.objects["src"], bpy.data.objects["src.ref"]
    ro = T.objects.result_object(obj, obj.modifiers[0], create=False)
    got = T.positions(ro.data)[:len(obj.data.vertices)]
    dg = bpy.context.evaluated_depsgraph_get()
    exp = T.positions(ref.evaluated_get(dg).data)
    records.append({"frame": scene.frame_current, "tris": len(ro.data.polygons),
                    "patches": T.patches(obj, obj.modifiers[0]),
                    "err": float(np.abs(got - exp).max()),
                    "status": smooth_ffd.status(obj.modifiers[0])})
    with open(OUT, "w") as f:
        json.dump(records, f)


T.setup()
bpy.app.handlers.render_post.append(on_post)
