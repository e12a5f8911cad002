"""Adaptive tessellation against uniform levels: triangles, time and true error (CPU or CUDA).

    PYTHONPATH=python:tests:bench python3 bench/bench_adaptive.py [--workloads w1 vase suzanne ...]
        [--levels 2 3 4 6 8 10] [--repeats 5] [--error-patches 8000] [--device cpu|cuda] [--json PATH]

For each workload and uniform level L: the uniform output's true tessellation error e_L (the
largest distance between its triangles and the cubic patches they approximate, by dense
sampling: tests/tessellation_error.py's uniform_error, 28 points a triangle), then the adaptive
tessellation at tolerance t = e_L (Deformer(..., tolerance=t)), its triangles, its own worst
true error (tessellation_error.adaptive_error) over t (also with the triangles' corners computed
in float64 on their patches: near 1e-6 of the diagonal the float32 output positions' own
rounding is a visible part of t), and the time of a frame of each (median of
--repeats frames, uniform and adaptive alternating in the same process; fresh result arrays,
normals per corner). The patches do not depend on L, so both tessellate the same surface.

Workloads with more than --error-patches patches (W1: about 54k) measure the errors on a
random subset of that many patches (the same subset for e_L and for the adaptive triangles
inside it); the triangle counts and times are always the whole mesh's. The output says so.

Workloads: w1 (bench/workloads.py), the corpus of tests/data/real under a random moderate
5x5x5 lattice (seed 7, as tests/test_adaptive.py), and the demo scenes whose meshes are plain
numpy (blender_scenes/shapes.py): vase, chess, teapot, knotbox, cube, each with its scene's
lattice as smoothffd.BlenderLattice (Blender's B-spline lattice, exactly) and the scene's sharp
edges as split normals. The suzanne and character scenes need Blender (bpy) and are skipped.
Prints numbers; asserts nothing about time.
"""

import argparse
import datetime
import json
import math
import os
import platform
import statistics
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
for p in (HERE, os.path.join(ROOT, "tests"), os.path.join(ROOT, "blender_scenes")):
    if p not in sys.path:
        sys.path.insert(0, p)

import numpy as np  # noqa: E402

import shapes  # noqa: E402
import smoothffd  # noqa: E402
import tessellation_error as ta  # noqa: E402
import test_real_meshes as real  # noqa: E402
from smoothffd import _core  # noqa: E402
from smoothffd.deform import _control_values_f32  # noqa: E402
from workloads import w1_lattice, w1_mesh  # noqa: E402

REAL = ["cube", "uv_sphere", "cylinder", "torus", "suzanne", "suzanne_subsurf", "goblet",
        "figure", "rock"]
# The demo scenes (blender_scenes/<name>.py build()): shape, lattice points, deformation of
# the lattice's rest points in [-0.5, 0.5]^3, margin of the lattice box around the mesh.
SCENES = {
    "vase": (lambda: shapes.vase(segments=12), (3, 3, 4),
             lambda co: shapes.bend(shapes.bulge(co, 0.4), 0.25, towards=0), 0.08),
    "chess": (lambda: shapes.chess_pawn(segments=16), (3, 3, 5),
              lambda co: shapes.twist(shapes.bend(co, 0.3, towards=0), 30), 0.08),
    "teapot": (lambda: shapes.teapot(n=3), (4, 3, 3),
               lambda co: shapes.twist(shapes.bend(co, 0.3, axis=0, towards=2), 35, axis=0), 0.08),
    "knotbox": (lambda: shapes.slab((2.4, 1.6, 0.3)), (7, 5, 2),
                lambda co: shapes.wave(shapes.wave(co, 0.9, 1.0, axis=0, up=2), 0.5, 0.6, axis=1, up=2),
                0.02),
    "cube": (lambda: shapes.grid_cube(2), (3, 3, 3),
             lambda co: shapes.bulge_twist(co, bulge=0.5, twist_degrees=60), 0.0),
}
BLENDER_ONLY = ["the suzanne scene (bpy's monkey primitive; tests/data/real/suzanne.obj is Suzanne "
                "exported from Blender)", "the character scene (a body built and rigged in bpy)"]
DEFAULT = ["w1", "vase", "chess", "teapot", "knotbox", "suzanne", "figure", "goblet", "torus",
           "rock", "suzanne_subsurf"]


def split_normals(positions, polygons, sharp):
    """Per-corner normals as Blender gives a smooth-shaded mesh with sharp edges: each corner
    the corner-angle-weighted mean of the face normals around its vertex reachable without
    crossing a sharp edge (or a boundary)."""
    P = np.asarray(positions, float)
    fn = shapes.face_normals(P, polygons)
    corners = []  # (face, vertex, prev, next)
    for f, poly in enumerate(polygons):
        n = len(poly)
        for k in range(n):
            corners.append((f, poly[k], poly[k - 1], poly[(k + 1) % n]))
    by_vertex = {}
    for c, (f, v, a, b) in enumerate(corners):
        by_vertex.setdefault(v, []).append(c)
    out = np.zeros((len(corners), 3))
    for v, cs in by_vertex.items():
        # union the corners of v whose faces share a smooth edge (v, x)
        parent = {c: c for c in cs}

        def root(c):
            while parent[c] != c:
                parent[c] = parent[parent[c]]
                c = parent[c]
            return c

        by_edge = {}
        for c in cs:
            _, _, a, b = corners[c]
            for x in (a, b):
                by_edge.setdefault(x, []).append(c)
        for x, group in by_edge.items():
            if len(group) == 2 and tuple(sorted((v, x))) not in sharp:
                parent[root(group[0])] = root(group[1])
        acc = {}
        for c in cs:
            f, _, a, b = corners[c]
            e1, e2 = P[a] - P[v], P[b] - P[v]
            ang = math.acos(np.clip(e1 @ e2 / (np.linalg.norm(e1) * np.linalg.norm(e2) + 1e-300), -1, 1))
            acc[root(c)] = acc.get(root(c), 0) + ang * fn[f]
        for c in cs:
            n = acc[root(c)]
            out[c] = n / (np.linalg.norm(n) + 1e-300)
    return out


def scene_workload(name):
    shape_fn, points, deform, margin = SCENES[name]
    s = shape_fn()
    cv, fo = shapes.flat(s)
    mesh = smoothffd.Mesh(s["positions"], (cv, fo),
                          corner_normals=split_normals(s["positions"], s["polygons"], s.get("sharp", set())))
    lo, hi = s["positions"].min(0), s["positions"].max(0)
    centre, size = (lo + hi) / 2, np.maximum((hi - lo) * (1 + 2 * margin), 1e-3)
    # Blender's rest points of a new lattice: a grid over [-0.5, 0.5] on each axis with 2+ points.
    axes = [np.linspace(-0.5, 0.5, n) if n > 1 else np.zeros(1) for n in points]
    rest = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    m = np.eye(4)
    m[:3, :3] = np.diag(size)
    m[:3, 3] = centre
    lattice = smoothffd.BlenderLattice(rest, deform(rest), "BSPLINE", lattice_to_object=m)
    return mesh, lattice


def workload(name):
    """(mesh, lattice, description)."""
    if name == "w1":
        return w1_mesh(), w1_lattice(0), "W1: torus, 5x5x5 quadratic lattice, random 5% displacements"
    if name in SCENES:
        mesh, lat = scene_workload(name)
        return mesh, lat, f"scene {name} (blender_scenes/{name}.py's mesh and B-spline lattice)"
    if name in REAL:
        mesh = real.load(name)
        return mesh, real._random_moderate(mesh, 7), f"tests/data/real/{name}.obj, random moderate lattice (seed 7)"
    raise SystemExit(f"unknown workload {name!r}: w1, {', '.join(SCENES)}, {', '.join(REAL)}")


def diagonal(mesh):
    return float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))


def patch_control(deformer, lattice):
    """The cubic patches (P, 10, 3) of this frame (the same for every level)."""
    r = _core.adaptive_frame(deformer.plan, _control_values_f32(lattice), 1e30, 1, 0, False,
                             None, True)
    return r["patch_control"]


def adaptive_worst(deformer, lattice, tol, subset):
    """The adaptive frame's worst true error (dense sampling) over the triangles of the patches
    in subset (None: all); the same with the triangles' corners evaluated on their patches in
    float64 instead of the output's float32 positions (what the tessellation itself decides,
    without the positions' rounding); its max and median patch level."""
    r = _core.adaptive_frame(deformer.plan, _control_values_f32(lattice), tol, deformer.max_level,
                             0, True, None, True)
    if subset is not None:
        keep = subset[r["triangle_patch"]]
        r = dict(r, triangles=r["triangles"][keep], corner_bary=r["corner_bary"][keep],
                 triangle_patch=r["triangle_patch"][keep])
    err = ta.adaptive_error(r)
    cp, cb, tp = r["patch_control"].astype(np.float64), r["corner_bary"].astype(np.float64), r["triangle_patch"]
    corners = np.einsum("tck,tkr->tcr", ta.cubic_basis(cb), cp[tp])
    n = len(corners)
    pos = corners.reshape(-1, 3)
    err64 = ta.adaptive_error(dict(r, positions=pos, triangles=np.arange(3 * n).reshape(n, 3)))
    return (float(err.max()), float(err64.max()), int(r["patch_level"].max()),
            float(np.median(r["patch_level"])))


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return (time.perf_counter() - t0) * 1e3, out


def run_workload(name, levels, repeats, error_patches, rng_seed=1, device="cpu"):
    mesh, lat, desc = workload(name)
    diag = diagonal(mesh)
    ad = smoothffd.Deformer(mesh, lat, device=device, tolerance=1.0)
    cp = patch_control(ad, lat)
    P = len(cp)
    subset, sel = None, slice(None)
    if P > error_patches:
        idx = np.sort(np.random.default_rng(rng_seed).choice(P, error_patches, replace=False))
        subset = np.zeros(P, bool)
        subset[idx] = True
        sel = idx
    print(f"\n{name} on {ad.device}: {desc}; {mesh.face_count} faces, {P} patches, bounding-box diagonal {diag:.4g}"
          + (f"; errors measured on {error_patches} random patches of {P}" if subset is not None else ""))
    print(f"{'L':>3} {'t = e_L':>10} {'t/diag':>9} {'uni tris':>10} {'uni ms':>8} {'ada tris':>10} "
          f"{'ada/uni':>7} {'ada ms':>8} {'worst/t':>7} {'f64/t':>6} {'levels':>7}")
    rows = []
    for L in levels:
        e_L = ta.uniform_error(cp[sel], L)
        uni = smoothffd.Deformer(mesh, lat, level=L, device=device)
        ad.tolerance = e_L  # the plan does not depend on the tolerance: one adaptive Deformer
        uni.deform(lat)
        ad.deform(lat)      # warm-up, untimed
        tu, ta_ = [], []
        for _ in range(repeats):  # alternating: the machine's drift hits both alike
            ms, ru = timed(lambda: uni.deform(lat))
            tu.append(ms)
            ms, ra = timed(lambda: ad.deform(lat))
            ta_.append(ms)
        worst, worst64, maxlev, medlev = adaptive_worst(ad, lat, e_L, subset)
        T_u, T_a = len(ru.triangles), len(ra.triangles)
        row = dict(workload=name, device=ad.device, description=desc, faces=mesh.face_count, patches=P, diagonal=diag,
                   error_patches=int(P if subset is None else error_patches), level=L,
                   uniform_error=e_L, tolerance=e_L, tolerance_rel=e_L / diag,
                   uniform_triangles=T_u, uniform_ms=statistics.median(tu),
                   adaptive_triangles=T_a, ratio=T_a / T_u, adaptive_ms=statistics.median(ta_),
                   adaptive_error=worst, adaptive_error_over_t=worst / e_L,
                   adaptive_error_f64_corners=worst64,
                   adaptive_max_patch_level=maxlev, adaptive_median_patch_level=medlev,
                   tolerance_met=bool(ra.stats["tolerance_met"]), repeats=repeats)
        rows.append(row)
        print(f"{L:>3} {e_L:10.3g} {e_L / diag:9.2e} {T_u:>10} {row['uniform_ms']:8.1f} {T_a:>10} "
              f"{row['ratio']:7.2f} {row['adaptive_ms']:8.1f} {worst / e_L:7.2f} {worst64 / e_L:6.2f} {medlev:>3.0f}/{maxlev:<3}",
              flush=True)
        del uni, ru, ra
    return rows


def commit():
    """The checkout's commit, "-dirty" with uncommitted changes (the module may be built from them)."""
    try:
        return subprocess.run(["git", "describe", "--always", "--dirty"], capture_output=True,
                              text=True, cwd=ROOT).stdout.strip() or "?"
    except OSError:
        return "?"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--workloads", nargs="+", default=DEFAULT,
                    help="w1, " + ", ".join(SCENES) + ", " + ", ".join(REAL))
    ap.add_argument("--levels", type=int, nargs="+", default=[2, 3, 4, 6, 8, 10])
    ap.add_argument("--w1-levels", type=int, nargs="+", default=None,
                    help="levels for w1 (default: --levels)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--error-patches", type=int, default=8000,
                    help="measure errors on at most this many random patches of a workload")
    ap.add_argument("--device", choices=("cpu", "cuda"), default="cpu",
                    help="where both the uniform and the adaptive frames run (cuda: raises without a GPU)")
    ap.add_argument("--json", metavar="PATH", help="write the rows as JSON")
    a = ap.parse_args()
    t0 = time.perf_counter()
    started = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    where = (f"CUDA: {smoothffd.cuda_status()[1]}" if a.device == "cuda" else
             f"CPU: {platform.machine()}, {os.cpu_count()} cores")
    print(f"Adaptive vs uniform tessellation, {where}; "
          f"smoothffd {getattr(smoothffd, '__version__', '?')}; median of {a.repeats} frames, "
          "uniform and adaptive alternating")
    print("t = e_L: the uniform level-L output's true max error (dense sampling); adaptive runs at "
          "tolerance t. worst/t: the adaptive output's true max error over t; f64/t: the same with its "
          "triangles' corners evaluated on their patches in float64 (without the float32 output "
          "positions' rounding). levels: the adaptive patches' median/max interior level.")
    print("Skipped (need Blender): " + "; ".join(BLENDER_ONLY))
    rows = []
    for name in a.workloads:
        levels = a.w1_levels if (name == "w1" and a.w1_levels) else a.levels
        rows += run_workload(name, levels, a.repeats, a.error_patches, device=a.device)
    print(f"\ntotal {time.perf_counter() - t0:.0f} s")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(dict(date=started, commit=commit(), device=a.device, machine=platform.machine(),
                           cores=os.cpu_count(), repeats=a.repeats,
                           error_patches=a.error_patches, skipped=BLENDER_ONLY, rows=rows), f, indent=1)


if __name__ == "__main__":
    main()
