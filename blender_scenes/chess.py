"""Chess pawn (paper Fig. 12): a 16-sided lathe with sharp rims on the base and the collar,
bent by a 3x3x5 B-spline lattice.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/chess.py -- [--out DIR]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    mesh = common.mesh_from_shape(shapes.chess_pawn(segments=16))
    return common.build_comparison(
        "chess", mesh, (3, 3, 5), lambda co: shapes.twist(shapes.bend(co, 0.3, towards=0), 30),
        view=(15, 15), closeup=((0.5, 0.4, 0.62), 0.4, "clay"),
        description="16-sided pawn, sharp rims on base and collar; 3x3x5 B-spline lattice, "
                    "bend 0.3 and twist 30 degrees")


if __name__ == "__main__":
    common.run(build)
