"""Suzanne with mixed hard and soft edges: Blender's monkey, edges sharper than 50 degrees
marked sharp (brows, eye rims, ears), bulged and twisted by a 3x3x3 B-spline lattice.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/suzanne.py -- [--out DIR]
"""
import os
import sys

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    bpy.ops.mesh.primitive_monkey_add(size=2.0)
    tmp = bpy.context.active_object
    mesh = tmp.data
    mesh.name = "suzanne"
    bpy.data.objects.remove(tmp)
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    common.mark_sharp(mesh, common.sharp_pairs_by_angle(mesh, 50))
    return common.build_comparison(
        "suzanne", mesh, (3, 3, 3), lambda co: shapes.twist(shapes.bulge(co, 0.3, axis=1), 35),
        view=(-25, 12), closeup=((0.3, 0.2, 0.62), 0.4, "clay"),
        description="500 faces, edges over 50 degrees marked sharp; 3x3x3 B-spline lattice, "
                    "bulge 0.3 and twist 35 degrees")


if __name__ == "__main__":
    common.run(build)
