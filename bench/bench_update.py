"""Incremental frames (Deformer.deform(..., incremental=True), the CPU evaluator) against
whole frames: a 200k-triangle cube sphere in an 8x8x8 Blender lattice (cubic per axis) at
level 2, the add-on's viewport case (positions only) and with normals (compact layout), on 2
threads. Each round moves the middle point (its block reaches 4 of the 5 knot spans per axis),
a point next to a corner (2 of 5), or every point, and times one frame of each way, alternately,
so that both see the same machine load. Prints medians, the patches each recomputes and the
incremental tables' memory; asserts nothing (tests/test_update.py checks the bits).

    PYTHONPATH=python python3 bench/bench_update.py [ROUNDS]
"""
import statistics
import sys
import time

import numpy as np

import smoothffd


def cube_sphere(n):
    """A cube's six faces cut n x n, projected onto the unit sphere: 12 n^2 triangles, exact
    smooth corner normals."""
    g = np.linspace(-1.0, 1.0, n + 1)
    A, B = np.meshgrid(g, g, indexing="ij")
    pts, faces = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            P = np.empty((n + 1, n + 1, 3))
            P[..., axis] = sign
            P[..., (axis + 1) % 3] = A * sign
            P[..., (axis + 2) % 3] = B
            base = sum(len(p) for p in pts)
            pts.append(P.reshape(-1, 3))
            i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
            a = base + i * (n + 1) + j
            b, c, d = a + (n + 1), a + (n + 2), a + 1
            faces.append(np.stack([a, b, c], -1).reshape(-1, 3))
            faces.append(np.stack([a, c, d], -1).reshape(-1, 3))
    P = np.concatenate(pts)
    P, inverse = np.unique(np.round(P, 12), axis=0, return_inverse=True)
    F = inverse.reshape(-1)[np.concatenate(faces)]
    P = P / np.linalg.norm(P, axis=1, keepdims=True)
    return smoothffd.Mesh(P, F, corner_normals=P[F.reshape(-1)])


def main():
    rounds = int(sys.argv[1]) if len(sys.argv) > 1 else 9
    cuts = 129
    mesh = cube_sphere(cuts)
    shape = (8, 8, 8)
    g = [np.linspace(-0.5, 0.5, n) for n in shape]
    rest = np.stack(np.meshgrid(*g, indexing="ij"), -1)
    m = np.diag([2.4, 2.4, 2.4, 1.0])
    lat = smoothffd.BlenderLattice(rest, rest.copy(), lattice_to_object=m)
    # One Deformer each way: an incremental frame continues the same evaluator's last frame.
    ds = {way: smoothffd.Deformer(mesh, lat, level=2, device="cpu", threads=2)
          for way in ("whole", "incremental")}
    p = ds["whole"].plan
    print(f"cube sphere {12 * cuts * cuts} tris in, {p.output_triangles} out, {p.patches} patches, lattice 8x8x8, level 2; plan "
          f"{p.bytes / 1e6:.0f} MB", flush=True)
    rng = np.random.default_rng(3)
    moves = {"middle point (4,4,4)": [(4, 4, 4)], "corner point (1,1,1)": [(1, 1, 1)],
             "all 512 points": None}
    for normals, layout in ((False, "compact"), (True, "compact")):
        pts = rest.copy()
        kind = "with normals" if normals else "positions only"
        res = {}
        for way in ("whole", "incremental"):
            res[way] = ds[way].deform(pts, normals=normals, layout=layout)
        samples = {(mv, way): ([], []) for mv in moves for way in res}
        for r in range(rounds):
            for mv, idx in moves.items():
                if idx is None:
                    pts = pts + rng.normal(scale=0.004, size=pts.shape)
                else:
                    for q in idx:
                        pts[q] += rng.normal(scale=0.02, size=3)
                for way in ("whole", "incremental") if r % 2 == 0 else ("incremental", "whole"):
                    t0 = time.perf_counter()
                    res[way] = ds[way].deform(pts, out=res[way], normals=normals, layout=layout,
                                        incremental=way == "incremental")
                    samples[mv, way][0].append(1e3 * (time.perf_counter() - t0))
                    samples[mv, way][1].append(res[way].stats["recomputed_patches"])
                assert np.array_equal(res["whole"].positions, res["incremental"].positions)
        for mv in moves:
            w = statistics.median(samples[mv, "whole"][0])
            i = statistics.median(samples[mv, "incremental"][0])
            share = statistics.median(samples[mv, "incremental"][1]) / p.patches
            print(f"{kind:15} {mv:22} whole {w:6.1f} ms  incremental {i:6.1f} ms  "
                  f"({share:4.0%} of the patches)  whole/incremental {w / i:4.2f}x", flush=True)
    ev = ds["incremental"]._evaluator
    print(f"incremental tables: {ev.update_bytes / 1e6:.1f} MB (the plan: {p.bytes / 1e6:.0f} MB)")


if __name__ == "__main__":
    main()
