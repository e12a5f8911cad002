"""Writes docs/results.md: the paper's Tables 2-4 (approximation errors) reproduced beside the
paper's values, convergence plots, and timings like Tables 1, 5 and 6 (CPU here; the GPU
figures are taken from docs/benchmarks.md when it exists). Run through scripts/report.sh.

    PYTHONPATH=python python3 scripts/report.py [--quick] [--no-bench] [--adaptive-json PATH]
                                                [--adaptive-only]

--adaptive-only rewrites only the "Adaptive tessellation" section (bench/bench_adaptive.py's
table, plot and wireframes), e.g. from an earlier run's JSON:

    PYTHONPATH=python:tests:bench python3 bench/bench_adaptive.py --json /tmp/adaptive.json \
        > /tmp/adaptive.txt
    bash scripts/report.sh --adaptive-only --adaptive-json /tmp/adaptive.json

Errors follow the paper's definitions (sec. 6.3), measured by tests/reference.py:
geometry = distance between each output vertex and the exact FFD image of its rest point on
the flat input face; normal = angle between each output corner normal and the exact deformed
normal of the input's normal field at that point (cof(J) n); volume = the output mesh's
enclosed volume against the integral of det J over the cube.
"""
import argparse
import datetime
import json
import math
import os
import platform
import re
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
for p in ("python", "tests", "blender_scenes", "bench", "scripts"):
    sys.path.insert(0, os.path.join(ROOT, p))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import reference as ref  # noqa: E402
import shapes  # noqa: E402
import smoothffd  # noqa: E402
from meshes import bulge_twist, grid_cube  # noqa: E402

DOCS = os.path.join(ROOT, "docs")
IMAGES = os.path.join(DOCS, "images")

PAPER = {  # Tables 2, 3, 4: columns 1-3 of Fig. 14
    "cube2": dict(geometry_avg=0.00448184, geometry_max=0.0274765, normal_avg_deg=0.394331,
                  normal_max_deg=4.17587, volume_rel=0.00023107),
    "cube3": dict(geometry_avg=0.00297672, geometry_max=0.0261029, normal_avg_deg=0.387851,
                  normal_max_deg=5.23632, volume_rel=0.000304927),
    "teapot2": dict(geometry_avg=0.000906093, geometry_max=0.00710446, normal_avg_deg=0.566609,
                    normal_max_deg=23.3726, volume_rel=None),
}


# --- the test objects -------------------------------------------------------------------------

def cube_case(degree, shape=None, magnitude=1.0):
    mesh = grid_cube(2)
    shape = shape or (degree + 1,) * 3
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=shape, degree=degree)
    lat = bulge_twist(lat, bulge=0.25 * magnitude, twist_degrees=45 * magnitude)
    fn = ref.face_normals_of_polygons(mesh.positions, (mesh.corner_vertices, mesh.face_offsets))
    return mesh, lat, ("faces", fn)


_teapots = {}


def teapot_case(n=6, degree=2, magnitude=1.0):
    if n not in _teapots:
        _teapots[n] = shapes.teapot(n=n, normalize=True, triangles=True)
    t = _teapots[n]
    tris = np.array(t["polygons"], dtype=np.int64)
    vn = t["vertex_normals"]
    mesh = smoothffd.Mesh(t["positions"], tris, corner_normals=vn[tris.reshape(-1)])
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(degree + 1,) * 3,
                                            degree=degree)
    lat = bulge_twist(lat, bulge=0.25 * magnitude, twist_degrees=45 * magnitude)
    return mesh, lat, ("vertices", (t["positions"], tris, vn)), t


def _turned(n):
    """Corners of the n x n teapot whose shading normal the plan turned toward the geometry."""
    mesh, lat, _, _ = teapot_case(n)
    return smoothffd.Deformer(mesh, lat, level=1, device="cpu").plan.turned_normals


def exact_evaluator(lat, independent=True):
    if independent:
        return ref.BSplineReference(lat.control_points, lat.degree, None, lat.box_min,
                                    lat.box_max).evaluate
    return lat.evaluate   # the core's double-precision lattice (checked against the reference)


def errors(res, normals_kind, lattice_eval):
    """Paper-style errors. For flat-faced input (the cube) the exact normal is cof(J) n_face
    (tests/reference.smooth_ffd_errors); for smooth input (the teapot) it is cof(J) applied
    to the input's linear normal field (the vertex normals interpolated over the input
    triangle), the field the paper deforms."""
    kind, data = normals_kind
    if kind == "faces":
        return ref.smooth_ffd_errors(res, data, lattice_eval)
    P, tris, vn = data
    pos = np.asarray(res.positions, np.float64)
    rest = np.asarray(res.rest_positions, np.float64)
    # One exact evaluation per output vertex (the teapot lies in one knot box, where J is
    # continuous, so a corner needs no nudge into its own triangle as on the cube).
    exact, J = lattice_eval(rest)
    gerr = np.linalg.norm(pos - exact, axis=1)
    out_tris = np.asarray(res.triangles)
    fidx = np.asarray(res.face_index)
    crest = rest[out_tris].reshape(-1, 3)
    tri = P[tris[fidx]]                                      # (T, 3, 3) input triangle
    a, b, c = (np.repeat(tri[:, k], 3, axis=0) for k in range(3))
    v0, v1, v2 = b - a, c - a, crest - a
    d00, d01, d11 = (np.einsum("nd,nd->n", x, y) for x, y in ((v0, v0), (v0, v1), (v1, v1)))
    d20, d21 = np.einsum("nd,nd->n", v2, v0), np.einsum("nd,nd->n", v2, v1)
    den = d00 * d11 - d01 * d01
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    w0 = 1 - w1 - w2
    vnt = np.repeat(vn[tris[fidx]], 3, axis=0)               # (3T, 3, 3)
    n = w0[:, None] * vnt[:, 0] + w1[:, None] * vnt[:, 1] + w2[:, None] * vnt[:, 2]
    nex = np.einsum("nrc,nc->nr", ref.cofactor(np.asarray(J)[out_tris.reshape(-1)]), n)
    nex /= np.linalg.norm(nex, axis=1, keepdims=True)
    got = np.asarray(res.corner_normals, np.float64).reshape(-1, 3)
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.einsum("nd,nd->n", got, nex), -1, 1)))
    return dict(geometry_avg=float(gerr.mean()), geometry_max=float(gerr.max()),
                normal_avg_deg=float(ang.mean()), normal_max_deg=float(ang.max()),
                volume=ref.mesh_volume(pos, out_tris))


def surface_errors(res, case, lattice_eval):
    """Teapot against the FFD of the exact Bezier surface (the paper's reference: "original
    FFD of uniformly sampled points and normals"): each output corner's rest point is mapped
    to the surface through its input triangle's patch parameters (barycentric interpolation
    of the corners' (u, v)); geometry = distance to F(S(u, v)) (per output vertex), normal =
    angle to cof(J) n_S (per corner)."""
    (_, (P, tris, _vn)), t = case[2], case[3]
    rest = np.asarray(res.rest_positions, np.float64)
    out_tris = np.asarray(res.triangles)
    fidx = np.repeat(np.asarray(res.face_index), 3)
    cverts = out_tris.reshape(-1)
    crest = rest[cverts]
    tri = P[tris[fidx]]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, crest - a
    d00, d01, d11 = (np.einsum("nd,nd->n", x, y) for x, y in ((v0, v0), (v0, v1), (v1, v1)))
    d20, d21 = np.einsum("nd,nd->n", v2, v0), np.einsum("nd,nd->n", v2, v1)
    den = d00 * d11 - d01 * d01
    w = np.stack([1 - (d11 * d20 - d01 * d21) / den - (d00 * d21 - d01 * d20) / den,
                  (d11 * d20 - d01 * d21) / den, (d00 * d21 - d01 * d20) / den], -1)
    prm = np.asarray(t["corner_params"], np.float64)[fidx]     # (3T, 3, 3): (patch, u, v)
    uv = np.einsum("nk,nkd->nd", w, prm[:, :, 1:])
    S, N = shapes.teapot_surface(prm[:, 0, 0].astype(int), uv[:, 0], uv[:, 1], t["center"],
                                 t["scale"])
    key, inv = np.unique(np.round(S, 9), axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    F, J = lattice_eval(key)
    F, J = np.asarray(F)[inv], np.asarray(J)[inv]
    nex = np.einsum("nrc,nc->nr", ref.cofactor(J), N)
    nex /= np.linalg.norm(nex, axis=1, keepdims=True)
    got = np.asarray(res.corner_normals, np.float64).reshape(-1, 3)
    got /= np.linalg.norm(got, axis=1, keepdims=True)
    ang = np.degrees(np.arccos(np.clip(np.einsum("nd,nd->n", got, nex), -1, 1)))
    first = np.unique(cverts, return_index=True)[1]
    gerr = np.linalg.norm(np.asarray(res.positions, np.float64)[cverts[first]] - F[first], axis=1)
    return dict(geometry_avg=float(gerr.mean()), geometry_max=float(gerr.max()),
                normal_avg_deg=float(ang.mean()), normal_max_deg=float(ang.max()))


def exact_volume(lat):
    g, w = np.polynomial.legendre.leggauss(10)
    P = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    W = np.einsum("i,j,k->ijk", w, w, w).ravel()
    _, J = exact_evaluator(lat)(P)
    return float(np.sum(W * np.linalg.det(J)))


def run_case(case, level=10, independent=True, surface=False):
    mesh, lat, normals = case[:3]
    t0 = time.perf_counter()
    res = smoothffd.deform(mesh, lat, level=level, device="cpu")
    ms = 1e3 * (time.perf_counter() - t0)
    e = errors(res, normals, exact_evaluator(lat, independent))
    if surface:
        e["surface"] = surface_errors(res, case, exact_evaluator(lat, independent))
    e.update(patches=int(res.stats["patches"]), triangles=int(len(res.triangles)),
             input_faces=int(mesh.face_count), ms=ms)
    return e, lat


# --- tables and plots --------------------------------------------------------------------------

def fmt(x, digits=3):
    if x is None:
        return "-"
    return f"{x:.{digits}g}"


def error_tables(quick):
    rows = []
    cases = [("cube2", "Cube, degree 2 (3x3x3 control points, 1 knot box)", cube_case(2)),
             ("cube3", "Cube, degree 3 (4x4x4 control points, 1 knot box)", cube_case(3)),
             (None, "Cube, degree 2, 5x5x5 control points (27 knot boxes)",
              cube_case(2, (5, 5, 5))),
             ("teapot2", f"Teapot, degree 2; mesh 3x3 quads a patch (the demo's)",
              teapot_case(3)),
             ("teapot2", f"Teapot, degree 2; mesh {4 if quick else 6}x{4 if quick else 6} "
                         f"quads a patch", teapot_case(4 if quick else 6))]
    for key, label, case in cases:
        e, lat = run_case(case, surface=label.startswith("Teapot"))
        if label.startswith("Cube"):
            v = exact_volume(lat)
            e["volume_rel"] = abs(e["volume"] - v) / v
            e["volume_exact"] = v
            r40 = smoothffd.deform(case[0], case[1], level=40, device="cpu")
            e["volume_rel_L40"] = abs(ref.mesh_volume(r40.positions, r40.triangles) - v) / v
        rows.append((key, label, e))
        print(f"  {label}: {e['geometry_max']:.3g} max distance, {e['normal_max_deg']:.3g} deg")
    return rows


def sweep(quick):
    levels = [1, 2, 3, 4, 6, 8, 10, 12, 16] if not quick else [1, 2, 4, 10]
    mags = [0.125, 0.25, 0.5, 1.0, 1.5, 2.0] if not quick else [0.25, 1.0, 2.0]
    res_n = [2, 3, 4, 6, 8, 12] if not quick else [2, 3, 6]
    out = {"levels": levels, "mags": mags, "res_n": res_n, "L": {}, "M": {}, "N": {}}
    makers = {"cube, degree 2": lambda m=1.0: cube_case(2, magnitude=m),
              "cube, degree 3": lambda m=1.0: cube_case(3, magnitude=m),
              "teapot (3x3 quads a patch), degree 2": lambda m=1.0: teapot_case(3, magnitude=m)}
    for name, make in makers.items():
        out["L"][name] = [run_case(make(), L, independent=False)[0] for L in levels]
        out["M"][name] = [run_case(make(m), 10, independent=False)[0] for m in mags]
    out["N"]["teapot, degree 2"] = [run_case(teapot_case(n), 10, independent=False)[0]
                                    for n in res_n]
    return out


def plots(sw):
    os.makedirs(IMAGES, exist_ok=True)
    paths = []
    for key, xs, xlabel, fname, title in (
            ("L", sw["levels"], "level L (each patch tessellated into L^2 triangles)",
             "results_error_vs_level.png", "Error against the tessellation level"),
            ("M", sw["mags"], "deformation magnitude s (bulge 0.25 s, twist 45 s degrees)",
             "results_error_vs_magnitude.png", "Error against the deformation magnitude (L = 10)"),
            ("N", sw["res_n"], "teapot mesh: n x n quads a Bezier patch",
             "results_error_vs_mesh.png", "Teapot: error against the input mesh's resolution (L = 10)")):
        fig, axes = plt.subplots(1, 2, figsize=(8.4, 3.1), dpi=90)
        for name, es in sw[key].items():
            for ax, (m, lab) in zip(axes, (("geometry", "distance"), ("normal", "angle (deg)"))):
                unit = "" if m == "geometry" else "_deg"
                ax.plot(xs, [e[f"{m}_max{unit}"] for e in es], "o-", ms=3, label=f"{name}, max")
                ax.plot(xs, [e[f"{m}_avg{unit}"] for e in es], "s--", ms=3, label=f"{name}, avg",
                        color=ax.lines[-1].get_color())
                ax.set_ylabel(f"{m} error, {lab}", fontsize=8)
                ax.set_xlabel(xlabel, fontsize=8)
                ax.set_yscale("log")
                if key == "M" or key == "N":
                    ax.set_xscale("log")
                ax.tick_params(labelsize=7)
                ax.grid(True, which="both", alpha=0.3)
        axes[1].legend(fontsize=6, loc="best")
        fig.suptitle(title, fontsize=9)
        fig.tight_layout()
        path = os.path.join(IMAGES, fname)
        fig.savefig(path)
        plt.close(fig)
        paths.append(path)
    return paths


# --- timings -----------------------------------------------------------------------------------

def bench_cpu(quick):
    levels = ["4", "10", "16"] if not quick else ["10"]
    cmd = [sys.executable, os.path.join(ROOT, "bench", "bench_cpu.py"), "--levels", *levels,
           "--repeats", "3" if quick else "5"]
    env = dict(os.environ, PYTHONPATH=os.path.join(ROOT, "python"))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=1800)
    if p.returncode != 0:
        return None, p.stderr[-2000:]
    return p.stdout, None


def parse_bench(text):
    rows = []
    for line in text.splitlines():
        # L, the layout (bench_cpu.py prints one since it times several), plan, deform, ...
        m = re.match(r"\s*(\d+)\s+(?:[a-z]+\s+)?([\d.]+)\s+([\d.]+)\s+(\d+)\s+(\d+)\s+([\d.]+)\s+(.*)", line)
        if m:
            stages = dict((k.strip(), float(v)) for k, v in
                          (s.rsplit(" ", 1) for s in m.group(7).split(", ")))
            rows.append(dict(L=int(m.group(1)), plan=float(m.group(2)), deform=float(m.group(3)),
                             tris=int(m.group(4)), verts=int(m.group(5)), mtris=float(m.group(6)),
                             stages=stages))
    return rows


def vase_timing(level=27, repeats=5):
    """Table 6's case: the vase, all edges tessellated into 27 segments."""
    v = shapes.vase(12)
    cv, fo = shapes.flat(v)
    mesh = smoothffd.Mesh(v["positions"], (cv, fo))
    lo, hi = v["positions"].min(0), v["positions"].max(0)
    pad = 0.05 * (hi - lo)
    lat = smoothffd.BSplineLattice.identity(lo - pad, hi + pad, shape=(4, 4, 5))
    lat = bulge_twist(lat, 0.2, 30)
    d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = d.deform(lat)
        ts.append(1e3 * (time.perf_counter() - t0))
    return float(np.median(ts)), r


def gpu_table():
    path = os.path.join(DOCS, "benchmarks.md")
    if not os.path.exists(path):
        return None
    text = open(path).read()
    date = re.search(r"\*\*Full benchmark\*\* \((\d{4}-\d\d-\d\d)", text)
    hw = re.search(r"^## GPU \((.*?)\)$", text, re.M)
    table = re.search(r"(\| case \|.*?\n)(?:\n|$)", text, re.S)
    return (date.group(1) if date else "?", hw.group(1) if hw else "?",
            table.group(1).strip() if table else None)


# --- adaptive tessellation ------------------------------------------------------------------------

ADAPTIVE_PLOT_WORKLOADS = ("w1", "vase", "figure", "suzanne")


def bench_adaptive(quick, json_path=None):
    """bench/bench_adaptive.py's rows: from json_path when given (an earlier run's --json), else
    a fresh run. (rows dict or None, its printed output or an error)."""
    if json_path:
        with open(json_path) as f:
            data = json.load(f)
        txt = os.path.splitext(json_path)[0] + ".txt"
        return data, (open(txt).read() if os.path.exists(txt) else None)
    import tempfile

    out = os.path.join(tempfile.mkdtemp(prefix="report_adaptive_"), "adaptive.json")
    cmd = [sys.executable, os.path.join(ROOT, "bench", "bench_adaptive.py"), "--json", out]
    if quick:
        cmd += ["--workloads", "vase", "suzanne", "figure", "--levels", "2", "4", "8",
                "--repeats", "3"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        os.path.join(ROOT, d) for d in ("python", "tests", "bench")))
    p = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=3600)
    if p.returncode != 0:
        return None, p.stderr[-2000:]
    with open(out) as f:
        return json.load(f), p.stdout


def adaptive_plot(data):
    """True tessellation error (relative to the diagonal) against output triangles."""
    rows = data["rows"]
    names = [n for n in ADAPTIVE_PLOT_WORKLOADS if any(r["workload"] == n for r in rows)][:3]
    fig, ax = plt.subplots(figsize=(6.4, 4.0), dpi=90)
    for name in names:
        rs = sorted((r for r in rows if r["workload"] == name), key=lambda r: r["level"])
        d = rs[0]["diagonal"]
        ax.plot([r["uniform_triangles"] for r in rs], [r["uniform_error"] / d for r in rs], "o-",
                ms=4, label=f"{name}: uniform, L = {', '.join(str(r['level']) for r in rs)}")
        for r in rs:
            ax.annotate(str(r["level"]), (r["uniform_triangles"], r["uniform_error"] / d),
                        textcoords="offset points", xytext=(3, 3), fontsize=6,
                        color=ax.lines[-1].get_color())
        ax.plot([r["adaptive_triangles"] for r in rs], [r["adaptive_error"] / d for r in rs], "s--",
                ms=4, mfc="none", color=ax.lines[-1].get_color(),
                label=f"{name}: adaptive, t = e_L")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("output triangles", fontsize=8)
    ax.set_ylabel("true max tessellation error / bounding-box diagonal", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6.5, loc="best")
    ax.set_title("Tessellation error against triangles (dense sampling)", fontsize=9)
    fig.tight_layout()
    path = os.path.join(IMAGES, "results_adaptive_error_vs_triangles.png")
    fig.savefig(path)
    plt.close(fig)
    return path


def _wire_panel(ax, positions, triangles, direction, title):
    """Orthographic view along -direction: back faces culled, the rest painted far to near,
    shaded by their own normal, with their edges."""
    from matplotlib.collections import PolyCollection

    d = np.asarray(direction, float)
    d /= np.linalg.norm(d)
    right = np.cross(-d, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -d)
    P = np.asarray(positions, np.float64)[np.asarray(triangles)]           # (T, 3, 3)
    n = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    keep = n @ d > 0
    P, n = P[keep], n[keep]
    order = np.argsort(P.mean(axis=1) @ d)
    P, n = P[order], n[order]
    light = d + 0.6 * up + 0.3 * right
    light /= np.linalg.norm(light)
    g = 0.45 + 0.5 * np.clip(n @ light, 0, 1)
    xy = np.stack([P @ right, P @ up], axis=-1)
    ax.add_collection(PolyCollection(xy, facecolors=np.stack([g * 0.93, g * 0.95, g], 1),
                                     edgecolors=(0.1, 0.15, 0.35), linewidths=0.15))
    lo, hi = xy.reshape(-1, 2).min(0), xy.reshape(-1, 2).max(0)
    pad = 0.03 * (hi - lo).max()
    ax.set_xlim(lo[0] - pad, hi[0] + pad)
    ax.set_ylim(lo[1] - pad, hi[1] + pad)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.set_title(title, fontsize=8)


def adaptive_wireframes(level=4):
    """Uniform level L beside adaptive at t = e_L (the uniform output's true error) on the vase
    scene and on Suzanne: (path, caption facts) per mesh."""
    import bench_adaptive as ba
    import tessellation_error as ta

    out = []
    for name, direction, fname in (
            ("vase", (math.sin(math.radians(20)) * math.cos(math.radians(30)),
                      -math.cos(math.radians(20)) * math.cos(math.radians(30)),
                      math.sin(math.radians(30))), "results_adaptive_wire_vase.png"),
            ("suzanne", (math.sin(math.radians(-25)) * math.cos(math.radians(12)),
                         -math.cos(math.radians(-25)) * math.cos(math.radians(12)),
                         math.sin(math.radians(12))), "results_adaptive_wire_suzanne.png")):
        mesh, lat, _ = ba.workload(name)
        ad = smoothffd.Deformer(mesh, lat, device="cpu", tolerance=1.0)
        e = ta.uniform_error(ba.patch_control(ad, lat), level)
        uni = smoothffd.Deformer(mesh, lat, level=level, device="cpu").deform(lat)
        ad = smoothffd.Deformer(mesh, lat, device="cpu", tolerance=e)
        res = ad.deform(lat)
        fig, axes = plt.subplots(1, 2, figsize=(8.0, 4.2), dpi=90)
        _wire_panel(axes[0], uni.positions, uni.triangles, direction,
                    f"uniform L = {level}: {len(uni.triangles):,} triangles")
        _wire_panel(axes[1], res.positions, res.triangles, direction,
                    f"adaptive, t = e_{level} = {e:.3g}: {len(res.triangles):,} triangles")
        fig.tight_layout()
        path = os.path.join(IMAGES, fname)
        fig.savefig(path)
        plt.close(fig)
        out.append((name, path, dict(level=level, tolerance=e, diagonal=ba.diagonal(mesh),
                                     uniform=len(uni.triangles), adaptive=len(res.triangles))))
    return out


def adaptive_section(data, printed, err, wires, quick):
    """docs/results.md's "Adaptive tessellation" section (list of lines)."""
    L = ["## Adaptive tessellation", ""]
    w = L.append
    if data is None:
        w(f"(bench/bench_adaptive.py did not run: {err})")
        w("")
        return L
    rows = data["rows"]
    w("`Deformer(mesh, lattice, tolerance=t)` tessellates each patch edge and interior as finely "
      "as its bounds say is needed for every output triangle to lie within t of the cubic patch "
      "it approximates (recomputed each frame; measured here on the CPU). `bench/bench_adaptive.py` "
      "compares it with the uniform levels on the same patches: for each level L it measures the "
      "uniform output's true maximum tessellation error e_L (the largest distance between a "
      "triangle and its patch, by dense sampling: 28 points a triangle, "
      "`tests/tessellation_error.py`), runs the adaptive tessellation at t = e_L and measures its own "
      "true maximum error the same way: with the output's float32 positions (*worst / t*) and "
      "with its triangles' corners evaluated on their patches in float64 (*float64 corners*, as "
      "e_L is measured for the uniform triangles: the like-for-like figure). Times: one `Deformer.deform` each with the plan reused, "
      f"median of {data['repeats']} frames, uniform and adaptive alternating in the same process, "
      f"on this machine ({data['cores']} cores, shared), {data.get('date', '?')}, commit "
      f"{data.get('commit', '?')}; fresh result arrays with per-corner normals.")
    w("")
    import bench_adaptive as ba

    present = list(dict.fromkeys(r["workload"] for r in rows))
    parts = []
    w1 = [r for r in rows if r["workload"] == "w1"]
    if w1:
        parts.append("W1 (the timing workload below; errors on " + (
            f"{w1[0]['error_patches']:,} random patches of its {w1[0]['patches']:,}, the counts "
            "and times on all)" if w1[0]["error_patches"] < w1[0]["patches"] else "all patches)"))
    scenes = [n for n in present if n in ba.SCENES]
    if scenes:
        parts.append("the demo scenes whose meshes are plain numpy (`blender_scenes/shapes.py`: "
                     + ", ".join(scenes) + "), each with its scene's B-spline lattice as "
                     "`smoothffd.BlenderLattice` and its sharp edges as split normals")
    corpus = [n for n in present if n in ba.REAL]
    if corpus:
        parts.append("meshes of `tests/data/real` (" + ", ".join(corpus) + ") under a random "
                     "5x5x5 quadratic lattice (seed 7, condition number under 2)")
    w("Workloads: " + "; ".join(parts) + ". Not here: " + "; ".join(data.get("skipped", []))
      + ", which need Blender to build.")
    w("")
    w("![error vs triangles](images/results_adaptive_error_vs_triangles.png)")
    w("")
    w("| workload | L | t = e_L / diagonal | uniform triangles | adaptive triangles | adaptive / "
      "uniform | uniform ms | adaptive ms | worst / t | float64 corners |")
    w("|---|---|---|---|---|---|---|---|---|---|")
    last = None
    for r in rows:
        name = r["workload"] if r["workload"] != last else ""
        last = r["workload"]
        ratio = f"**{r['ratio']:.2f}**" if r["ratio"] < 1 else f"{r['ratio']:.2f}"
        w(f"| {name} | {r['level']} | {r['tolerance_rel']:.2e} | {r['uniform_triangles']:,} | "
          f"{r['adaptive_triangles']:,} | {ratio} | {r['uniform_ms']:.1f} | {r['adaptive_ms']:.1f} | "
          f"{r['adaptive_error_over_t']:.2f} | {r['adaptive_error_f64_corners'] / r['tolerance']:.2f} |")
    w("")
    by = {}
    for r in rows:
        by.setdefault(r["workload"], []).append(r)
    best = {n: min(rs, key=lambda r: r["ratio"]) for n, rs in by.items()}
    w64 = [r["adaptive_error_f64_corners"] / r["tolerance"] for r in rows]
    over = [r for r in rows if r["adaptive_error_over_t"] > 1]
    w(f"With float64 corners every adaptive tessellation is within its tolerance (worst / t "
      f"{min(w64):.2f}-{max(w64):.2f}). "
      + (("The float32 output positions exceed it in "
          + ", ".join(f"{r['workload']} L = {r['level']} ({r['adaptive_error_over_t']:.2f} t at "
                      f"t = {r['tolerance_rel']:.2g} of the diagonal)" for r in over)
          + ": t is then only a few float32 steps of the output's coordinates (a step is 1.2e-7 "
          "at 1-2 units), and the positions' rounding, not the tessellation, makes the excess. ")
         if over else "")
      + "Adaptive / uniform at its lowest for each workload: "
      + ", ".join(f"{n} {b['ratio']:.2f} (L = {b['level']})" for n, b in best.items()) + ".")
    w("")
    more = [r for r in rows if r["ratio"] > 1]
    if more:
        groups = {}
        for r in more:
            groups.setdefault(r["workload"], []).append(r)
        coarse = [r["adaptive_error_over_t"] for r in rows if r["level"] == min(x["level"] for x in rows)]
        w("More triangles than the uniform level: "
          + "; ".join(f"{n} at L = {', '.join(str(r['level']) for r in g)} ("
                      + (f"{g[0]['ratio']:.2f}" if len(g) == 1 else
                         f"{min(r['ratio'] for r in g):.2f}-{max(r['ratio'] for r in g):.2f}") + ")"
                      for n, g in groups.items())
          + ". The adaptive tessellation decides by bounds, which lie above the true error, "
          f"most at the coarsest tolerance (there its worst triangle is {min(coarse):.2f}-"
          f"{max(coarse):.2f} t); and where every patch bends about alike (the corpus torus, the "
          "knot-box slab under its waves) a uniform level is already close to what each patch "
          "needs.")
        w("")
    sp = [r["adaptive_ms"] / r["uniform_ms"] for r in rows]
    w(f"Time: an adaptive frame took {min(sp):.1f}-{max(sp):.1f} times the uniform frame of the "
      "same error here: its counts, bounds and triangles are computed for every frame on the "
      "CPU, where a uniform frame fills a topology fixed by the plan.")
    w("")
    for name, path, f in wires:
        w(f"![adaptive wireframe, {name}](images/{os.path.basename(path)})")
        w("")
    if wires:
        w("Wireframes: uniform level " + str(wires[0][2]["level"]) + " beside the adaptive "
          "tessellation at that level's true error, " + "; ".join(
              f"{n} t = {f['tolerance']:.3g} ({f['tolerance'] / f['diagonal']:.2e} of the diagonal): "
              f"{f['uniform']:,} against {f['adaptive']:,} triangles" for n, _, f in wires)
          + " (the vase scene's lattice; Suzanne from `tests/data/real` under the random lattice "
          "above; orthographic, back faces culled).")
        w("")
    if printed:
        w("<details><summary>bench/bench_adaptive.py output</summary>")
        w("")
        w("```")
        w(printed.strip())
        w("```")
        w("")
        w("</details>")
        w("")
    return L


def splice_section(text, lines, heading="## Adaptive tessellation", before="## Timings"):
    """text with the section `heading` replaced by lines (inserted before `before` if absent)."""
    block = "\n".join(lines) + "\n"
    start = text.find(heading + "\n")
    if start >= 0:
        end = text.find("\n## ", start + len(heading))
        end = len(text) if end < 0 else end + 1
        return text[:start] + block + text[end:]
    at = text.find(before)
    if at < 0:
        return text.rstrip("\n") + "\n\n" + block
    return text[:at] + block + text[at:]


# --- the document ------------------------------------------------------------------------------

def cpu_name():
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def git_rev():
    try:
        return subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, cwd=ROOT).stdout.strip()
    except OSError:
        return "?"


def real_meshes_section(after):
    """docs/results.md's section on the real-mesh corpus: scripts/quality_corpus.py's table."""
    return [
        "## Real meshes",
        "",
        "Real assets are harder than the paper's shapes. `tests/data/real/` holds a corpus "
        "of small real meshes (Blender primitives and Suzanne exported with their split normals, "
        "a lathe with sharp rims, a low-poly figure with flat non-planar quads and smooth parts, "
        "an OBJ with its own normals; see its README). `python3 -m smoothffd quality IN.obj` "
        "measures a user's own asset the same way (`smoothffd.metrics.quality`); "
        "`scripts/quality_corpus.py` prints this table. Lattice: 5x5x5 quadratic B-spline around "
        "the mesh (identity, twisted 45 degrees or bent 40 degrees about z). *reversed*: output "
        "triangles whose geometric normal points against the mean of their corner normals; "
        "*tiny*: area under 1e-8 of the bounding-box diagonal squared; *smallest angle* over "
        "levels 1, 3, 6 (in brackets: the smallest angle of the core's own triangulation of the "
        "input); *largest aspect*: longest edge^2 sqrt(3) / (4 area), 1 for an equilateral "
        "triangle; *flat*: the largest distance, relative to the diagonal, of an output vertex "
        "of a face whose normals say it is flat from the exact FFD of the flat input, across the "
        "surface (the deformed normal's component) / whole (where a flat face meets a smooth "
        "one, the shared crease curves within the flat face's plane); *volume change*: against "
        "the exact FFD of the flat input (closed meshes).",
        "",
        "What keeps these clean is in docs/algorithm.md: snapping the knot-plane cuts, the "
        "adjustment normals and the shading bound, knots anywhere.",
        "",
        after,
        "",
        "Suzanne has a strongly non-planar quad whose normals lie 81-90 degrees from one of its "
        "triangles: with the fold bound alone, the deformation turns them past 90 degrees from "
        "the triangle's own image (3 / 27 / 108 reversed triangles under the twist, 1 under the "
        "bend). The shading bound (docs/algorithm.md) turns such normals toward the geometry (18 "
        "corners of Suzanne; no other corpus mesh changes), so that no lattice whose Jacobian "
        "has a condition number under 2 reverses a triangle.",
        "",
        "The same on CUDA (`tests/test_cuda_real_meshes.py`, run on a GPU machine: "
        "docs/benchmarks.md): every corpus mesh under the three lattices at levels 1, 3 and 6, "
        "both paths, against the CPU evaluator on the same plan (positions and each render "
        "vertex's normal within that file's bounds, 3x the float rounding measured between the "
        "two), no reversed triangle and flat faces on the exact FFD of their flat input in the "
        "CUDA result itself, flat-shaded input back at rest, knots shifted by 1e5 and 1e7 or "
        "scaled, and two 1e-7 spans (the inline kernel's global mode). The CUDA per-corner "
        "normals are the render vertices' (the owner patch's); the CPU's per-corner normals are "
        "each patch's own, which at a vertex shared by nearly coplanar flat faces (the figure) "
        "differ from the owner's by up to 0.93 degrees, within the plan's 1-degree normal class.",
        "",
    ]


def quality_table():
    import quality_corpus as qc

    return qc.table(qc.measure_all())


def write(rows, sw, plot_paths, bench, bench_err, vase, gpu, elapsed, quick, quality_rows="",
          adaptive_lines=()):
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    dev = f"{cpu_name()}, {os.cpu_count()} logical cores (shared with other jobs)"
    L = []
    w = L.append
    w("# Results: the paper's comparisons, reproduced")
    w("")
    w(f"Generated by `bash scripts/report.sh` on {now}, commit {git_rev()}, {dev}; "
      f"numpy {np.__version__}, Python {platform.python_version()}"
      + (" (**--quick** run: fewer points)" if quick else "") + f". It took {elapsed:.0f} s.")
    w("Paper: Cui & Feng 2015, *Smooth free-form deformation with sharp feature awareness* "
      "(sec. 6). Pictures of the demo scenes: `bash scripts/demo.sh` (see the README).")
    w("")
    w("## Approximation errors (paper Tables 2-4)")
    w("")
    w("Objects as in the paper: a cube and the Utah teapot (Newell's 32 bicubic patches, "
      "`blender_scenes/teapot_data.py`, sampled uniformly into quads and split into "
      "triangles, with the surface's exact vertex normals), both normalized into [-1, 1]^3. "
      "The cube has 2 x 2 quads a face and sharp edges (`tests/meshes.py: grid_cube(2)`). "
      "Lattice: a B-spline volume of the given degree over [-1, 1]^3 with its control "
      "points at the Greville abscissae, then *bulge 0.25, twist 45 degrees* "
      "(`tests/meshes.py: bulge_twist`: each control point p scaled by "
      "1 + 0.25 exp(-|p|^2), then rotated about z by an angle growing linearly from -22.5 "
      "to 22.5 degrees with height). The paper does not give its deformations, so the "
      "values are comparable in size only. Level L = 10 (100 triangles a patch, as in the "
      "paper). Exact FFD by the independent reference `tests/reference.py` (B-spline "
      "volume by Cox-de Boor, normals by the cofactor of its Jacobian).")
    w("")
    w("* geometry: distance between each output vertex and the exact FFD of the point of "
      "the flat input face it comes from (`Result.rest_positions`);")
    w("* normal: angle between each output corner normal and the exact deformed normal at "
      "that point: cof(J) n_face for the cube; for the teapot cof(J) applied to the "
      "input's linear normal field (vertex normals interpolated over the triangle), the "
      "field the paper deforms;")
    w("* teapot, second row: against the FFD of the exact Bezier surface instead (the paper's "
      "reference, \"original FFD of uniformly sampled points and normals\"): each output "
      "point is mapped to the surface point with the same patch parameters (interpolated "
      "over its input triangle) and compared with that point's exact image and normal;")
    w("* volume: enclosed volume of the output triangles against the integral of det J over "
      "the cube (10^3 Gauss-Legendre points). Not for the teapot (it is not closed).")
    w("")
    w("| case | patches | geometry avg | geometry max | normal avg | normal max | volume rel. |")
    w("|---|---|---|---|---|---|---|")
    for key, label, e in rows:
        w(f"| {label} | {e['patches']} | {fmt(e['geometry_avg'])} | {fmt(e['geometry_max'])} | "
          f"{fmt(e['normal_avg_deg'])}° | {fmt(e['normal_max_deg'])}° | "
          f"{fmt(e.get('volume_rel'))} |")
        if "surface" in e:
            f = e["surface"]
            w(f"| ... same, against the FFD of the exact Bezier surface | | "
              f"{fmt(f['geometry_avg'])} | {fmt(f['geometry_max'])} | "
              f"{fmt(f['normal_avg_deg'])}° | {fmt(f['normal_max_deg'])}° | - |")
        if key and key in PAPER and (key != "teapot2" or "3x3" not in label):
            p = PAPER[key]
            w(f"| *paper, Fig. 14 column {dict(cube2=1, cube3=2, teapot2=3)[key]}* | | "
              f"*{fmt(p['geometry_avg'])}* | *{fmt(p['geometry_max'])}* | "
              f"*{fmt(p['normal_avg_deg'])}°* | *{fmt(p['normal_max_deg'])}°* | "
              f"*{fmt(p['volume_rel'])}* |")
    w("")
    cube = [e for k, _, e in rows if k == "cube2"][0]
    w(f"Volumes: cube degree 2 output {cube['volume']:.5g}, exact {cube['volume_exact']:.5g} "
      f"(paper: 16.641 vs 16.6449 for its own deformation). The output's volume includes "
      f"the chord error of the tessellation (flat triangles inscribed in the curved "
      f"patches): at L = 40 the relative volume error is {cube['volume_rel_L40']:.3g} "
      f"instead of {cube['volume_rel']:.3g}; the rest is the patches' own error.")
    w("")
    w("Teapot: against the FFD of its own flat triangles the smooth result is close (the "
      "first row of each mesh); against the exact surface the errors are those of the "
      "coarse polygonal input and shrink with a finer mesh (see the mesh plot below). The "
      "maximum normal angles (about 85 degrees) sit where Newell's patches meet at a crease "
      "(the spout's tip, the handle's ends, the rim under the lid): the mesh is welded there "
      "and its single averaged vertex normal cannot match both sides of the exact surface. "
      "The paper reports its maximum (23 degrees) at the spout's end and the lip as well. "
      "At those creases the coarser mesh's welded normals lie so far from some of their "
      "triangles that the shading bound (docs/algorithm.md) turns them toward the geometry "
      f"({_turned(3)} corners of the 3x3 mesh, {_turned(6)} of the 6x6): its maximum against "
      "the input's own normal field is that deliberate turn, not the fit.")
    w("")
    w("## Error against level, deformation and mesh")
    w("")
    w("Same objects and deformation; for these sweeps the exact FFD is the core's own "
      "double-precision lattice evaluation (`lattice.evaluate`, checked against the "
      "reference above in `tests/test_lattices.py`), which is 500 times faster.")
    w("")
    w("![error vs level](images/results_error_vs_level.png)")
    w("")
    w("The level only decides where the smooth patches are sampled: the patches themselves "
      "do not change with L, so the error does not go to zero as L grows; it settles at the "
      "distance between the cubic patch and the exact deformed triangle (L = 1 measures the "
      "corners only, where the patches interpolate the exact FFD).")
    w("")
    w("![error vs magnitude](images/results_error_vs_magnitude.png)")
    w("")
    w("The cube's errors vanish with the deformation (its flat faces and sharp edges are "
      "represented exactly at rest). The teapot's do not: at rest its smooth patches already "
      "differ from the flat triangles (the PN-like geometry adjustment rounds a coarse smooth "
      "mesh towards the surface its normals describe, the paper's sec. 4.2 remark), so the "
      "errors against the FFD of the *flat* triangles have a floor.")
    w("")
    w("![error vs mesh](images/results_error_vs_mesh.png)")
    w("")
    w("A finer input mesh brings the teapot's errors down: the paper's remark that the "
      "maximum normal error comes from the polygonal approximation of the smooth object.")
    w("")
    for line in real_meshes_section(quality_rows):
        w(line)
    for line in adaptive_lines:
        w(line)
    w("## Timings (paper Tables 1, 5, 6)")
    w("")
    w(f"CPU, this machine: {dev}, {now}. `bench/bench_cpu.py` (the Table 1 workload W1: a "
      "torus of 46,760 triangles, 5x5x5 control points, degree 2, random displacements; "
      "per frame = `Deformer.deform` with the plan reused, median of repeats; times include "
      "returning numpy arrays with per-corner normals).")
    w("")
    if bench:
        rows_b = parse_bench(bench)
        w("| L | plan ms | deform ms | output triangles | Mtri/s | stages (ms) |")
        w("|---|---|---|---|---|---|")
        for r in rows_b:
            st = ", ".join(f"{k} {v:.1f}" for k, v in r["stages"].items())
            w(f"| {r['L']} | {r['plan']:.0f} | {r['deform']:.0f} | {r['tris']:,} | "
              f"{r['mtris']:.2f} | {st} |")
        w("")
        w("Paper Table 1 (GTX 465, W1, L = 10): 37.3 ms a frame including rendering, 23.3 ms "
          "for the compute steps (sampling 8.5, constraints 2.9, control points 4.0, "
          "normals 1.2, adjustment 2.0, tessellation 4.9). Paper Table 5 (smooth FFD, "
          "100 to 256 sub-triangles a patch = L 10 to 16): 26.4 to 36.2 ms.")
        w("")
        w("```")
        w(bench.strip())
        w("```")
    else:
        w(f"(bench/bench_cpu.py did not run: {bench_err or 'skipped with --no-bench'})")
    w("")
    ms, r = vase
    w(f"Table 6's case, the vase (`blender_scenes/shapes.py: vase`, {len(shapes.vase()['polygons'])} "
      f"faces, 12 segments) with every patch edge in 27 segments (L = 27): "
      f"{r.stats['patches']} patches, {len(r.triangles):,} triangles, **{ms:.1f} ms** a frame "
      f"on this CPU (median of 5; paper, GPU: 0.456 ms for the tessellation points, 4.06 ms "
      f"with copy and render).")
    w("")
    w("### GPU")
    w("")
    if gpu and gpu[2]:
        w(f"From `docs/benchmarks.md` (run {gpu[0]} on {gpu[1]}; see that file for the "
          f"method, the uniform-upsampling comparison of Table 5 and the raw numbers):")
        w("")
        w(gpu[2])
    else:
        w("No GPU figures yet (`docs/benchmarks.md` is written by the GPU benchmark).")
    w("")
    with open(os.path.join(DOCS, "results.md"), "w") as f:
        f.write("\n".join(L) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer points (a smoke run)")
    ap.add_argument("--no-bench", action="store_true")
    ap.add_argument("--adaptive-json", metavar="PATH",
                    help="the adaptive section from an earlier bench/bench_adaptive.py --json PATH "
                         "run (its printed output from PATH with .txt, if there) instead of a new run")
    ap.add_argument("--adaptive-only", action="store_true",
                    help="regenerate only the \"Adaptive tessellation\" section of docs/results.md "
                         "and its images, leaving the rest of the file as it is")
    a = ap.parse_args()
    t0 = time.perf_counter()
    os.makedirs(IMAGES, exist_ok=True)
    print("adaptive tessellation (bench/bench_adaptive.py)...")
    adata, aout = bench_adaptive(a.quick, a.adaptive_json)
    adaptive_paths = [adaptive_plot(adata)] if adata else []
    wires = adaptive_wireframes()
    adaptive_paths += [p for _, p, _ in wires]
    adaptive_lines = adaptive_section(adata, aout if adata else None, aout, wires, a.quick)
    if a.adaptive_only:
        path = os.path.join(DOCS, "results.md")
        with open(path) as f:
            text = f.read()
        with open(path, "w") as f:
            f.write(splice_section(text, adaptive_lines))
        print("wrote the adaptive section of docs/results.md and",
              ", ".join(os.path.relpath(p, ROOT) for p in adaptive_paths))
        return
    print("errors (Tables 2-4)...")
    rows = error_tables(a.quick)
    print("sweeps...")
    sw = sweep(a.quick)
    paths = plots(sw)
    bench, err = (None, None) if a.no_bench else (print("bench/bench_cpu.py...") or bench_cpu(a.quick))
    vase = vase_timing()
    print("real meshes (scripts/quality_corpus.py)...")
    quality = quality_table()
    write(rows, sw, paths, bench, err, vase, gpu_table(), time.perf_counter() - t0, a.quick, quality,
          adaptive_lines)
    print("wrote docs/results.md and", ", ".join(os.path.relpath(p, ROOT) for p in paths + adaptive_paths))


if __name__ == "__main__":
    main()
