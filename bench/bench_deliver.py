"""The frame as a user receives it: `Deformer.deform` into numpy, per layout, against the
time the bytes of the compact output take to cross the bus into page-locked memory.

    PYTHONPATH=python python3 bench/bench_deliver.py [--device cuda] [--levels 10] [--repeats 21]

Rows (median ms over the repeats, layouts alternating so the machine's drift hits each alike):
  corners fresh      deform()                      per-corner normals (T, 3, 3), new arrays
  corners reuse      deform(out=previous)
  compact fresh      deform(layout="compact")      render-vertex normals (R, 3), new arrays
  compact reuse      deform(layout="compact", out=previous)
  compact pinned     the same into page-locked arrays (CUDA only; cudaHostAlloc via ctypes)
On CUDA the last row's copy_back stage is the pure device-to-host transfer of the compact
output into pinned memory: the floor a delivered frame is measured against.
"""

import argparse
import ctypes
import ctypes.util
import dataclasses
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import smoothffd  # noqa: E402
from workloads import w1_lattice, w1_mesh  # noqa: E402


def pinned_empty(shape, keep):
    """A float32 array in page-locked memory (the CUDA runtime's cudaHostAlloc), or None."""
    for name in ("libcudart.so", "libcudart.so.13", "libcudart.so.12",
                 "/usr/local/cuda/lib64/libcudart.so"):
        try:
            rt = ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        return None
    n = int(np.prod(shape)) * 4
    ptr = ctypes.c_void_p()
    if rt.cudaHostAlloc(ctypes.byref(ptr), ctypes.c_size_t(n), ctypes.c_uint(0)) != 0:
        return None
    keep.append((rt, ptr))
    buf = (ctypes.c_float * (n // 4)).from_address(ptr.value)
    return np.frombuffer(buf, dtype=np.float32).reshape(shape)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--device", default="cuda", choices=smoothffd.DEVICES[1:])   # not "auto"
    ap.add_argument("--levels", type=int, nargs="+", default=[10])
    ap.add_argument("--repeats", type=int, default=21)
    args = ap.parse_args()
    mesh = w1_mesh()
    keep = []
    for L in args.levels:
        d = smoothffd.Deformer(mesh, w1_lattice(0), level=L, device=args.device)
        p = d.plan
        nbytes = 12 * (p.output_vertices + p.render_vertex_count)
        rows = ["corners fresh", "corners reuse", "compact fresh", "compact reuse"]
        last = {}
        pinned = None
        if d.device == "cuda":
            first = d.deform(layout="compact")
            pos = pinned_empty(first.positions.shape, keep)
            nrm = pinned_empty(first.normals.shape, keep)
            if pos is not None and nrm is not None:
                pinned = dataclasses.replace(first, positions=pos, normals=nrm)
                rows.append("compact pinned")
        times = {r: [] for r in rows}
        stages = {r: [] for r in rows}
        for i in range(args.repeats):
            pts = w1_lattice(i + 1).control_points
            for r in rows:
                layout = r.split()[0]
                out = pinned if r == "compact pinned" else last.get(r) if r.endswith("reuse") else None
                t0 = time.perf_counter()
                res = d.deform(pts, out=out, layout=layout)
                times[r].append((time.perf_counter() - t0) * 1e3)
                stages[r].append(res.stats["stage_ms"])
                last[r] = res
        print(f"W1 L={L} on {d.device} ({d.device_message}): T={p.output_triangles} N={p.output_vertices} "
              f"R={p.render_vertex_count}; compact output {nbytes / 2**20:.1f} MiB, per-corner "
              f"{(12 * p.output_vertices + 36 * p.output_triangles) / 2**20:.1f} MiB")
        for r in rows:
            st = {k: statistics.median(s[k] for s in stages[r]) for k in stages[r][0]}
            print(f"  {r:15s} {statistics.median(times[r]):8.3f} ms (min {min(times[r]):.3f})  "
                  + ", ".join(f"{k} {v:.3f}" for k, v in st.items()))
        if "compact pinned" in rows:
            floor = statistics.median(s["copy_back"] for s in stages["compact pinned"])
            best = statistics.median(times["compact reuse"])
            print(f"  floor (compact bytes into pinned memory, device events): {floor:.3f} ms "
                  f"= {nbytes / floor / 1e6:.1f} GB/s; compact reuse / floor = {best / floor:.2f}; "
                  f"compact pinned / floor = {statistics.median(times['compact pinned']) / floor:.2f}")


if __name__ == "__main__":
    main()
