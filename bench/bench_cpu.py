"""CPU benchmark of the paper's Table 1 workload (W1): prints plan time, per-frame deform time
(median of repeats), stage times, output counts and throughput.

    PYTHONPATH=python python3 bench/bench_cpu.py [--levels 4 10 16] [--repeats 7] [--reuse]
                                                 [--positions-only] [--layouts corners compact]

--positions-only times deform(..., normals=False) (the add-on's 3.4-4.0 viewport): the same
table, without the normal stages. --layouts: the output layouts to time (deform(...,
layout=...)); with more than one, their frames alternate in the same run, one row each.
"""

import argparse
import os
import platform
import statistics
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import smoothffd  # noqa: E402
from workloads import w1_lattice, w1_mesh  # noqa: E402


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--levels", type=int, nargs="+", default=[4, 10, 16])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--reuse", action="store_true",
                    help="steady state of a frame loop: each frame overwrites the previous Result")
    ap.add_argument("--positions-only", action="store_true",
                    help="deform(..., normals=False): positions only, no corner normals")
    ap.add_argument("--layouts", nargs="+", choices=("corners", "compact"), default=["corners"])
    args = ap.parse_args()
    mesh = w1_mesh()
    print(f"W1: {mesh.face_count} triangles, 5x5x5 control points, degree 2x2x2; "
          f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores"
          + ("; positions only (normals=False)" if args.positions_only else ""))
    print(f"{'L':>3} {'layout':>8} {'plan ms':>9} {'deform ms':>10} {'out tris':>10} {'out verts':>10} "
          f"{'Mtri/s':>7}  stages (ms)")
    for L in args.levels:
        t0 = time.perf_counter()
        d = smoothffd.Deformer(mesh, w1_lattice(0), level=L, device="cpu", threads=args.threads)
        plan_ms = (time.perf_counter() - t0) * 1e3
        times = {k: [] for k in args.layouts}
        stages = {k: [] for k in args.layouts}
        last = dict.fromkeys(args.layouts)
        for i in range(args.repeats):
            lat = w1_lattice(i + 1)
            for layout in args.layouts:  # alternating: the machine's drift hits every layout alike
                t0 = time.perf_counter()
                r = d.deform(lat.control_points, out=last[layout] if args.reuse else None,
                             normals=not args.positions_only, layout=layout)
                times[layout].append((time.perf_counter() - t0) * 1e3)
                stages[layout].append(r.stats["stage_ms"])
                last[layout] = r
        for layout in args.layouts:
            med = statistics.median(times[layout])
            st = {k: statistics.median(s[k] for s in stages[layout]) for k in stages[layout][0]}
            r = last[layout]
            T = r.stats["output_triangles"]
            print(f"{L:>3} {layout:>8} {plan_ms:9.1f} {med:10.1f} {T:>10} {r.stats['output_vertices']:>10} "
                  f"{T / med / 1e3:7.2f}  " + ", ".join(f"{k} {v:.1f}" for k, v in st.items()))


if __name__ == "__main__":
    main()
