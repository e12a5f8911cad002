"""Cube (paper Fig. 14, the error test): [-1, 1]^3 with 2 x 2 quads a face and sharp edges,
deformed by the error test's bulge-and-twist on a 3x3x3 Blender B-spline lattice around it.
The error numbers themselves (2x2x2 and 3x3x3 B-spline volumes of the core) are in
docs/results.md (scripts/report.sh).

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/cube.py -- [--out DIR]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    mesh = common.mesh_from_shape(shapes.grid_cube(2))
    return common.build_comparison(
        "cube", mesh, (3, 3, 3), lambda co: shapes.bulge_twist(co, bulge=0.5, twist_degrees=60),
        margin=0.0, view=(30, 25), closeup=((0.5, 0.3, 0.7), 0.55),
        description="2x2 quads a face, sharp edges; 3x3x3 B-spline lattice on the cube, "
                    "bulge 0.5 and twist 60 degrees")


if __name__ == "__main__":
    common.run(build)
