"""How the inline kernel's frame time grows with the patch count (W1's torus, more or fewer
rings; L = 10): a staircase at multiples of (resident blocks x 32 patches) means each round
of groups costs a fixed latency, a straight line that throughput sets the time.

    python3 bench/tail_probe.py [--iters 100]

Also times W1 with SMOOTHFFD_INLINE_GRID (blocks of the persistent grid) set to a few values."""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu  # noqa: E402
import smoothffd  # noqa: E402
from smoothffd import _core  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--iters", type=int, default=100)
args = ap.parse_args()
rng = np.random.default_rng(2015)


def case(nu, nv=140):
    P, F, N = bench_gpu.torus(nu, nv)
    lat = bench_gpu.lattice_for(P, np.random.default_rng(2015))
    mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
    plan = smoothffd.Deformer(mesh, lat, level=10, device="cpu").plan
    return plan, bench_gpu.values(lat)


for nu in (40, 60, 80, 100, 120, 140, 155, 167, 180, 200, 220, 240, 260):
    plan, vals = case(nu)
    ev = _core.CudaEvaluator(plan, "fused")
    b = ev.benchmark(vals, args.iters)
    g = (plan.patches + 31) // 32
    print(f"nu={nu:4d} patches={plan.patches:6d} groups={g:5d} groups/528={g / 528:5.2f} "
          f"events={b['total_events']:.4f} graph={b['total_graph']:.4f} "
          f"ns/patch={b['total_graph'] * 1e6 / plan.patches:.3f}", flush=True)
    del ev
plan, vals = case(167)
for grid in (132, 264, 396, 427, 528, 569, 853, 1705):
    os.environ["SMOOTHFFD_INLINE_GRID"] = str(grid)
    ev = _core.CudaEvaluator(plan, "fused")
    b = ev.benchmark(vals, args.iters)
    print(f"W1 grid={grid:5d} events={b['total_events']:.4f} graph={b['total_graph']:.4f}", flush=True)
    del ev
