"""Times the fused path on W1 (L = 10) with whichever smoothffd is first on the path:
bench/gpu_ab.sh runs it alternately against two builds in one run, so that a
change is compared with its reference on the same machine (the floor varies between calls).

    PYTHONPATH=<tree>/python python3 bench/ab_time.py [--iters 100] [--level 10] [--label new]
        [--path fused|cublas] [--limit BYTES] [--degree D] [--shape N]

--limit emulates a GPU with that much shared memory a block (shared_memory_limit), --degree
uses a lattice of that degree: the inline kernel's other modes, reached as a plan or a device
reaches them. --shape N: N control points an axis (default 5); N = degree + 1 is one knot span,
no knot plane cuts the torus, so two trees whose plan builders differ (clipping) build the same
plan and the kernels compare on equal work (the printed patch, sample and output counts). Works with trees from before the timing harness moved to bench/ (their
CudaEvaluator.benchmark) and after (bench/native's sffd_bench module).
"""

import argparse
import json
import os
import sys

import numpy as np

import smoothffd  # noqa: E402  (first: bench_gpu puts this tree's python/ first on the path)

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--iters", type=int, default=100)
ap.add_argument("--level", type=int, default=10)
ap.add_argument("--label", default="")
ap.add_argument("--path", default="fused")
ap.add_argument("--limit", type=int, default=0, help="shared_memory_limit (bytes; 0: the device's own)")
ap.add_argument("--degree", type=int, default=2, help="lattice degree (every axis)")
ap.add_argument("--shape", type=int, default=5, help="lattice control points an axis")
args = ap.parse_args()
P, F, N = bench_gpu.torus(167, 140)
lat = bench_gpu.lattice_for(P, np.random.default_rng(2015), shape=(args.shape,) * 3, degree=(args.degree,) * 3)
mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
plan = smoothffd.Deformer(mesh, lat, level=args.level, device="cpu").plan
b = bench_gpu.benchmark(plan, args.path, args.limit, bench_gpu.values(lat), args.iters)
kernel = b["kernel"]
print(json.dumps(dict(label=args.label, module=os.path.dirname(smoothffd.__file__), level=args.level,
                      path=args.path, limit=args.limit, degree=args.degree, shape=args.shape, kernel=kernel,
                      patches=plan.patches, samples=getattr(plan, "samples", None), outputs=plan.output_vertices,
                      events=b["total_events"], queued=b.get("total_events_queued", float("nan")),
                      graph=b["total_graph"], floor=b["floor_ms"])))
