"""Command line: ``python3 -m smoothffd {deform,make-lattice,info} ...``.

    deform IN.obj --lattice L.json -o OUT.obj [--level 10] [--device auto|cpu|cuda]
    make-lattice (--bbox-of IN.obj | --box X0 Y0 Z0 X1 Y1 Z1) [--shape 5 5 5] [--degree 2 2 2]
                 [--twist DEG | --bend DEG | --bulge F] [--axis z] -o L.json
    info FILE.obj|FILE.json
    quality IN.obj [--lattice L.json | --twist DEG | --bend DEG | --bulge F] [--levels 3 6]

Progress goes to stderr, one line per stage with its time. Bad input (unreadable or malformed
files, invalid arguments) exits with status 2 and a one-line message; anything else is a bug
and keeps its traceback.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import sys
import time

import numpy as np

from . import io as objio
from . import lattice_json

# make-lattice's largest lattice: 2^20 control points (101 x 101 x 101), a JSON of ~70 MB.
MAKE_LATTICE_MAX_POINTS = 1 << 20

# Errors that mean "your input is wrong", not "smoothffd is broken".
_USER_ERRORS = (ValueError, TypeError, OSError, RuntimeError, MemoryError)


class UserError(Exception):
    """A problem with the command line's input; reported in one line, exit status 2."""


class _Progress:
    """Stage lines on stderr: the name is printed when a stage starts (so a long stage shows
    what is running), its details and wall time when it ends."""

    def __init__(self, quiet=False, stream=None):
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.open = False
        self.times = {}

    @contextlib.contextmanager
    def stage(self, name):
        note = {}
        t0 = time.perf_counter()
        if not self.quiet:
            print(f"smoothffd: {name:<6} ...", end="", file=self.stream, flush=True)
            self.open = True
        yield note
        dt = time.perf_counter() - t0
        self.times[name] = dt
        if not self.quiet:
            detail = f" {note['detail']}" if note.get("detail") else ""
            print(f"{detail} ({dt:.2f} s)", file=self.stream, flush=True)
            self.open = False

    def abort(self):
        if self.open:
            print(" failed", file=self.stream, flush=True)
            self.open = False


# ----------------------------------------------------------------------------------------
# make-lattice helpers (pure numpy: usable and testable without the core)


def open_uniform_knots(degree, count):
    """Clamped uniform knot vector on [0, 1]: count + degree + 1 values."""
    inner = np.linspace(0.0, 1.0, count - degree + 1)
    return np.concatenate([np.zeros(degree), inner, np.ones(degree)])


def greville_grid(box_min, box_max, shape, degree):
    """Control points of the identity B-spline volume over the box (open-uniform knots):
    the Greville abscissae (means of `degree` consecutive knots) mapped into the box.
    -> (nu, nv, nw, 3)."""
    axes = []
    for a in range(3):
        k = open_uniform_knots(degree[a], shape[a])
        xi = np.array([k[i + 1:i + degree[a] + 1].mean() for i in range(shape[a])])
        axes.append(box_min[a] + xi * (box_max[a] - box_min[a]))
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


def deform_points(points, box_min, box_max, mode=None, amount=0.0, axis=2):
    """Apply an example deformation to points (..., 3) in object space.

    The deformation is relative to the box: h in [0, 1] is the position along `axis`.
      twist  amount degrees: rotation about the box's central axis by amount * (h - 1/2)
      bend   amount degrees: the axis is bent into a circular arc turning by `amount` over the
             box length, towards the next axis (z -> x, x -> y, y -> z); the centre is fixed
      bulge  amount factor: distances from the central axis scaled by 1 + amount * 4h(1 - h)
    """
    p = np.array(points, dtype=np.float64)
    if mode is None or amount == 0:
        return p
    lo, hi = np.asarray(box_min, float), np.asarray(box_max, float)
    c = (lo + hi) / 2
    length = hi[axis] - lo[axis]
    b, d = (axis + 1) % 3, (axis + 2) % 3  # the two cross-section axes
    q = p - c
    h = (p[..., axis] - lo[axis]) / length
    if mode == "twist":
        ang = math.radians(amount) * (h - 0.5)
        cs, sn = np.cos(ang), np.sin(ang)
        qb, qd = q[..., b].copy(), q[..., d].copy()
        q[..., b] = cs * qb - sn * qd
        q[..., d] = sn * qb + cs * qd
    elif mode == "bend":
        theta = math.radians(amount)
        radius = length / theta  # arc of the central axis keeps its length
        phi = q[..., axis] / radius
        r = radius - q[..., b]
        q[..., b] = radius - r * np.cos(phi)
        q[..., axis] = r * np.sin(phi)
    elif mode == "bulge":
        s = 1.0 + amount * 4.0 * h * (1.0 - h)
        q[..., b] *= s
        q[..., d] *= s
    else:
        raise ValueError(f"deformation: unknown mode {mode!r}")
    return q + c


def padded_box(positions, margin):
    """Bounding box of positions (N, 3) grown by margin * (largest extent) on every side, so
    flat meshes still get a box with volume."""
    p = np.asarray(positions, dtype=np.float64)
    if len(p) == 0:
        raise ValueError("the mesh has no vertices")
    lo, hi = p.min(axis=0), p.max(axis=0)
    pad = margin * max(float((hi - lo).max()), 1e-12)
    return lo - pad, hi + pad


def make_lattice_doc(box_min, box_max, shape, degree=(2, 2, 2), kind="bspline", mode=None,
                     amount=0.0, axis=2, interpolation="BSPLINE", name=None):
    """A lattice JSON document: the identity lattice of the box, then the deformation."""
    box_min, box_max = np.asarray(box_min, float), np.asarray(box_max, float)
    if kind == "bspline":
        rest = greville_grid(box_min, box_max, shape, degree)
        cp = deform_points(rest, box_min, box_max, mode, amount, axis)
        doc = {"format": lattice_json.FORMAT, "version": lattice_json.VERSION, "kind": "bspline",
               "shape": list(shape), "degree": list(degree), "knots": None,
               "box_min": box_min.tolist(), "box_max": box_max.tolist(),
               "control_points": cp.reshape(-1, 3).tolist()}
    elif kind == "blender":
        rest = lattice_json.blender_rest_grid(shape)
        # lattice space [-0.5, 0.5]^3 -> the box; a one-point axis sits at the box centre
        m = np.eye(4)
        m[:3, :3] = np.diag(box_max - box_min)
        m[:3, 3] = (box_min + box_max) / 2
        obj = rest @ m[:3, :3].T + m[:3, 3]
        moved = deform_points(obj, box_min, box_max, mode, amount, axis)
        pts = (moved - m[:3, 3]) @ np.linalg.inv(m[:3, :3]).T
        doc = {"format": lattice_json.FORMAT, "version": lattice_json.VERSION, "kind": "blender",
               "shape": list(shape), "interpolation": [interpolation] * 3,
               "lattice_to_object": m.tolist(), "strength": 1.0,
               "rest_points": rest.reshape(-1, 3).tolist(), "points": pts.reshape(-1, 3).tolist()}
    else:
        raise ValueError(f"--kind: expected bspline or blender, got {kind!r}")
    if name:
        doc["name"] = name
    lattice_json.parse_lattice(doc, "make-lattice")  # validates shape/degree combinations
    return doc


# ----------------------------------------------------------------------------------------
# commands


def _ensure_parent(path):
    """Create the output's folder, so `-o out/x.obj` works on a fresh checkout."""
    parent = os.path.dirname(os.path.abspath(path))
    probe = parent
    while probe and not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if probe and not os.path.isdir(probe):
        raise ValueError(f"{path}: cannot write there: {probe} is a file, not a folder")
    os.makedirs(parent, exist_ok=True)


def cmd_deform(args, progress):
    from . import Deformer  # the core (its ImportError says why it is missing)

    with progress.stage("read") as note:
        mesh = objio.read_obj_mesh(args.input)
        lattice = lattice_json.load_lattice(args.lattice)
        shape = "x".join(map(str, np.shape(lattice.control_values())[:3]))
        note["detail"] = (f"{args.input}: {mesh.vertex_count:,} vertices, "
                          f"{mesh.face_count:,} faces; {type(lattice).__name__} {shape}")
    with progress.stage("plan") as note:
        tolerance = None
        if args.tolerance is not None:
            size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0))) or 1.0
            tolerance = args.tolerance * (size if args.relative else 1.0)
        deformer = Deformer(mesh, lattice, level=args.level, device=args.device, threads=args.threads,
                            tolerance=tolerance, max_level=args.max_level)
        how = (f"tolerance {tolerance:.3g}, at most {args.max_level} segments an edge" if tolerance
               else f"level {args.level}")
        note["detail"] = f"{how}, device {deformer.device}"
    with progress.stage("deform") as note:
        res = deformer.deform(estimate_error=args.estimate_error)
        note["detail"] = f"{len(res.triangles):,} triangles, {len(res.positions):,} vertices"
        if tolerance:
            met = ("every triangle within it" if res.stats["tolerance_met"] else
                   f"not met where {res.stats['capped']} edges and patches reached --max-level")
            note["detail"] += (f"; tessellation bound {res.stats['max_tessellation_bound']:.3g} ({met}), "
                               f"levels up to {res.stats['max_patch_level']}")
        if args.estimate_error:
            size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0))) or 1.0
            worst = int(np.argmax(res.face_error))
            note["detail"] += (f"; fit error at most {res.stats['max_face_error']:.3g} "
                               f"({res.stats['max_face_error'] / size:.2g} of the mesh's size, "
                               f"face {worst}), normals about {res.stats['max_face_normal_error_deg']:.3g} deg")
    with progress.stage("write") as note:
        _ensure_parent(args.output)
        how = (f"--tolerance {args.tolerance:g}{' --relative' if args.relative else ''} "
               f"--max-level {args.max_level}" if args.tolerance is not None else f"--level {args.level}")
        header = (f"smoothffd deform {os.path.basename(args.input)} "
                  f"--lattice {os.path.basename(args.lattice)} {how}")
        objio.write_result(args.output, res, header=header)
        note["detail"] = f"{args.output}, {os.path.getsize(args.output) / 2**20:.1f} MiB"
    if args.errors:
        from . import metrics

        with progress.stage("check") as note:
            # A volume needs a closed surface: an open mesh gets the other measures only.
            closed = metrics.is_watertight(res.triangles)
            e = metrics.reference_errors(res, lattice, closed=closed)
            g, n = e["geometry"], e["normal"]
            volume = (f"volume error {e['volume_error']:.3g}" if closed and e["reference_volume"]
                      else "no volume error (the mesh is not closed)")
            note["detail"] = (f"vs exact FFD of the flat input: geometry mean {g.mean:.3g} "
                              f"max {g.max:.3g}; normal mean {n.mean:.3g} max {n.max:.3g} deg; "
                              f"{volume}")
    if args.stats:
        stats = dict(res.stats)
        stats["cli_seconds"] = progress.times
        print(json.dumps(stats, indent=2, default=str))
    return 0


def cmd_make_lattice(args, progress):
    if args.bbox_of:
        with progress.stage("read") as note:
            d = objio.read_obj(args.bbox_of)
            note["detail"] = f"{args.bbox_of}: {len(d.positions):,} vertices"
        box_min, box_max = padded_box(d.positions, args.margin)
    else:
        lo, hi = np.array(args.box[:3], float), np.array(args.box[3:], float)
        if (hi <= lo).any():
            raise UserError("--box: each max must exceed its min")
        box_min, box_max = lo, hi
    if args.kind == "bspline":  # what the lattice reader accepts (lattice_json.parse_lattice)
        for a, (n, d) in enumerate(zip(args.shape, args.degree)):
            if not 1 <= d <= 5:
                raise UserError(f"--degree: each degree must be between 1 and 5, got {d}")
            if n < d + 1:
                raise UserError(f"--shape: degree {d} needs at least {d + 1} points on axis "
                                f"{'xyz'[a]}, got {n}")
    # Checked before the grid is built: --shape 1000 1000 1000 asked for 7.5 GiB at once, and
    # 300 300 300 for minutes of work and a 1.5 GB file (found by native/fuzz/fuzz_cli.py).
    points = math.prod(args.shape)
    if points > MAKE_LATTICE_MAX_POINTS:
        raise UserError(f"--shape: {' x '.join(map(str, args.shape))} = {points:,} control points; "
                        f"make-lattice writes at most {MAKE_LATTICE_MAX_POINTS:,}")
    mode, amount = None, 0.0
    for m in ("twist", "bend", "bulge"):
        if getattr(args, m) is not None:
            mode, amount = m, getattr(args, m)
    if not math.isfinite(amount):
        raise UserError(f"--{mode}: expected a finite number")
    doc = make_lattice_doc(box_min, box_max, tuple(args.shape), tuple(args.degree), args.kind,
                           mode, amount, "xyz".index(args.axis), args.interpolation,
                           name=f"{mode or 'identity'} {amount:g}" if mode else "identity")
    with progress.stage("write") as note:
        _ensure_parent(args.output)
        lattice_json.save_lattice(args.output, doc)
        shape = "x".join(map(str, args.shape))
        note["detail"] = f"{args.output}: {doc['kind']} {shape}, {doc['name']}"
    return 0


def _describe_obj(path):
    from . import metrics

    d = objio.read_obj(path)
    sizes = np.diff(d.face_offsets)
    lines = [f"file        {path}",
             f"vertices    {len(d.positions):,}",
             f"faces       {len(sizes):,} ({int((sizes == 3).sum()):,} triangles, "
             f"{int((sizes == 4).sum()):,} quads, {int((sizes > 4).sum()):,} n-gons, "
             f"largest {int(sizes.max()) if len(sizes) else 0} corners)",
             f"corners     {len(d.corner_vertices):,}; "
             f"fan triangulation: {int((sizes - 2).sum()):,} triangles"]
    if d.corner_normals is not None:
        # a vertex is split (sharp) where its corners carry different normals
        rows = np.column_stack([d.corner_vertices.astype(np.float64), d.corner_normals])
        uniq, _ = objio._dedupe(rows)
        per_vertex = np.bincount(uniq[:, 0].astype(np.int64), minlength=len(d.positions))
        distinct = len(objio._dedupe(d.corner_normals)[0])
        lines.append(f"normals     per corner, {distinct:,} distinct; "
                     f"split at {int((per_vertex > 1).sum()):,} vertices")
    else:
        lines.append("normals     none (smooth vertex normals will be computed)")
    lines.append(f"uvs         {'per corner' if d.uvs is not None else 'none'}")
    if len(d.positions):
        lo, hi = d.positions.min(axis=0), d.positions.max(axis=0)
        lines.append(f"bbox        min {np.array2string(lo, precision=4)} "
                     f"max {np.array2string(hi, precision=4)}")
    if len(sizes):
        # fan triangles share the polygons' edges, so the edge report is the polygon mesh's
        fan = sizes - 2  # triangle k of a polygon's fan: corners 0, k+1, k+2
        first = np.repeat(d.face_offsets[:-1], fan)
        k = np.arange(int(fan.sum())) - np.repeat(np.cumsum(fan) - fan, fan)
        tri = np.stack([d.corner_vertices[first], d.corner_vertices[first + k + 1],
                        d.corner_vertices[first + k + 2]], axis=1)
        r = metrics.edge_report(tri)
        lines.append(f"edges       {r.edges:,}: {r.boundary:,} boundary, "
                     f"{r.non_manifold:,} non-manifold, {r.misoriented:,} misoriented")
        if r.watertight:
            vol = metrics.signed_volume(d.positions, tri)
            lines.append(f"volume      {vol:.6g} (closed, oriented)")
    return lines


def _describe_lattice(path):
    with open(path, encoding="utf-8") as fh:
        try:
            doc = json.load(fh)
        except json.JSONDecodeError as e:
            raise ValueError(f"{path}:{e.lineno}: invalid JSON: {e.msg}") from None
    kind, kw = lattice_json.parse_lattice(doc, path)
    lines = [f"file        {path}", f"lattice     {kind} {'x'.join(map(str, doc['shape']))}"
             + (f" ({doc['name']})" if doc.get("name") else "")]
    if kind == "bspline":
        cp = kw["control_points"].reshape(-1, 3)
        knots = "open uniform" if kw["knots"] is None else "custom"
        lines.append(f"degree      {list(kw['degree'])}, knots {knots}")
        if kw["box_min"] is not None:
            lines.append(f"box         {kw['box_min'].tolist()} .. {kw['box_max'].tolist()}")
        lines.append(f"points      {len(cp)}, bbox {cp.min(0).tolist()} .. {cp.max(0).tolist()}")
    else:
        disp = np.linalg.norm(kw["points"] - kw["rest_points"], axis=-1)
        lines.append(f"interp      {list(kw['interpolation'])}, strength {kw['strength']}")
        lines.append(f"points      {disp.size}, max displacement {disp.max():.4g} (lattice space)")
    return lines


def cmd_quality(args, progress):
    """Deform a mesh at several levels and print metrics.quality for each: what real assets
    need checked (reversed triangles, flat faces, slivers, volume)."""
    from . import Deformer, metrics

    with progress.stage("read") as note:
        mesh = objio.read_obj_mesh(args.input)
        note["detail"] = f"{args.input}: {mesh.vertex_count:,} vertices, {mesh.face_count:,} faces"
    mode, amount = None, 0.0
    for m in ("twist", "bend", "bulge"):
        if getattr(args, m) is not None:
            mode, amount = m, getattr(args, m)
    if args.lattice:
        if mode:
            raise UserError(f"--{mode}: give either --lattice or a deformation, not both")
        lattice = lattice_json.load_lattice(args.lattice)
        what = args.lattice
    else:
        box_min, box_max = padded_box(mesh.positions, 0.05)
        doc = make_lattice_doc(box_min, box_max, (5, 5, 5), (2, 2, 2), "bspline", mode, amount,
                               "xyz".index(args.axis))
        lattice = lattice_json.build_lattice(*lattice_json.parse_lattice(doc, "quality"))
        what = f"5x5x5 quadratic B-spline, {mode + f' {amount:g}' if mode else 'identity'}"
    rows = []
    for level in args.levels:
        if level < 1:
            raise UserError(f"--levels: each level must be at least 1, got {level}")
        with progress.stage(f"L={level}") as note:
            d = Deformer(mesh, lattice, level=level, device=args.device)
            res = d.deform()
            tin = mesh.corner_vertices[d.plan.input_triangles()[0]]
            q = metrics.quality(res, mesh, lattice, input_triangles=tin)
            rows.append((level, q))
            note["detail"] = f"{q.triangles:,} triangles"
    if args.json:
        print(json.dumps([dict(level=L, **q._asdict()) for L, q in rows], indent=2))
        return 0
    q0 = rows[0][1]
    print(f"{args.input}: {mesh.face_count:,} faces, {q0.flat_faces:,} flat; lattice: {what}; "
          f"size (bbox diagonal) {q0.size:.4g}; smallest angle of its triangulation "
          f"{q0.input_min_angle:.3g}\u00b0"
          + (f"; {q0.against_face} input corners with a normal against their face"
             if q0.against_face else ""))
    print(f"{'L':>3} {'triangles':>10} {'reversed':>9} {'degen':>6} {'tiny':>6} {'min angle':>10} "
          f"{'max aspect':>11} {'flat off':>9} {'flat dist':>9} {'volume':>10} watertight")
    for level, q in rows:
        vol = f"{q.volume_change:+.2e}" if q.volume_change is not None else "open"
        print(f"{level:>3} {q.triangles:>10,} {q.reversed:>9,} {q.degenerate:>6,} {q.tiny:>6,} "
              f"{q.min_angle:>9.3g}\u00b0 {q.max_aspect:>11.4g} {q.flat_deviation:>9.2e} "
              f"{q.flat_slide:>9.2e} "
              f"{vol:>10} {'yes' if q.watertight else 'no'}")
    return 0


def cmd_info(args, progress):
    is_json = args.input.lower().endswith(".json")
    lines = _describe_lattice(args.input) if is_json else _describe_obj(args.input)
    print("\n".join(lines))
    return 0


class _Parser(argparse.ArgumentParser):
    """argparse reading a negative number in any float syntax (-1e-3, -.5, -2E+1) as a value,
    not an option, as Python 3.13's argparse does (3.11's takes only -1 and -1.5: --box -1e-3
    ... failed with "expected 6 arguments"). Subcommand parsers inherit the class."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")


def _core_devices():
    """The core's device names (smoothffd.DEVICES) for --device; None without the core (any
    name passes here, and deform and quality stop at the core's ImportError, which says why)."""
    try:
        from ._core import DEVICES
    except ImportError:
        return None
    return DEVICES


def build_parser():
    p = _Parser(
        prog="python3 -m smoothffd",
        description="Smooth free-form deformation of polygon meshes (Cui & Feng 2015).")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    d = sub.add_parser("deform", help="deform an OBJ mesh with a lattice JSON")
    d.add_argument("input", metavar="IN.obj")
    d.add_argument("--lattice", "-l", required=True, metavar="L.json")
    d.add_argument("--output", "-o", required=True, metavar="OUT.obj")
    d.add_argument("--level", type=int, default=10,
                   help="tessellation level L (L^2 triangles per patch; default 10)")
    d.add_argument("--tolerance", type=float, metavar="T",
                   help="adaptive tessellation instead of --level: every output triangle within T "
                        "(object units) of the smooth patch it approximates")
    d.add_argument("--relative", action="store_true",
                   help="--tolerance as a fraction of the mesh's bounding-box diagonal")
    d.add_argument("--max-level", type=int, default=64, metavar="M",
                   help="with --tolerance: at most M segments a patch edge (default 64)")
    d.add_argument("--device", choices=_core_devices(), default="auto")
    d.add_argument("--threads", type=int, default=0, help="CPU threads (0: all cores)")
    d.add_argument("--stats", action="store_true",
                   help="print the result's stats as JSON on stdout")
    d.add_argument("--errors", action="store_true",
                   help="also report geometry/normal/volume errors against exact FFD of the flat "
                        "input (meaningful for flat-faced meshes, as in the paper's cube test)")
    d.add_argument("--estimate-error", action="store_true",
                   help="estimate each face's fit error (a bound on the distance from the exact "
                        "FFD of the flat face, and the normals' angle) and report the largest; "
                        "with --stats, in the JSON too")
    d.add_argument("--quiet", "-q", action="store_true", help="no progress lines")
    d.set_defaults(func=cmd_deform)

    m = sub.add_parser("make-lattice", help="write an example lattice JSON (identity around a "
                                             "box, then a deformation)")
    src = m.add_mutually_exclusive_group(required=True)
    src.add_argument("--bbox-of", metavar="IN.obj",
                     help="use this mesh's bounding box (plus --margin)")
    src.add_argument("--box", type=float, nargs=6, metavar=("X0", "Y0", "Z0", "X1", "Y1", "Z1"))
    m.add_argument("--margin", type=float, default=0.05,
                   help="box padding, fraction of the largest extent (default 0.05)")
    m.add_argument("--shape", type=int, nargs=3, default=[5, 5, 5], metavar=("NU", "NV", "NW"))
    m.add_argument("--degree", type=int, nargs=3, default=[2, 2, 2], metavar=("DU", "DV", "DW"))
    m.add_argument("--kind", choices=("bspline", "blender"), default="bspline")
    m.add_argument("--interpolation", choices=lattice_json.INTERPOLATIONS, default="BSPLINE",
                   help="Blender lattice interpolation (with --kind blender)")
    m.add_argument("--axis", choices=("x", "y", "z"), default="z",
                   help="axis of twist/bend/bulge (default z)")
    how = m.add_mutually_exclusive_group()
    how.add_argument("--twist", type=float, metavar="DEG", help="twist by DEG degrees end to end")
    how.add_argument("--bend", type=float, metavar="DEG", help="bend by DEG degrees end to end")
    how.add_argument("--bulge", type=float, metavar="F",
                     help="scale the middle cross-section by 1 + F")
    m.add_argument("--output", "-o", required=True, metavar="L.json")
    m.add_argument("--quiet", "-q", action="store_true")
    m.set_defaults(func=cmd_make_lattice)

    q = sub.add_parser("quality", help="deform a mesh at several levels and report reversed "
                                       "triangles, flat-face deviation, angles, volume")
    q.add_argument("input", metavar="IN.obj")
    q.add_argument("--lattice", "-l", metavar="L.json",
                   help="the lattice (default: 5x5x5 quadratic B-spline around the mesh, identity "
                        "or the deformation below)")
    qhow = q.add_mutually_exclusive_group()
    qhow.add_argument("--twist", type=float, metavar="DEG")
    qhow.add_argument("--bend", type=float, metavar="DEG")
    qhow.add_argument("--bulge", type=float, metavar="F")
    q.add_argument("--axis", choices=("x", "y", "z"), default="z")
    q.add_argument("--levels", type=int, nargs="+", default=[1, 3, 6], metavar="L")
    q.add_argument("--device", choices=_core_devices(), default="auto")
    q.add_argument("--json", action="store_true", help="print the measures as JSON")
    q.add_argument("--quiet", "-q", action="store_true", help="no progress lines")
    q.set_defaults(func=cmd_quality)

    i = sub.add_parser("info", help="describe an OBJ mesh or a lattice JSON")
    i.add_argument("input", metavar="FILE")
    i.set_defaults(func=cmd_info, quiet=True)
    return p


def main(argv=None):
    """Entry point; returns the exit status (0 ok, 2 bad input)."""
    args = build_parser().parse_args(argv)
    progress = _Progress(quiet=getattr(args, "quiet", False))
    try:
        return args.func(args, progress)
    except (UserError,) + _USER_ERRORS as e:
        progress.abort()
        msg = " ".join(str(e).split()) or type(e).__name__
        if isinstance(e, FileNotFoundError) and e.filename:
            msg = f"{e.filename}: no such file"
        print(f"smoothffd: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        progress.abort()
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
