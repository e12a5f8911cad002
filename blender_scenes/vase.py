"""Vase (paper Fig. 1 and 16): a 12-sided low-poly lathe with a sharp rim and bottom edge,
bulged and bent by a 3x3x4 B-spline lattice.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/vase.py -- [--out DIR]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    mesh = common.mesh_from_shape(shapes.vase(segments=12))
    return common.build_comparison(
        "vase", mesh, (3, 3, 4), lambda co: shapes.bend(shapes.bulge(co, 0.4), 0.25, towards=0),
        view=(20, 18), closeup=((0.6, 0.5, 0.85), 0.4, "clay"),
        description="12-sided lathe, sharp rim and bottom edge; 3x3x4 B-spline lattice, "
                    "bulge 0.4 and bend 0.25")


if __name__ == "__main__":
    common.run(build)
