"""The smoothffd lattice JSON format (version 1), documented in docs/formats.md.

    load_lattice(path)            -> smoothffd.BSplineLattice | smoothffd.BlenderLattice
    save_lattice(path, lattice)
    lattice_to_dict(lattice)      -> dict (JSON-ready)
    parse_lattice(doc, source)    -> (kind, constructor kwargs as numpy arrays); validation only

Validation and (de)serialization are pure Python; only building the lattice object needs the
native core, so the core is imported lazily.
"""
from __future__ import annotations

import json
import math
import reprlib
import os

import numpy as np

__all__ = ["FORMAT", "VERSION", "load_lattice", "save_lattice", "lattice_to_dict",
           "parse_lattice", "build_lattice", "dumps_lattice", "blender_rest_grid"]

FORMAT = "smoothffd-lattice"
VERSION = 1
INTERPOLATIONS = ("LINEAR", "CARDINAL", "CATMULL_ROM", "BSPLINE")

_COMMON = {"format", "version", "kind", "shape", "name", "comment"}
_KEYS = {
    "bspline": _COMMON | {"degree", "knots", "box_min", "box_max", "control_points"},
    "blender": _COMMON | {"rest_points", "points", "interpolation", "lattice_to_object",
                          "strength", "point_weights"},
}


class _Err:
    """Builds ValueErrors that start with the source (file name) and name the JSON key."""

    def __init__(self, source):
        self.prefix = f"{source}: " if source else ""

    def __call__(self, key, msg):
        return ValueError(f"{self.prefix}key '{key}': {msg}")


def _is_number(x):
    if not isinstance(x, (int, float)) or isinstance(x, bool):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:  # an integer beyond float range (JSON allows any number of digits)
        return False


def _int_triple(doc, key, err, lo, hi, default=None):
    val = doc.get(key, default)
    if isinstance(val, int) and not isinstance(val, bool):
        val = [val] * 3  # one number means "the same on every axis"
    if (not isinstance(val, list) or len(val) != 3
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in val)):
        raise err(key, f"expected 3 integers, got {reprlib.repr(val)}")
    for a, v in enumerate(val):
        if not lo <= v <= hi:
            raise err(f"{key}[{a}]", f"expected {lo}..{hi}, got {v}")
    return tuple(val)


def _vector(doc, key, err, n=3, optional=False):
    val = doc.get(key)
    if val is None and optional:
        return None
    if not isinstance(val, list) or len(val) != n or not all(_is_number(v) for v in val):
        raise err(key, f"expected {n} finite numbers, got {reprlib.repr(val)}")
    return np.array(val, dtype=np.float64)


def _points(doc, key, err, shape):
    """A flat list of nu*nv*nw [x, y, z] rows (w fastest) -> (nu, nv, nw, 3) float64."""
    val = doc.get(key)
    n = shape[0] * shape[1] * shape[2]
    if not isinstance(val, list):
        raise err(key, f"expected a list of {n} [x, y, z] points, got {type(val).__name__}")
    if len(val) != n:
        raise err(key, f"expected {n} points for shape {list(shape)}, got {len(val)}")
    for i, p in enumerate(val):
        if not isinstance(p, list) or len(p) != 3 or not all(_is_number(v) for v in p):
            raise err(f"{key}[{i}]", f"expected [x, y, z] finite numbers, got {reprlib.repr(p)}")
    return np.array(val, dtype=np.float64).reshape(*shape, 3)


def blender_rest_grid(shape):
    """Blender's default rest lattice: points spread over [-0.5, 0.5] per axis (0 for an axis
    with one point). shape (nu, nv, nw) -> (nu, nv, nw, 3)."""
    axes = [np.linspace(-0.5, 0.5, n) if n > 1 else np.zeros(1) for n in shape]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)


def parse_lattice(doc, source=None):
    """Validate a decoded JSON document. Returns (kind, kwargs) where kwargs are the keyword
    arguments of ``BSplineLattice(...)`` or ``BlenderLattice(...)`` as numpy arrays.
    Raises ValueError naming the offending key."""
    err = _Err(source)
    if not isinstance(doc, dict):
        raise err("(top level)", f"expected a JSON object, got {type(doc).__name__}")
    if doc.get("format") != FORMAT:
        raise err("format", f"expected {reprlib.repr(FORMAT)}, got {reprlib.repr(doc.get('format'))}")
    version = doc.get("version")
    if not isinstance(version, int) or isinstance(version, bool):
        raise err("version", f"expected an integer, got {reprlib.repr(version)}")
    if version != VERSION:
        raise err("version", f"version {version} is not supported (this reader knows {VERSION})")
    kind = doc.get("kind")
    if not isinstance(kind, str) or kind not in _KEYS:
        raise err("kind", f"expected 'bspline' or 'blender', got {reprlib.repr(kind)}")
    unknown = sorted(set(doc) - _KEYS[kind])
    if unknown:  # catches typos such as "knot" that would otherwise be silently ignored
        raise err(unknown[0], f"unknown key for kind {reprlib.repr(kind)}")
    for key in ("name", "comment"):
        if key in doc and not isinstance(doc[key], str):
            raise err(key, "expected a string")

    if kind == "bspline":
        shape = _int_triple(doc, "shape", err, 2, 100000)
        degree = _int_triple(doc, "degree", err, 1, 5, default=[2, 2, 2])
        for a in range(3):
            if shape[a] < degree[a] + 1:
                raise err(f"shape[{a}]", f"degree {degree[a]} needs at least {degree[a] + 1} "
                                         f"points, got {shape[a]}")
            # What build_plan takes (lattice._check_pieces): the spans inside the box and one
            # piece on each side outside it.
            if shape[a] - degree[a] + 2 > 1023:
                raise err(f"shape[{a}]", f"{shape[a]} points of degree {degree[a]} make "
                                         f"{shape[a] - degree[a] + 2} polynomial pieces; the core "
                                         "handles at most 1023 an axis")
        knots = doc.get("knots")
        if knots is not None:
            if not isinstance(knots, list) or len(knots) != 3:
                raise err("knots", "expected null or three knot vectors [u, v, w]")
            kv = []
            for a, k in enumerate(knots):
                want = shape[a] + degree[a] + 1
                if not isinstance(k, list) or not all(_is_number(v) for v in k):
                    raise err(f"knots[{a}]", "expected a list of finite numbers")
                if len(k) != want:
                    raise err(f"knots[{a}]",
                              f"expected {want} values (points + degree + 1), got {len(k)}")
                arr = np.array(k, dtype=np.float64)
                if (arr[1:] < arr[:-1]).any():  # not np.diff: -1e308 .. 1e308 overflows
                    raise err(f"knots[{a}]", "must be non-decreasing")
                if not arr[degree[a]] < arr[shape[a]]:
                    raise err(f"knots[{a}]", "the domain [knots[degree], knots[points]] is empty")
                kv.append(arr)
            knots = kv
        box_min = _vector(doc, "box_min", err, optional=True)
        box_max = _vector(doc, "box_max", err, optional=True)
        if box_min is not None and box_max is not None and (box_max <= box_min).any():
            raise err("box_max", "must exceed box_min on every axis "
                                 f"({box_min.tolist()} .. {box_max.tolist()})")
        cp = _points(doc, "control_points", err, shape)
        return kind, dict(control_points=cp, degree=degree, knots=knots, box_min=box_min,
                          box_max=box_max)

    shape = _int_triple(doc, "shape", err, 1, 64)  # Blender's own limit per axis
    rest = doc.get("rest_points")
    rest = blender_rest_grid(shape) if rest is None else _points(doc, "rest_points", err, shape)
    points = _points(doc, "points", err, shape)
    interp = doc.get("interpolation", "BSPLINE")
    if isinstance(interp, str):
        interp = [interp] * 3
    if (not isinstance(interp, list) or len(interp) != 3
            or any(t not in INTERPOLATIONS for t in interp)):
        raise err("interpolation", f"expected a name or 3 names from {list(INTERPOLATIONS)}, "
                                   f"got {reprlib.repr(doc.get('interpolation'))}")
    m = doc.get("lattice_to_object")
    if m is None:
        m = np.eye(4)
    else:
        def row_ok(r):
            return isinstance(r, list) and len(r) == 4 and all(_is_number(v) for v in r)

        if not isinstance(m, list) or len(m) != 4 or not all(row_ok(r) for r in m):
            raise err("lattice_to_object", "expected a 4x4 matrix as 4 rows of 4 finite numbers")
        m = np.array(m, dtype=np.float64)
        if not np.allclose(m[3], [0, 0, 0, 1]):
            raise err("lattice_to_object", "the last row must be [0, 0, 0, 1]")
    strength = doc.get("strength", 1.0)
    if not _is_number(strength):
        raise err("strength", f"expected a finite number, got {reprlib.repr(strength)}")
    weights = doc.get("point_weights")
    if weights is not None:
        n = shape[0] * shape[1] * shape[2]
        if not isinstance(weights, list) or len(weights) != n:
            raise err("point_weights", f"expected null or a list of {n} numbers (one a point, "
                                       f"in the order of 'points'), got {reprlib.repr(weights)}")
        for i, v in enumerate(weights):
            if not _is_number(v):
                raise err(f"point_weights[{i}]", f"expected a finite number, got {reprlib.repr(v)}")
        weights = np.array(weights, dtype=np.float64).reshape(shape)
    return kind, dict(rest_points=rest, points=points, interpolation=tuple(interp),
                      lattice_to_object=m, strength=float(strength), point_weights=weights)


def build_lattice(kind, kwargs):
    """Construct the lattice object (needs the native core)."""
    from . import BlenderLattice, BSplineLattice  # lazy: the rest of this module is pure

    return (BSplineLattice if kind == "bspline" else BlenderLattice)(**kwargs)


def load_lattice(path):
    """Read a lattice JSON file -> smoothffd.BSplineLattice or smoothffd.BlenderLattice."""
    path = os.fspath(path)
    with open(path, "r", encoding="utf-8") as fh:
        text = fh.read()
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"{path}:{e.lineno}: invalid JSON: {e.msg}") from None
    except RecursionError:  # "[[[[..." deeper than the interpreter's recursion limit
        raise ValueError(f"{path}: invalid JSON: nested too deeply") from None
    kind, kwargs = parse_lattice(doc, path)
    try:
        return build_lattice(kind, kwargs)
    except (ValueError, TypeError) as e:  # the constructor's own checks; keep the file name
        raise type(e)(f"{path}: {e}") from None


def _rows(a):
    return [[float(v) for v in row] for row in np.asarray(a, dtype=np.float64).reshape(-1, 3)]


def lattice_to_dict(lattice, name=None):
    """A JSON-ready dict for a lattice, read through its public attributes:
    control_points, degree, knots, box_min, box_max (B-spline) or rest_points, points,
    interpolation, lattice_to_object, strength, point_weights (Blender)."""
    if hasattr(lattice, "lattice_to_object"):
        pts = np.asarray(lattice.points, dtype=np.float64)
        doc = {"format": FORMAT, "version": VERSION, "kind": "blender",
               "shape": [int(n) for n in pts.shape[:3]],
               "interpolation": [str(t) for t in lattice.interpolation],
               "lattice_to_object": np.asarray(lattice.lattice_to_object, float).tolist(),
               "strength": float(lattice.strength),
               "rest_points": _rows(lattice.rest_points), "points": _rows(pts)}
        weights = getattr(lattice, "point_weights", None)
        if weights is not None:
            doc["point_weights"] = [float(v) for v in np.asarray(weights, dtype=np.float64).ravel()]
    elif hasattr(lattice, "control_points"):
        cp = np.asarray(lattice.control_points, dtype=np.float64)
        knots = getattr(lattice, "knots", None)

        def vec(v):
            return None if v is None else [float(x) for x in np.asarray(v, dtype=np.float64)]

        doc = {"format": FORMAT, "version": VERSION, "kind": "bspline",
               "shape": [int(n) for n in cp.shape[:3]],
               "degree": [int(d) for d in lattice.degree],
               "knots": None if knots is None else [vec(k) for k in knots],
               "box_min": vec(getattr(lattice, "box_min", None)),
               "box_max": vec(getattr(lattice, "box_max", None)),
               "control_points": _rows(cp)}
    else:
        raise TypeError("lattice: expected a BSplineLattice or BlenderLattice, "
                        f"got {type(lattice).__name__}")
    if name:
        doc["name"] = str(name)
    return doc


def dumps_lattice(doc):
    """Format a lattice dict as JSON with one point (or matrix row) per line."""
    def scalar(v):
        if isinstance(v, float) and not math.isfinite(v):
            raise ValueError(f"cannot save a non-finite value ({v}) in lattice JSON")
        return json.dumps(v)

    def small(v):  # a short list on one line
        if isinstance(v, list):
            return "[" + ", ".join(small(x) for x in v) + "]"
        return scalar(v)

    lines = []
    for key, val in doc.items():
        if isinstance(val, list) and val and isinstance(val[0], list):
            body = ",\n".join("    " + small(r) for r in val)
            lines.append(f'  {json.dumps(key)}: [\n{body}\n  ]')
        else:
            lines.append(f"  {json.dumps(key)}: {small(val)}")
    return "{\n" + ",\n".join(lines) + "\n}\n"


def save_lattice(path, lattice, name=None):
    """Write a lattice (or a dict from lattice_to_dict) as lattice JSON."""
    doc = lattice if isinstance(lattice, dict) else lattice_to_dict(lattice, name=name)
    parse_lattice(doc, os.fspath(path))  # never write a file we could not read back
    text = dumps_lattice(doc)
    from .io import atomic_write  # written whole or not at all
    with atomic_write(path) as fh:
        fh.write(text)
