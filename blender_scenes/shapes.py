"""The demo's shapes and lattice deformations as plain numpy (no bpy): the scene scripts turn
them into Blender data, and scripts/report.py feeds the same teapot to the core directly.

A shape is a dict: positions (V, 3), polygons (list of vertex-index lists, outward, counter-
clockwise), sharp (set of sorted vertex-index pairs: edges to mark sharp, on top of those found
by the dihedral angle in the scene scripts) and, for the teapot, vertex_normals (V, 3): the
normals of the smooth surface it samples.
"""
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import teapot_data  # noqa: E402


# --- lathes: the vase (paper Fig. 1/16) and the chess piece (Fig. 12) -------------------------

def lathe(profile, segments, name):
    """Surface of revolution about z. profile: [(radius, z, sharp)], from the bottom up. A
    nonzero first radius gets a flat n-gon cap; a zero radius (first or last point) closes
    that end with a fan to a pole. sharp marks the ring of edges at that profile point as
    sharp (a rim, a crease)."""
    angles = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    pos, ring_index = [], []
    for r, z, _ in profile:
        if r == 0:
            ring_index.append([len(pos)] * segments)
            pos.append((0.0, 0.0, z))
        else:
            ring_index.append(list(range(len(pos), len(pos) + segments)))
            pos += [(r * math.cos(a), r * math.sin(a), z) for a in angles]
    polys, sharp = [], set()
    if profile[0][0] != 0:   # flat bottom cap, seen from below
        polys.append(ring_index[0][::-1])
    for k in range(len(profile) - 1):
        a, b = ring_index[k], ring_index[k + 1]
        for s in range(segments):
            t = (s + 1) % segments
            quad = [a[s], a[t], b[t], b[s]]
            uniq = [v for i, v in enumerate(quad) if v not in quad[:i]]
            polys.append(uniq)
    for k, (r, _, is_sharp) in enumerate(profile):
        if is_sharp and r != 0:
            ring = ring_index[k]
            sharp |= {tuple(sorted((ring[s], ring[(s + 1) % segments]))) for s in range(segments)}
    return dict(name=name, positions=np.array(pos), polygons=polys, sharp=sharp)


def vase(segments=12):
    """A low-poly vase: sharp bottom edge, a bulging body, a neck, a sharp rim with a lip and
    an inner wall down to a shallow floor."""
    profile = [(0.55, 0.0, True), (0.62, 0.05, True), (0.85, 0.55, False), (0.9, 1.0, False),
               (0.7, 1.5, False), (0.42, 1.85, False), (0.4, 2.1, False), (0.55, 2.35, True),
               (0.47, 2.35, True), (0.33, 2.1, False), (0.3, 1.8, False), (0.0, 1.75, False)]
    return lathe(profile, segments, "vase")


def chess_pawn(segments=16):
    """A pawn: a base with sharp rims, a shaft, a sharp collar and a round head."""
    # The head meets the neck ring at about 120 degrees: that ring is sharp, as Blender's auto
    # smooth (30 degrees) would mark it. Left smooth, the averaged normal there is nearly
    # perpendicular to the ring and any PN-style smoothing folds the ring (docs/algorithm.md).
    head = [(0.36 * math.sin(t), 1.78 - 0.36 * math.cos(t), i == 0)
            for i, t in enumerate(np.linspace(0.55, np.pi, 6))]
    profile = [(0.72, 0.0, True), (0.72, 0.16, True), (0.6, 0.24, False), (0.56, 0.32, True),
               (0.46, 0.36, True), (0.36, 0.55, False), (0.26, 0.95, False), (0.22, 1.25, False),
               (0.42, 1.33, True), (0.42, 1.41, True), (0.24, 1.47, False)] + head
    profile[-1] = (0.0, profile[-1][1], False)
    return lathe(profile, segments, "chess_pawn")


# --- the knot-box case (Fig. 6/7): a slab of a few large faces -------------------------------

def slab(size=(2.4, 1.6, 0.3)):
    """A box of 6 quads (12 triangles when triangulated): every face is much larger than the
    lattice cells that will cross it, so only clipping can follow the deformation inside."""
    sx, sy, sz = (s / 2 for s in size)
    v = np.array([(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    edges = set()
    for q in quads:
        edges |= {tuple(sorted((q[i], q[(i + 1) % 4]))) for i in range(4)}
    return dict(name="slab", positions=v, polygons=[list(q) for q in quads], sharp=edges)


# --- the Utah teapot --------------------------------------------------------------------------

def _bernstein(t):
    t = np.asarray(t, dtype=np.float64)
    s = 1 - t
    b = np.stack([s ** 3, 3 * s * s * t, 3 * s * t * t, t ** 3], -1)
    db = np.stack([-3 * s * s, 3 * s * s - 6 * s * t, 6 * s * t - 3 * t * t, 3 * t * t], -1)
    return b, db


def teapot(n=3, normalize=True, triangles=False):
    """Newell's 32 patches, each sampled on an (n+1) x (n+1) grid (n x n quads), welded.

    Collapsed patch rows (the lid's knob top, the bottom centre) give triangles instead of
    quads; faces with fewer than 3 distinct corners are dropped. vertex_normals are the exact
    surface normals (z at the two poles, where the patches degenerate). normalize maps the
    teapot into [-1, 1]^3 keeping its proportions (the paper's error test); triangles splits
    the quads (the report feeds triangles to the core so face_index names a flat triangle).
    """
    cp = np.array(teapot_data.VERTICES, dtype=np.float64)
    t = np.linspace(0, 1, n + 1)
    b, db = _bernstein(t)
    keys, pos, nrm, polys, params = {}, [], [], [], []
    for pi, patch in enumerate(teapot_data.PATCHES):
        P = cp[list(patch)].reshape(4, 4, 3)
        S = np.einsum("ui,vj,ijd->uvd", b, b, P)
        Su = np.einsum("ui,vj,ijd->uvd", db, b, P)
        Sv = np.einsum("ui,vj,ijd->uvd", b, db, P)
        N = np.cross(Sv, Su)   # Newell's (u, v) order faces inwards
        ids = np.empty((n + 1, n + 1), dtype=np.int64)
        for i in range(n + 1):
            for j in range(n + 1):
                key = tuple(np.round(S[i, j], 5))
                if key not in keys:
                    keys[key] = len(pos)
                    pos.append(S[i, j])
                    nrm.append(np.zeros(3))
                ids[i, j] = keys[key]
                ln = np.linalg.norm(N[i, j])
                if ln > 1e-9:   # collapsed rows have no normal; patch seams add up
                    nrm[ids[i, j]] = nrm[ids[i, j]] + N[i, j] / ln
        for i in range(n):
            for j in range(n):
                ij = [(i, j), (i, j + 1), (i + 1, j + 1), (i + 1, j)]
                quad = [ids[a, b] for a, b in ij]
                keep = [k for k, v in enumerate(quad) if v not in quad[:k]]
                if len(keep) >= 3:
                    polys.append([quad[k] for k in keep])
                    params.append([(pi, t[ij[k][0]], t[ij[k][1]]) for k in keep])
    pos, nrm = np.array(pos), np.array(nrm)
    for v in range(len(pos)):
        if np.linalg.norm(nrm[v]) < 1e-9:   # a pole: the axis of revolution
            nrm[v] = (0, 0, 1.0 if pos[v, 2] > 1.5 else -1.0)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    lo, hi = pos.min(0), pos.max(0)
    center, scale = ((lo + hi) / 2, 2 / (hi - lo).max()) if normalize else (np.zeros(3), 1.0)
    pos = (pos - center) * scale
    if triangles:
        fan = [(f, k) for f, p in enumerate(polys) for k in range(1, len(p) - 1)]
        params = [[params[f][0], params[f][k], params[f][k + 1]] for f, k in fan]
        polys = [[polys[f][0], polys[f][k], polys[f][k + 1]] for f, k in fan]
    return dict(name="teapot", positions=pos, polygons=polys, sharp=set(), vertex_normals=nrm,
                corner_params=params, center=center, scale=scale)


def teapot_surface(patch, u, v, center=np.zeros(3), scale=1.0):
    """Points and unit outward normals of the exact teapot at (patch (N,), u (N,), v (N,)),
    in the frame of teapot(normalize=...) given its center and scale."""
    cp = np.array(teapot_data.VERTICES, dtype=np.float64)
    P = cp[np.array(teapot_data.PATCHES)[patch]].reshape(-1, 4, 4, 3)
    u, v = np.clip(u, 0.0, 1.0), np.clip(v, 0.0, 1.0)
    bu, _ = _bernstein(u)
    bv, _ = _bernstein(v)
    S = np.einsum("ni,nj,nijd->nd", bu, bv, P)
    # Normals a hair inside the patch: on a collapsed row (the lid's knob top, the bottom
    # centre) the tangents vanish and only the limit from inside has a direction.
    bu, dbu = _bernstein(np.clip(u, 1e-4, 1 - 1e-4))
    bv, dbv = _bernstein(np.clip(v, 1e-4, 1 - 1e-4))
    N = np.cross(np.einsum("ni,nj,nijd->nd", bu, dbv, P), np.einsum("ni,nj,nijd->nd", dbu, bv, P))
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    return (S - center) * scale, N


def face_normals(positions, polygons):
    """Unit Newell normals of polygons."""
    out = np.empty((len(polygons), 3))
    for f, poly in enumerate(polygons):
        v = positions[poly]
        w = np.roll(v, -1, axis=0)
        n = np.array([((v[:, 1] - w[:, 1]) * (v[:, 2] + w[:, 2])).sum(),
                      ((v[:, 2] - w[:, 2]) * (v[:, 0] + w[:, 0])).sum(),
                      ((v[:, 0] - w[:, 0]) * (v[:, 1] + w[:, 1])).sum()])
        out[f] = n / (np.linalg.norm(n) + 1e-300)
    return out


def flat(shape):
    """(corner_vertices, face_offsets) of a shape's polygons, as smoothffd.Mesh takes them."""
    cv = np.concatenate([np.asarray(p) for p in shape["polygons"]]).astype(np.int64)
    fo = np.cumsum([0] + [len(p) for p in shape["polygons"]]).astype(np.int64)
    return cv, fo


# --- lattice deformations, in the lattice's own space: rest points co in [-0.5, 0.5]^3 --------

def bend(co, amount=0.6, axis=2, towards=0):
    """Bends along `axis`: points shift along `towards` by amount * (2 t)^2, t the position
    along the axis, and tilt to stay perpendicular to the bent centre line."""
    out = co.copy()
    t = co[..., axis]
    out[..., towards] += amount * (2 * t) ** 2
    out[..., axis] -= 2 * amount * (2 * t) * co[..., towards] * 0.5
    return out


def twist(co, degrees=60, axis=2):
    """Rotates each slice perpendicular to `axis` by degrees * t (t from -0.5 to 0.5)."""
    out = co.copy()
    a, b = [(1, 2), (2, 0), (0, 1)][axis]
    ang = np.radians(degrees) * co[..., axis]
    c, s = np.cos(ang), np.sin(ang)
    out[..., a] = c * co[..., a] - s * co[..., b]
    out[..., b] = s * co[..., a] + c * co[..., b]
    return out


def bulge(co, amount=0.35, axis=2):
    """Scales the cross-section by 1 + amount * cos(pi t) (widest in the middle)."""
    out = co.copy()
    f = 1 + amount * np.cos(np.pi * co[..., axis])
    for k in range(3):
        if k != axis:
            out[..., k] *= f
    return out


def wave(co, amount=0.12, waves=1.5, axis=0, up=2):
    """Moves points along `up` by amount * sin(2 pi waves t): a wave across the lattice."""
    out = co.copy()
    out[..., up] += amount * np.sin(2 * np.pi * waves * co[..., axis])
    return out


def grid_cube(n=2, size=1.0):
    """The paper's error-test cube [-size, size]^3, each face n x n quads (welded), all 12
    cube edges sharp (tests/meshes.py grid_cube, as a shape)."""
    index, pos, polys = {}, [], []

    def vid(p):
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(pos)
            pos.append(p)
        return index[key]

    for axis in range(3):
        for sign in (-1.0, 1.0):
            nrm = np.zeros(3)
            nrm[axis] = sign
            u, w = np.zeros(3), np.zeros(3)
            u[(axis + 1) % 3], w[(axis + 2) % 3] = 1, 1
            if sign < 0:
                u, w = w, u
            for i in range(n):
                for j in range(n):
                    polys.append([vid(size * (nrm + (-1 + 2 * (i + di) / n) * u
                                              + (-1 + 2 * (j + dj) / n) * w))
                                  for di, dj in ((0, 0), (1, 0), (1, 1), (0, 1))])
    pos = np.array(pos)
    sharp = set()
    for p in polys:
        for k in range(4):
            a, b = p[k], p[(k + 1) % 4]
            mid = (pos[a] + pos[b]) / 2
            if np.sum(np.isclose(np.abs(mid), size)) >= 2:   # on a cube edge
                sharp.add(tuple(sorted((a, b))))
    return dict(name="cube", positions=pos, polygons=polys, sharp=sharp)


def bulge_twist(co, bulge=0.25, twist_degrees=45):
    """tests/meshes.py bulge_twist on lattice rest points co in [-0.5, 0.5]^3 (mapped to
    [-1, 1]^3): pushed outwards by 1 + bulge exp(-|p|^2), then twisted about z by
    twist_degrees over the height."""
    p = 2 * co
    p = p * (1 + bulge * np.exp(-np.sum(p ** 2, axis=-1, keepdims=True)))
    z = p[..., 2]
    zn = (z - z.min()) / max(z.max() - z.min(), 1e-12)
    ang = np.radians(twist_degrees) * (zn - 0.5)
    c, s = np.cos(ang), np.sin(ang)
    out = p.copy()
    out[..., 0] = c * p[..., 0] - s * p[..., 1]
    out[..., 1] = s * p[..., 0] + c * p[..., 1]
    return out / 2
