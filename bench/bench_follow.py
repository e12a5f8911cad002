"""A moving input against a static one (Deformer.follow): prints, per level, the frame time of W1
with a static input, with a pose change every frame that the plan follows (with a new clipping
every frame, and holding the pieces: follow(hold=True)), and with a new plan every frame (what
a moving input cost before plans could follow), all in one run.

The pose: W1's torus bent (z grows with x^2) and twisted about z (the angle grows with x), both
swinging with the frame, so every vertex moves every frame by about 1e-3 of the torus's size,
as a character's skin moves at 24 frames a second. Every frame is written into the arrays of
the frame before (deform(out=...), as the Blender add-on does) where their shapes allow.

    python3 bench/bench_follow.py [--levels 4 10] [--frames 12] [--device cpu|cuda]
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import smoothffd  # noqa: E402
from workloads import w1_lattice, w1_mesh  # noqa: E402


def pose(mesh, frame, period=240):
    """W1 bent and twisted at `frame` (every vertex moves between frames)."""
    P = mesh.positions
    s = np.sin(2 * np.pi * frame / period)
    x, y, z = P[:, 0], P[:, 1], P[:, 2]
    th = 0.15 * s * (x / 1.4)
    c, sn = np.cos(th), np.sin(th)
    posed = np.stack([c * x - sn * y, sn * x + c * y, z + 0.05 * s * (x / 1.4) ** 2], 1)
    normals = None
    if mesh.corner_normals is not None:  # turned by the twist at their vertex (the bend is small)
        n = mesh.corner_normals.astype(np.float64)
        tc, ts = c[mesh.corner_vertices], sn[mesh.corner_vertices]
        normals = np.stack([tc * n[:, 0] - ts * n[:, 1], ts * n[:, 0] + tc * n[:, 1], n[:, 2]], 1)
    return smoothffd.Mesh(posed, (mesh.corner_vertices, mesh.face_offsets), corner_normals=normals)


def median_ms(times):
    return 1e3 * float(np.median(times))


def run(level, frames, device):
    mesh, lattice = w1_mesh(), w1_lattice(0)
    poses = [pose(mesh, f + 1) for f in range(frames)]
    d = smoothffd.Deformer(mesh, lattice, level=level, device=device)
    r = d.deform()
    static = []
    for _ in range(frames):
        t = time.perf_counter()
        r = d.deform(out=r)
        static.append(time.perf_counter() - t)
    moving, follow, kept = [], [], 0
    for m in poses:
        t = time.perf_counter()
        kept += d.follow(m)
        t1 = time.perf_counter()
        r = d.deform(out=r)
        moving.append(time.perf_counter() - t)
        follow.append(t1 - t)
    # The same poses followed holding the pieces (Deformer.follow(hold=True)), from the same
    # first plan.
    h = smoothffd.Deformer(mesh, lattice, level=level, device=device)
    r = h.deform()
    holding, held, held_kept, held_follow, held_stages = [], 0, 0, [], {}
    for m in poses:
        t = time.perf_counter()
        held_kept += h.follow(m, hold=True)
        t1 = time.perf_counter()
        if h.plan.pieces_held:
            held += 1
            held_follow.append(t1 - t)
            held_stages = h.plan.build_ms
        r = h.deform(out=r)
        holding.append(time.perf_counter() - t)
    replan = []
    for m in poses[: max(3, frames // 3)]:
        t = time.perf_counter()
        smoothffd.Deformer(m, lattice, level=level, device=device).deform()
        replan.append(time.perf_counter() - t)
    s, mv = median_ms(static), median_ms(moving)
    print(f"W1 L={level} on {d.device}: {d.plan.output_triangles} triangles; frame: static {s:.1f} ms, "
          f"moving (follow + frame) {mv:.1f} ms = {mv / s:.2f}x static (follow {median_ms(follow):.1f} ms, "
          f"topology kept {kept}/{frames}); a new plan every frame {median_ms(replan):.1f} ms = "
          f"{median_ms(replan) / s:.2f}x static", flush=True)
    print(f"  holding the pieces: moving {median_ms(holding):.1f} ms = {median_ms(holding) / s:.2f}x static "
          f"(pieces held {held}/{frames}, topology kept {held_kept}/{frames}; a held follow "
          f"{median_ms(held_follow) if held_follow else float('nan'):.1f} ms)", flush=True)
    print("  held follow stages (ms, last held frame): " +
          ", ".join(f"{k} {v:.1f}" for k, v in held_stages.items()), flush=True)
    print("  follow stages with a new clipping (ms, last frame): " +
          ", ".join(f"{k} {v:.1f}" for k, v in d.plan.build_ms.items()), flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--levels", type=int, nargs="+", default=[4, 10])
    ap.add_argument("--frames", type=int, default=12)
    ap.add_argument("--device", default="cpu", choices=["cpu", "cuda"])
    args = ap.parse_args()
    for level in args.levels:
        run(level, args.frames, args.device)


if __name__ == "__main__":
    main()
