"""A few device-resident frames of W1 (bench_gpu.py's workload) for a profiler:

    ncu --kernel-name regex:k_ --launch-skip 6 --launch-count 6 python3 bench/profile_gpu.py [--level 10]

--path cublas profiles the reference path; --limit (shared_memory_limit) and --degree reach the
inline kernel's other modes as bench_gpu.py's MODES do."""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu  # noqa: E402
import smoothffd  # noqa: E402
from smoothffd import _core  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--level", type=int, default=10)
ap.add_argument("--frames", type=int, default=8)
ap.add_argument("--path", default="fused")
ap.add_argument("--limit", type=int, default=0)
ap.add_argument("--degree", type=int, default=2)
args = ap.parse_args()
P, F, N = bench_gpu.torus(167, 140)
lat = bench_gpu.lattice_for(P, np.random.default_rng(2015), degree=(args.degree,) * 3)
mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
plan = smoothffd.Deformer(mesh, lat, level=args.level, device="cpu").plan
ev = _core.CudaEvaluator(plan, args.path, shared_memory_limit=args.limit)
print(ev.kernel)
vals = bench_gpu.values(lat)
for _ in range(args.frames):
    t = ev.evaluate_device(vals)
print({k: round(v, 4) for k, v in t.items()})
