"""GPU benchmark of smooth FFD: W1 (paper Table 1) at several levels, a 1M-triangle
mesh, fused vs cuBLAS paths, ratio to the CPU backend, the uniform upsampling baseline
(paper Table 5), and the inline kernel's other modes where a plan or a device calls for them
(smaller GPUs emulated by their shared memory, a degree-4 lattice). Writes a JSON with every
number and prints a summary table last.

    PYTHONPATH=python python3 bench/bench_gpu.py --out bench.json [--quick]
"""

import argparse
import json
import os
import sys
import time

import numpy as np

import smoothffd  # the installed package, or the source tree's with PYTHONPATH=python
from smoothffd import _core


def torus(nu, nv, R=1.0, r=0.4):
    """Torus grid: 2 nu nv triangles, exact smooth normals."""
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    U, Vv = np.meshgrid(u, v, indexing="ij")
    n = np.stack([np.cos(U) * np.cos(Vv), np.sin(U) * np.cos(Vv), np.sin(Vv)], -1).reshape(-1, 3)
    c = np.stack([R * np.cos(U), R * np.sin(U), np.zeros_like(U)], -1).reshape(-1, 3)
    P = c + r * n
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    cc = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    F = np.concatenate([np.stack([a, b, cc], -1).reshape(-1, 3), np.stack([a, cc, d], -1).reshape(-1, 3)])
    return P, F, n


def lattice_for(P, rng, shape=(5, 5, 5), degree=(2, 2, 2), amount=0.06):
    """W1's lattice (degree 2; `degree` for the modes' comparison) around the points P."""
    lo, hi = P.min(0), P.max(0)
    pad = 0.05 * (hi - lo)
    lat = smoothffd.BSplineLattice.identity(lo - pad, hi + pad, shape=shape, degree=degree)
    size = np.linalg.norm(hi - lo)
    return lat.with_control_points(lat.rest_points + amount * size * rng.standard_normal(lat.rest_points.shape))


def values(lat):
    return np.ascontiguousarray(lat.control_values().reshape(-1, 3), dtype=np.float32)


def benchmark(plan, path, limit, vals, iters):
    """The timing harness's measures of an evaluator of the plan (path, shared_memory_limit as
    CudaEvaluator's): medians of per-stage events, the frame behind a holding kernel (queued),
    CUDA-graph replays, the device-to-device copy floor, and "kernel", what ran. The only
    evaluator alive while it runs, in every tree (a second one's memory moved the floor)."""
    if hasattr(_core.CudaEvaluator, "benchmark"):  # a tree from before the harness moved to bench/native
        ev = _core.CudaEvaluator(plan, path, shared_memory_limit=limit)
        b = ev.benchmark(vals, iters)
        b["kernel"] = ev.fused_kernel if path == "fused" else "cublas"
        return b
    try:
        module = bench_module()
    except ImportError:  # an installed wheel: the public evaluator's stage events only
        return public_timing(plan, path, limit, vals, iters)
    return module.benchmark(plan, vals, iters, path=path, shared_memory_limit=limit)


def public_timing(plan, path, limit, vals, iters):
    """Without bench/native (an installed package): medians of CudaEvaluator.evaluate_device's
    per-stage CUDA events; the queued, graph and floor measures are the harness's (NaN here)."""
    ev = _core.CudaEvaluator(plan, path, shared_memory_limit=limit)
    for _ in range(5):
        ev.evaluate_device(vals)
    runs = [ev.evaluate_device(vals) for _ in range(iters)]
    b = {k: float(np.median([r[k] for r in runs])) for k in runs[0]}
    b["total_events"] = b.pop("device_total")
    for key in ("total_events_queued", "total_graph", "d2d_copy_ms", "d2d_bandwidth_GBps", "floor_ms"):
        b[key] = float("nan")
    b["output_bytes"] = float(ev.output_bytes)
    b["kernel"] = ev.kernel
    return b


def bench_module():
    """bench/native's sffd_bench of the tree whose smoothffd is imported (a development build
    puts it in that tree's bench/); ImportError for an installed package, which has none (a
    module built against another tree's _core must not take its plans)."""
    tree_bench = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(smoothffd.__file__)))),
                              "bench")
    if "sffd_bench" in sys.modules:
        return sys.modules["sffd_bench"]
    found = [f for f in (os.listdir(tree_bench) if os.path.isdir(tree_bench) else [])
             if f.startswith("sffd_bench.") and f.endswith(".so")]
    if not found:
        raise ImportError(f"no sffd_bench in {tree_bench} (bench/native is built by development builds)")
    sys.path.insert(0, tree_bench)
    try:
        import sffd_bench
    finally:
        sys.path.remove(tree_bench)
    return sffd_bench


def upsampling_baseline(plan, points, normals, pieces):
    """The paper's uniform upsampling baseline (bench/native's, or a tree's own from before)."""
    if hasattr(_core, "CudaUpsamplingBaseline"):
        return _core.CudaUpsamplingBaseline(plan, points, normals, pieces)
    return bench_module().UpsamplingBaseline(plan, points, normals, pieces)


def cpu_time(plan, vals, reps):
    ev = _core.CpuEvaluator(plan)
    ev.evaluate(vals)
    ts, stages = [], []
    for _ in range(reps):
        t0 = time.perf_counter()
        _, _, st = ev.evaluate(vals)
        ts.append((time.perf_counter() - t0) * 1e3)
        stages.append(st)
    return float(np.median(ts)), stages[int(np.argsort(ts)[len(ts) // 2])], ev.threads


# The inline kernel's other modes at W1 L = 10, each reached the way a user's plan or GPU
# reaches it: (label, shared_memory_limit, lattice degree). A consumer GPU's shared memory a
# block (99 KB sm_86/89, 64 KB sm_75, 48 KB the least any CUDA device has), and a degree-4
# lattice (5 terms an axis: the global mode's kMaxTerms kernel).
MODES = [("99 KB", 99 * 1024, 2), ("64 KB", 64 * 1024, 2), ("48 KB", 48 * 1024, 2), ("degree 4", 0, 4)]


def gpu_case(name, P, F, N, lat, level, iters, cpu_reps, log, variants=False):
    mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
    t0 = time.perf_counter()
    plan = smoothffd.Deformer(mesh, lat, level=level, device="cpu").plan
    plan_ms = (time.perf_counter() - t0) * 1e3
    vals = values(lat)
    row = dict(case=name, level=level, input_triangles=int(len(F)), patches=plan.patches,
               samples=plan.samples, output_vertices=plan.output_vertices,
               output_triangles=plan.output_triangles, render_vertices=plan.render_vertex_count,
               plan_ms=plan_ms)
    for path in ("cublas", "fused"):
        row[path] = benchmark(plan, path, 0, vals, iters)
        log(f"  {name} L={level} {path}: {row[path]}")
    row["kernel"] = row["fused"]["kernel"]
    if variants:
        for label, limit, degree in MODES:
            plan2, lat2 = plan, lat
            if degree != 2:
                lat2 = lattice_for(P, np.random.default_rng(2015), degree=(degree,) * 3)
                plan2 = smoothffd.Deformer(mesh, lat2, level=level, device="cpu").plan
            b = benchmark(plan2, "fused", limit, values(lat2), iters)
            row.setdefault("modes", {})[label] = b
            log(f"  {name} L={level} fused {label}: {b}")
    # Whole frame with the copy back to numpy (corner normals gathered on the host).
    ev = _core.CudaEvaluator(plan, "fused")
    row["output_bytes"] = ev.output_bytes
    row["device_bytes"] = ev.device_bytes
    ev.evaluate(vals)
    ts = []
    for _ in range(5):
        t0 = time.perf_counter()
        _, _, st = ev.evaluate(vals)  # fresh numpy arrays every time (as deform() does)
        ts.append((time.perf_counter() - t0) * 1e3)
    row["evaluate_with_copy_back_ms"] = float(np.median(ts))
    row["evaluate_stages"] = st
    if cpu_reps:
        row["cpu_ms"], row["cpu_stages"], row["cpu_threads"] = cpu_time(plan, vals, cpu_reps)
    del ev
    return row, plan


def pn_upsample(P, F, N, level):
    """PN triangles (Vlachos et al.) of the mesh, welded tessellation points at `level`:
    vertices once, each edge's inner points once, each face's interior points once; the
    normal is the normalized linear interpolation of the vertex normals."""
    L = level
    e_all = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    key = np.sort(e_all, axis=1)
    edges, inv = np.unique(key, axis=0, return_inverse=True)
    pts, nrm = [P], [N]

    def bcoef(a, b):  # PN control point near a on edge a -> b
        w = np.sum((P[b] - P[a]) * N[a], axis=1, keepdims=True)
        return (2 * P[a] + P[b] - w * N[a]) / 3

    a, b = edges[:, 0], edges[:, 1]
    c_ab, c_ba = bcoef(a, b), bcoef(b, a)
    for m in range(1, L):
        t = m / L
        pts.append((1 - t) ** 3 * P[a] + 3 * (1 - t) ** 2 * t * c_ab + 3 * (1 - t) * t ** 2 * c_ba + t ** 3 * P[b])
        nrm.append((1 - t) * N[a] + t * N[b])
    i0, i1, i2 = F[:, 0], F[:, 1], F[:, 2]
    b210, b120 = bcoef(i0, i1), bcoef(i1, i0)
    b021, b012 = bcoef(i1, i2), bcoef(i2, i1)
    b102, b201 = bcoef(i2, i0), bcoef(i0, i2)
    E = (b210 + b120 + b021 + b012 + b102 + b201) / 6
    Vc = (P[i0] + P[i1] + P[i2]) / 3
    b111 = E + (E - Vc) / 2
    for j in range(1, L):
        for i in range(1, L - j):
            u, v = i / L, j / L
            w = 1 - u - v
            x = (w ** 3 * P[i0] + u ** 3 * P[i1] + v ** 3 * P[i2] + 3 * w * w * u * b210 + 3 * w * u * u * b120
                 + 3 * u * u * v * b021 + 3 * u * v * v * b012 + 3 * w * v * v * b102 + 3 * w * w * v * b201
                 + 6 * w * u * v * b111)
            pts.append(x)
            nrm.append(w * N[i0] + u * N[i1] + v * N[i2])
    pts = np.concatenate(pts)
    nrm = np.concatenate(nrm)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pts, nrm


def pieces_of(lat, pts):
    s = pts @ lat.object_to_param[:, :3].T + lat.object_to_param[:, 3]
    planes = lat.knot_planes()
    packed = np.zeros(len(pts), np.uint32)
    for a in range(3):
        idx = np.searchsorted(planes[a], s[:, a], side="right")
        packed |= idx.astype(np.uint32) << np.uint32(10 * a)
    return packed


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="bench_gpu.json")
    ap.add_argument("--iters", type=int, default=200)
    ap.add_argument("--quick", action="store_true", help="W1 at L=10 only, no 1M mesh")
    ap.add_argument("--no-1m", action="store_true")
    args = ap.parse_args()
    usable, why = smoothffd.cuda_status()
    if not usable:
        sys.exit(f"no usable CUDA device: {why}")
    lines = []

    def log(s):
        print(s, flush=True)
        lines.append(s)

    rng = np.random.default_rng(2015)
    result = dict(device=why, date=time.strftime("%Y-%m-%d %H:%M:%S"), w1=[], big=None, baseline=[])
    P, F, N = torus(167, 140)  # 46,760 triangles (paper Table 1: 46,742)
    lat = lattice_for(P, rng)
    levels = (10,) if args.quick else (4, 10, 12, 14, 16)
    plans = {}
    for L in levels:
        row, plan = gpu_case("W1", P, F, N, lat, L, args.iters, 3 if L in (4, 10, 16) else 0, log, L == 10)
        result["w1"].append(row)
        plans[L] = plan
    # Paper Table 5: smooth FFD vs uniform upsampling (PN + every sample deformed) at the same
    # number of sub-triangles a patch.
    for L in (10, 12, 14, 16):
        if L not in plans:
            continue
        if not hasattr(_core, "CudaUpsamplingBaseline"):
            try:
                bench_module()
            except ImportError as e:
                log(f"  baseline L={L}: skipped (bench/native's sffd_bench not built: {e})")
                continue
        pts, nrm = pn_upsample(P, F, N, L)
        base = upsampling_baseline(plans[L], pts.astype(np.float32), nrm.astype(np.float32), pieces_of(lat, pts))
        bt = base.benchmark(values(lat), args.iters)
        sffd = next(r for r in result["w1"] if r["level"] == L)
        best = min(sffd["fused"]["total_events"], sffd["cublas"]["total_events"])
        result["baseline"].append(dict(level=L, sub_triangles=L * L, points=base.points,
                                       upsampling_ms=bt["deform_samples"], smooth_ffd_ms=best,
                                       ratio=best / bt["deform_samples"]))
        log(f"  baseline L={L}: {result['baseline'][-1]}")
        del base
    if not (args.quick or args.no_1m):
        P2, F2, N2 = torus(1000, 500)  # 1,000,000 triangles
        lat2 = lattice_for(P2, rng)
        row, _ = gpu_case("1M", P2, F2, N2, lat2, 10, max(args.iters // 4, 20), 2, log)
        result["big"] = row
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)

    # Summary
    print("\n=== summary (ms, medians; device:", why, ")")
    # events: host-paced frames (the launch's host latency included); queued: the same behind a
    # kernel that holds the stream until the frame is queued (device time only); graph: CUDA
    # graph replays back to back. x_floor: each of the three over the floor.
    hdr = (f"{'case':6} {'L':>3} {'tris_out':>10} {'path':7} {'stages':60} {'events':>8} {'queued':>8} {'graph':>8} "
           f"{'floor':>7} {'x_floor (ev/q/gr)':>18} {'cpu':>8} {'cpu/gpu':>8}")
    print(hdr)
    for row in result["w1"] + ([result["big"]] if result["big"] else []):
        for path in ("fused", "cublas"):
            b = row[path]
            st = " ".join(f"{k}={v:.4f}" for k, v in b.items()
                          if k not in ("total_events", "total_events_queued", "total_graph", "d2d_copy_ms",
                                       "d2d_bandwidth_GBps", "floor_ms", "output_bytes", "kernel"))
            cpu = row.get("cpu_ms", float("nan"))
            best = min(b["total_events"], b["total_graph"])
            fl = b["floor_ms"]
            xf = f"{b['total_events'] / fl:.2f}/{b['total_events_queued'] / fl:.2f}/{b['total_graph'] / fl:.2f}"
            print(f"{row['case']:6} {row['level']:>3} {row['output_triangles']:>10} {path:7} {st:60} "
                  f"{b['total_events']:8.4f} {b['total_events_queued']:8.4f} {b['total_graph']:8.4f} {fl:7.4f} "
                  f"{xf:>18} {cpu:8.2f} {cpu / best:8.1f}")
        print(f"       output {row['output_bytes'] / 1e6:.1f} MB (N {row['output_vertices']}, R {row['render_vertices']}), "
              f"d2d {row['fused']['d2d_bandwidth_GBps']:.0f} GB/s, "
              f"evaluate()+copy back {row['evaluate_with_copy_back_ms']:.2f} ms "
              f"({', '.join(f'{k}={v:.2f}' for k, v in row['evaluate_stages'].items())}), plan {row['plan_ms']:.0f} ms")
        print(f"       fused path kernel: {row['kernel']}")
        for key, b in row.get("modes", {}).items():
            print(f"       {key:9} {b['kernel']:17} events {b['total_events']:.4f} "
                  f"queued {b['total_events_queued']:.4f} graph {b['total_graph']:.4f}")
    for b in result["baseline"]:
        print(f"baseline {b['sub_triangles']:>3} sub-tris/patch: upsampling {b['upsampling_ms']:.4f} ms "
              f"({b['points']} pts), smooth FFD {b['smooth_ffd_ms']:.4f} ms, ratio {b['ratio']:.3f} (paper 0.82 at 256)")


if __name__ == "__main__":
    main()
