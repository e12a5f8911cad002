"""Knot-box clipping (paper Fig. 6 and 7): a slab of 6 large quads (12 triangles) inside a
7x5x2 B-spline lattice: every face crosses several lattice cells, so the wave inside a face
only shows where the triangles are clipped against the knot boxes. Blender's Lattice
modifier moves the 8 corners only and the faces stay flat.

    blender -b --factory-startup --python-exit-code 1 --python blender_scenes/knotbox.py -- [--out DIR]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402
import shapes  # noqa: E402


def build():
    mesh = common.mesh_from_shape(shapes.slab((2.4, 1.6, 0.3)))
    return common.build_comparison(
        "knotbox", mesh, (7, 5, 2),
        lambda co: shapes.wave(shapes.wave(co, 0.9, 1.0, axis=0, up=2), 0.5, 0.6, axis=1, up=2),
        margin=0.02, view=(25, 35), closeup=((0.5, 0.5, 0.5), 0.6),
        description="6 quads (12 triangles), sharp edges; 7x5x2 B-spline lattice, waves "
                    "along x and y")


if __name__ == "__main__":
    common.run(build)
