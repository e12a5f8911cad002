"""Times the default fused path on W1 (L = 10) with whichever smoothffd is first on the path:
bench/ab_device.sh runs it alternately against two builds in one device call, so that a
change is compared with its reference on the same machine (the floor varies between calls).

    PYTHONPATH=<tree>/python python3 bench/ab_time.py [--iters 100] [--level 10] [--label new]
        [--env SMOOTHFFD_X=1 ...]
"""

import argparse
import json
import os
import sys

import numpy as np

import smoothffd  # noqa: E402  (first: bench_gpu puts this tree's python/ first on the path)
from smoothffd import _core  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("--iters", type=int, default=100)
ap.add_argument("--level", type=int, default=10)
ap.add_argument("--label", default="")
ap.add_argument("--env", action="append", default=[], help="NAME=VALUE set before the evaluator is made")
args = ap.parse_args()
for kv in args.env:
    name, value = kv.split("=", 1)
    os.environ[name] = value
P, F, N = bench_gpu.torus(167, 140)
lat = bench_gpu.lattice_for(P, np.random.default_rng(2015))
mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
plan = smoothffd.Deformer(mesh, lat, level=args.level, device="cpu").plan
b = _core.CudaEvaluator(plan, "fused").benchmark(bench_gpu.values(lat), args.iters)
print(json.dumps(dict(label=args.label, module=os.path.dirname(smoothffd.__file__), level=args.level,
                      events=b["total_events"], queued=b.get("total_events_queued", float("nan")), graph=b["total_graph"],
                      floor=b["floor_ms"])))
