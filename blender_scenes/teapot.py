"""Utah teapot (paper Fig. 14, third column): Newell's 32 bicubic patches (teapot_data.py),
each tessellated coarsely into 3 x 3 quads, bent upwards along its spout-handle axis by a
4x3x3 B-spline lattice.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/teapot.py -- [--out DIR]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    mesh = common.mesh_from_shape(shapes.teapot(n=3))
    return common.build_comparison(
        "teapot", mesh, (4, 3, 3), lambda co: shapes.twist(shapes.bend(co, 0.3, axis=0, towards=2),
                                                           35, axis=0),
        view=(15, 22), closeup=((0.75, 0.5, 0.75), 0.45),
        description="32 Bezier patches at 3 x 3 quads each; 4x3x3 B-spline lattice, bend "
                    "0.3 and twist 35 degrees along the spout-handle axis")


if __name__ == "__main__":
    common.run(build)
