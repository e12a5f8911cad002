"""Incremental frames: `Deformer.deform(..., out=previous, incremental=True)`.

Each frame recomputes only what reads a control point that moved since the previous one
(native/smoothffd/eval/cpu_update.hpp). Its output must be bitwise a whole frame's from a
fresh Deformer with the same points, over runs of edits (one point, a few, none, all, a
point's weight) in every output kind, on a real asset (Suzanne with Subsurf 1 and its split
normals, tests/data/real) and on a weighted Blender lattice; an edit of one point of a large
lattice must recompute part of the mesh only, and whatever cannot continue (no `out`, another
result, another kind, a new plan) must run a whole frame. The C++ side: test_cpu_evaluator.cpp
(UpdateMatchesWholeFramesBitwise). The add-on's use: tests/blender/check_live.py.
"""

import os

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")

import smoothffd  # noqa: E402
import smoothffd.io  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
KINDS = [(True, "corners"), (True, "compact"), (False, "corners"), (False, "compact")]


def bits(a):
    return np.ascontiguousarray(a).view(np.uint32)


def suzanne():
    return smoothffd.io.read_obj_mesh(os.path.join(HERE, "data", "real", "suzanne_subsurf.obj"))


def lattice_around(positions, shape, weights=False):
    """A Blender lattice (cubic per axis) over the mesh's box, points moved at random."""
    lo, hi = positions.min(0) - 1e-3, positions.max(0) + 1e-3
    g = [np.linspace(-0.5, 0.5, n) for n in shape]
    rest = np.stack(np.meshgrid(*g, indexing="ij"), -1)
    m = np.eye(4)
    m[:3, :3] = np.diag(hi - lo)
    m[:3, 3] = (lo + hi) / 2
    pts = rest + np.random.default_rng(5).normal(scale=0.02, size=rest.shape)
    w = np.random.default_rng(6).uniform(0.3, 1.0, shape) if weights else None
    return smoothffd.BlenderLattice(rest, pts, lattice_to_object=m, point_weights=w)


def edits(lattice, rng):
    """(label, lattice) of a run of edits, each from the one before."""
    shape = lattice.points.shape[:3]
    pts = lattice.points.copy()
    w = None if lattice.point_weights is None else np.array(lattice.point_weights)
    out = []
    for label in ("one", "one", "corner", "three", "none", "all", "weight", "one"):
        if label in ("one", "three"):
            for _ in range(1 if label == "one" else 3):
                pts[tuple(rng.integers(0, shape))] += rng.normal(scale=0.03, size=3)
        elif label == "corner":
            pts[0, 0, 0] += 0.05
        elif label == "all":
            pts = pts + rng.normal(scale=0.01, size=pts.shape)
        elif label == "weight":
            if w is None:
                continue
            w = w.copy()
            w[tuple(rng.integers(0, shape))] = 0.9
        out.append((label, lattice.with_points(pts.copy(), point_weights=w)))
    return out


def check_run(mesh, lattice, level, normals, layout):
    inc = smoothffd.Deformer(mesh, lattice, level=level, device="cpu")
    res = inc.deform(normals=normals, layout=layout)
    nname = "normals" if layout == "compact" else "corner_normals"
    partial = 0
    for label, lat in edits(lattice, np.random.default_rng(11)):
        res = inc.deform(lat, out=res, normals=normals, layout=layout, incremental=True)
        want = smoothffd.Deformer(mesh, lat, level=level, device="cpu").deform(
            normals=normals, layout=layout)
        np.testing.assert_array_equal(bits(res.positions), bits(want.positions), err_msg=label)
        if normals:
            np.testing.assert_array_equal(bits(getattr(res, nname)), bits(getattr(want, nname)),
                                          err_msg=label)
        patches = res.stats["recomputed_patches"]
        if label == "none":
            assert res.stats["changed_points"] == 0 and patches == 0
        elif label == "all":
            assert patches == inc.plan.patches
        else:
            assert patches <= inc.plan.patches
            partial += patches < inc.plan.patches
    return partial


@pytest.mark.parametrize("normals,layout", KINDS)
def test_suzanne_runs_of_edits_are_whole_frames_bitwise(normals, layout):
    mesh = suzanne()
    partial = check_run(mesh, lattice_around(np.asarray(mesh.positions), (6, 5, 6)), 2, normals,
                        layout)
    assert partial >= 3   # single points of a 6x5x6 lattice reach part of Suzanne only


def test_weighted_lattice_runs_of_edits():
    mesh = suzanne()
    lat = lattice_around(np.asarray(mesh.positions), (5, 5, 5), weights=True)
    check_run(mesh, lat, 2, True, "compact")
    check_run(mesh, lat, 3, False, "compact")


def test_one_point_near_a_corner_recomputes_a_small_part():
    # Blender's B-spline lattice, 8 points an axis: point (1, 1, 1) reaches 2 of 5 knot spans
    # along each axis, 8/125 of the lattice's volume (6% of Suzanne's patches).
    mesh = suzanne()
    lat = lattice_around(np.asarray(mesh.positions), (8, 8, 8))
    d = smoothffd.Deformer(mesh, lat, level=2, device="cpu")
    res = d.deform(normals=False)
    pts = lat.points.copy()
    pts[1, 1, 1] += 0.1
    res = d.deform(pts, out=res, normals=False, incremental=True)
    assert res.stats["changed_points"] == 1
    assert 0 < res.stats["recomputed_patches"] < 0.1 * d.plan.patches


def test_what_cannot_continue_runs_a_whole_frame():
    mesh = suzanne()
    lat = lattice_around(np.asarray(mesh.positions), (6, 6, 6))
    d = smoothffd.Deformer(mesh, lat, level=2, device="cpu")
    P = d.plan.patches
    a = d.deform(normals=False)
    pts = lat.points.copy()

    def move():
        pts[2, 2, 2] += 0.01
        return pts.copy()

    a = d.deform(move(), out=a, normals=False, incremental=True)
    assert a.stats["recomputed_patches"] < P
    # No out: fresh arrays, whatever address they get.
    assert d.deform(move(), normals=False, incremental=True).stats["recomputed_patches"] == P
    # Another result than the last one.
    assert d.deform(move(), out=a, normals=False, incremental=True).stats["recomputed_patches"] == P
    # Another kind (normals) into the same result.
    b = d.deform(move(), out=a, normals=True, incremental=True)
    assert b.stats["recomputed_patches"] == P
    b = d.deform(move(), out=b, normals=True, incremental=True)
    assert b.stats["recomputed_patches"] < P
    # Without incremental: a whole frame, as always.
    assert d.deform(move(), out=b).stats["recomputed_patches"] == P
    # A new lattice structure: a new plan, a whole frame, right output.
    lat2 = lattice_around(np.asarray(mesh.positions), (5, 6, 6))
    c = d.deform(lat2, out=b, incremental=True)
    assert c.stats["recomputed_patches"] == d.plan.patches
    want = smoothffd.Deformer(mesh, lat2, level=2, device="cpu").deform()
    np.testing.assert_array_equal(bits(c.positions), bits(want.positions))
    with pytest.raises(TypeError):
        d.deform(out=c, incremental="yes")
