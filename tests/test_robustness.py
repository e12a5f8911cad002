"""Robustness of the Python API: unusual array layouts and dtypes, inputs left
untouched, concurrent use from several threads, memory limits refused with a clear message,
the GIL released during native work, and OBJ reader regressions found by fuzzing.

See docs/robustness.md for the whole picture (native sanitizers, fuzzers, Blender side).
"""
import importlib
import json
import os
import subprocess
import sys
import threading
import warnings

import numpy as np
import pytest

import smoothffd
deform_mod = importlib.import_module("smoothffd.deform")  # the module (smoothffd.deform is the function)
from smoothffd import io as sio

from meshes import cube_mesh, icosphere, random_bspline_lattice, sphere_mesh


def _quad_grid(n=6):
    """Flat-ish n x n quad grid (polygons), values exactly representable in float16."""
    xs = np.arange(n + 1, dtype=np.float64) / n  # multiples of 1/n, n a power of 2 below
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = ((np.arange(X.size) % 3) / 8.0).reshape(X.shape)
    pos = np.stack([X, Y, Z], -1).reshape(-1, 3)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    quads = np.stack([idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], -1).reshape(-1, 4)
    return pos, quads


def _lattice(seed=0):
    rng = np.random.default_rng(seed)
    return random_bspline_lattice(rng, [-0.1, -0.1, -0.2], [1.1, 1.1, 0.6], (4, 4, 3), (2, 2, 2), 0.08)


def _result_arrays(r):
    return [r.positions, r.triangles, r.corner_normals, r.face_index, r.rest_positions]


def _same(a, b):
    for x, y in zip(_result_arrays(a), _result_arrays(b)):
        assert x.shape == y.shape and np.array_equal(x, y)


# --------------------------------------------------------------------------------------
# Array layouts and dtypes: every variant gives the result of plain float64 / int32 input.

def _variants(a, kind):
    """(name, array) pairs holding the same values as `a` in unusual layouts / dtypes."""
    out = []
    wide = np.zeros((a.shape[0], 2 * a.shape[1]), a.dtype)
    wide[:, ::2] = a
    out.append(("non-contiguous", wide[:, ::2]))
    out.append(("fortran", np.asfortranarray(a)))
    ro = a.copy()
    ro.setflags(write=False)
    out.append(("read-only", ro))
    out.append(("big-endian", a.astype(a.dtype.newbyteorder(">"))))
    rev = a[::-1].copy()[::-1]
    out.append(("negative-stride", rev))
    if kind == "float":
        out += [("float32", a.astype(np.float32)), ("float16", a.astype(np.float16)),
                ("big-endian float32", a.astype(">f4")), ("list", a.tolist())]
    else:
        out += [("int64", a.astype(np.int64)), ("uint16", a.astype(np.uint16)),
                ("int8", a.astype(np.int8)), ("big-endian int64", a.astype(">i8")),
                ("float (integral)", a.astype(np.float64)), ("list", a.tolist())]
    return out


@pytest.fixture(scope="module")
def grid_reference():
    pos, quads = _quad_grid(8)
    lat = _lattice()
    cv = quads.reshape(-1).astype(np.int32)
    fo = np.arange(0, len(cv) + 1, 4, dtype=np.int32)
    ref = smoothffd.deform(smoothffd.Mesh(pos, (cv, fo)), lat, level=3, device="cpu")
    return pos, cv, fo, lat, ref


@pytest.mark.parametrize("which", range(9))
def test_position_array_variants(grid_reference, which):
    pos, cv, fo, lat, ref = grid_reference
    name, arr = _variants(pos, "float")[which]
    before = np.array(arr, copy=True)
    r = smoothffd.deform(smoothffd.Mesh(arr, (cv, fo)), lat, level=3, device="cpu")
    _same(r, ref)
    assert np.array_equal(np.asarray(arr), before), f"{name}: input modified"


@pytest.mark.parametrize("which", range(11))
def test_face_array_variants(grid_reference, which):
    pos, cv, fo, lat, ref = grid_reference
    name, arr = _variants(cv.reshape(-1, 4), "int")[which]
    flat = np.asarray(arr).reshape(-1) if not isinstance(arr, list) else sum(arr, [])
    _, fo_arr = _variants(fo.reshape(-1, 1), "int")[which]
    fo_flat = np.asarray(fo_arr).reshape(-1) if not isinstance(fo_arr, list) else sum(fo_arr, [])
    if name == "int8":
        fo_flat = fo  # offsets up to 256 do not fit in int8 (the corner indices do)
    r = smoothffd.deform(smoothffd.Mesh(pos, (flat, fo_flat)), lat, level=3, device="cpu")
    _same(r, ref)


def test_triangle_array_variants_and_int_positions():
    V, F = icosphere(1)
    pos = np.round(V * 64)  # integral positions: int arrays must work too
    lat = smoothffd.BSplineLattice.identity(pos.min(0) - 1, pos.max(0) + 1, shape=(4, 4, 4))
    ref = smoothffd.deform(smoothffd.Mesh(pos, F.astype(np.int32)), lat, level=2, device="cpu")
    for dtype in (np.int64, np.int32, np.int16, np.int8, ">i4", ">i8"):
        r = smoothffd.deform(smoothffd.Mesh(pos.astype(dtype), F), lat, level=2, device="cpu")
        _same(r, ref)
    for name, f in _variants(F.astype(np.int32), "int"):
        r = smoothffd.deform(smoothffd.Mesh(pos, f), lat, level=2, device="cpu")
        _same(r, ref)


def test_lattice_and_normal_array_variants():
    mesh = sphere_mesh(1)
    lat = _lattice(3)
    ref = smoothffd.deform(mesh, lat, level=2, device="cpu")
    cp = lat.control_points
    for name, arr in _variants(cp.reshape(-1, 3), "float"):
        if name in ("float16", "float32", "big-endian float32"):
            continue  # these round the control points: a different (valid) lattice
        arr = np.asarray(arr).reshape(cp.shape)
        r = smoothffd.deform(mesh, lat.with_control_points(arr), level=2, device="cpu")
        _same(r, ref)
    # A genuinely non-contiguous 4-D view, and a read-only one.
    big = np.zeros(cp.shape[:3] + (6,))
    big[..., ::2] = cp
    view = big[..., ::2]
    assert not view.flags.c_contiguous
    _same(smoothffd.deform(mesh, lat.with_control_points(view), level=2, device="cpu"), ref)
    ro = cp.copy()
    ro.setflags(write=False)
    _same(smoothffd.deform(mesh, lat.with_control_points(ro), level=2, device="cpu"), ref)
    # Corner normals in float16 / big-endian / non-contiguous give the same as float32 ones.
    n32 = mesh.corner_normals
    for name, arr in _variants(n32.astype(np.float64), "float"):
        if name == "float16":
            continue  # rounds the normals
        m2 = smoothffd.Mesh(mesh.positions, (mesh.corner_vertices, mesh.face_offsets), arr)
        _same(smoothffd.deform(m2, lat, level=2, device="cpu"), ref)


def test_float16_positions_are_exact_when_representable(grid_reference):
    pos, cv, fo, lat, ref = grid_reference
    assert np.array_equal(pos.astype(np.float16).astype(np.float64), pos)
    r = smoothffd.deform(smoothffd.Mesh(pos.astype(np.float16), (cv, fo)), lat, level=3, device="cpu")
    _same(r, ref)


def test_deformer_points_variants_and_inputs_untouched():
    mesh = cube_mesh()
    lat = smoothffd.BSplineLattice.identity([-0.6] * 3, [0.6] * 3, shape=(4, 4, 4))
    d = smoothffd.Deformer(mesh, lat, level=3, device="cpu")
    cp = lat.control_points * 1.1
    ref = d.deform(cp)
    for name, arr in [("read-only", np.require(cp, requirements="C").copy()),
                      ("big-endian", cp.astype(">f8")), ("float32", cp.astype(np.float32)),
                      ("fortran", np.asfortranarray(cp))]:
        if name == "read-only":
            arr.setflags(write=False)
        before = np.array(arr, copy=True)
        r = d.deform(arr)
        if name == "float32":
            assert np.allclose(r.positions, ref.positions, atol=1e-6)
        else:
            _same(r, ref)
        assert np.array_equal(arr, before)
    # Results of earlier calls are not overwritten by later ones (no shared output buffers).
    r1 = d.deform(cp)
    keep = r1.positions.copy(), r1.corner_normals.copy()
    d.deform(cp * 0.5)
    assert np.array_equal(r1.positions, keep[0]) and np.array_equal(r1.corner_normals, keep[1])
    # Arrays shared between results are read-only, so a caller cannot corrupt the next frame.
    with pytest.raises(ValueError):
        r1.triangles[0, 0] = 0


# --------------------------------------------------------------------------------------
# Threads

def _points_for(lat, k):
    rng = np.random.default_rng(100 + k)
    return lat.control_points + rng.uniform(-0.05, 0.05, lat.control_points.shape)


def test_concurrent_deform_on_one_deformer_matches_serial():
    mesh = sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3, shape=(5, 5, 5))
    d = smoothffd.Deformer(mesh, lat, level=4, device="cpu")
    pts = [_points_for(lat, k) for k in range(8)]
    serial = [d.deform(p) for p in pts]
    out, errors = [None] * (3 * len(pts)), []
    barrier = threading.Barrier(6)

    def work(t):
        try:
            barrier.wait()
            for i in range(t, len(out), 6):
                out[i] = d.deform(pts[i % len(pts)])
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(t,)) for t in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for i, r in enumerate(out):
        _same(r, serial[i % len(pts)])


def test_concurrent_replanning_on_one_deformer():
    """Threads alternating two lattice structures force replans under the lock."""
    mesh = cube_mesh()
    a = smoothffd.BSplineLattice.identity([-0.6] * 3, [0.6] * 3, shape=(4, 4, 4))
    b = smoothffd.BSplineLattice.identity([-0.7] * 3, [0.7] * 3, shape=(5, 3, 4), degree=(3, 2, 1))
    a2 = a.with_control_points(a.control_points * 1.2)
    b2 = b.with_control_points(b.control_points * 0.8)
    d = smoothffd.Deformer(mesh, a, level=3, device="cpu")
    want = {0: d.deform(a2), 1: d.deform(b2)}
    out, errors = [], []

    def work(t):
        try:
            for i in range(6):
                k = (t + i) % 2
                out.append((k, d.deform(a2 if k == 0 else b2)))
        except Exception as exc:  # pragma: no cover
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    assert len(out) == 24
    for k, r in out:
        _same(r, want[k])


def test_different_deformers_in_parallel_match_serial():
    jobs = []
    for k in range(6):
        mesh = sphere_mesh(1 + k % 2) if k % 3 else cube_mesh()
        lat = random_bspline_lattice(np.random.default_rng(k), [-1.2] * 3, [1.2] * 3, (4, 5, 4),
                                     (2, 2, 2), 0.1)
        jobs.append((mesh, lat, 2 + k % 3))
    serial = [smoothffd.deform(m, lat, level=L, device="cpu") for m, lat, L in jobs]
    out, errors = [None] * len(jobs), []

    def work(i):
        try:
            m, lat, L = jobs[i]
            out[i] = smoothffd.Deformer(m, lat, level=L, device="cpu").deform()
        except Exception as exc:  # pragma: no cover
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(len(jobs))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors, errors
    for a, b in zip(out, serial):
        _same(a, b)


def test_thread_count_gives_identical_bits():
    mesh = sphere_mesh(3)
    lat = random_bspline_lattice(np.random.default_rng(9), [-1.1] * 3, [1.1] * 3, (5, 5, 5), (2, 3, 2), 0.1)
    rs = [smoothffd.Deformer(mesh, lat, level=5, device="cpu", threads=t).deform() for t in (1, 2, 3, 8)]
    for r in rs[1:]:
        _same(r, rs[0])


GIL_CHILD = r'''
import json, sys, threading
sys.path.insert(0, sys.argv[1])
import numpy as np
import smoothffd
from meshes import icosphere

# With a switch interval longer than any run here, the main thread never hands the GIL over
# while it runs Python code or a C call that keeps the GIL: another thread gets it only where
# a call releases it.
sys.setswitchinterval(100.0)


def other_thread_ran_inside(fn, tries):
    """Whether a second Python thread, waiting for the GIL from just before the first call,
    got it while fn() ran (calls fn up to `tries` times, until it has)."""
    go, seen, inside = threading.Event(), [], [False]

    def other():
        go.wait()
        seen.append(inside[0])

    t = threading.Thread(target=other)
    t.start()
    go.set()
    for _ in range(tries):
        inside[0] = True
        fn()
        inside[0] = False
        if seen:
            break
    t.join()
    return seen[0]


V, F = icosphere(4)  # 5120 triangles
m = smoothffd.Mesh(V, F)
lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3, shape=(6, 6, 6))
plans = []


def build():
    plans.append(smoothffd._core.build_plan(m.positions, m.corner_vertices, m.face_offsets,
                                            m.corner_normals, m.uvs, m.vertex_weights,
                                            lat._spec, 16))


build()
ev = smoothffd._core.CpuEvaluator(plans[0], 1)
values = np.ascontiguousarray(lat.control_values().reshape(-1, 3), dtype=np.float32)
print(json.dumps({
    # The detector works: sum(range(n)) is C code that never releases the GIL.
    "sum": other_thread_ran_inside(lambda: sum(range(3_000_000)), 3),
    "build_plan": other_thread_ran_inside(build, 20),
    "evaluate": other_thread_ran_inside(lambda: ev.evaluate(values), 20),
}))
'''


def test_gil_released_during_native_work():
    """A Python thread runs while the native core builds a plan and evaluates it (an event:
    the thread ran inside the call, which it can only do where the call released the GIL)."""
    out = subprocess.run([sys.executable, "-c", GIL_CHILD, os.path.dirname(os.path.abspath(__file__))],
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["sum"] is False, f"control: another thread ran inside sum(), which holds the GIL ({r})"
    assert r["build_plan"] is True, f"build_plan held the GIL throughout ({r})"
    assert r["evaluate"] is True, f"evaluate held the GIL throughout ({r})"


# --------------------------------------------------------------------------------------
# Resource limits

def test_absurd_level_is_refused():
    mesh = cube_mesh()
    lat = smoothffd.BSplineLattice.identity([-0.6] * 3, [0.6] * 3)
    for level in (0, -1, deform_mod.MAX_LEVEL + 1, 10**9):
        with pytest.raises(ValueError, match="level"):
            smoothffd.Deformer(mesh, lat, level=level, device="cpu")
    with pytest.raises(TypeError, match="level"):
        smoothffd.Deformer(mesh, lat, level=2.5, device="cpu")


def test_output_that_cannot_fit_is_refused_with_its_size():
    # 2M triangles (small to hold: they reuse 4 vertices) at level 64: ~1.4 TB of output.
    F = np.tile(np.array([[0, 1, 2], [0, 2, 3]], np.int32), (1_000_000, 1))
    mesh = smoothffd.Mesh([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], F)
    lat = smoothffd.BSplineLattice.identity([-0.5] * 3, [1.5] * 3)
    # Refused by the estimate, before anything is allocated: the message says so.
    with pytest.raises(MemoryError, match=r"level 64: the plan and output need at least [0-9.]+ GiB.*available"):
        smoothffd.Deformer(mesh, lat, level=64, device="cpu")


def test_memory_limit_uses_the_available_memory(monkeypatch):
    mesh = sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3)
    need = deform_mod._estimate_bytes(mesh, lat, 10)
    monkeypatch.setattr(deform_mod, "_available_memory", lambda: need - 1)
    with pytest.raises(MemoryError, match="GiB"):
        smoothffd.deform(mesh, lat, level=10, device="cpu")
    monkeypatch.setattr(deform_mod, "_available_memory", lambda: need + 1)
    smoothffd.deform(mesh, lat, level=2, device="cpu")
    monkeypatch.setattr(deform_mod, "_available_memory", lambda: None)  # unknown: no check
    smoothffd.deform(mesh, lat, level=2, device="cpu")


def test_memory_estimate_is_a_fair_lower_bound():
    """Before planning, the estimate takes the input triangles as the patches: for a mesh no
    knot plane cuts, that is the plan, one frame's buffers and one result as measured (the
    clipped case is checked after clipping: tests/test_memory.py)."""
    mesh = sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-2] * 3, [2] * 3, shape=(3, 3, 3))  # no plane cuts
    for L in (2, 6, 12):
        d = smoothffd.Deformer(mesh, lat, level=L, device="cpu")
        r = d.deform()
        p = d.plan
        assert p.patches == mesh.face_count
        static = sum(a.nbytes for a in d._static_arrays().values() if a is not None)
        real = p.bytes + 48 * p.samples + 240 * p.patches + static + r.positions.nbytes + r.corner_normals.nbytes
        est = deform_mod._estimate_bytes(mesh, lat, L)
        assert 0.85 * real <= est <= 1.35 * real, (L, est, real)


# --------------------------------------------------------------------------------------
# OBJ reader: regressions from native/fuzz/fuzz_obj.py

@pytest.mark.parametrize("text", [
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",       # > int64: was OverflowError
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/99999999999999999999 2 3\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -99999999999999999999\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9223372036854775807\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9223372036854775808\n",
    "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/\x00\n",
])
def test_obj_huge_indices_raise_value_error(tmp_path, text):
    p = tmp_path / "m.obj"
    p.write_bytes(text.encode())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match=r"m\.obj:4:"):
            sio.read_obj(p)


def test_obj_fuzz_seed_corpus_only_value_errors():
    """Every committed seed either reads into consistent data or raises ValueError."""
    import pathlib

    corpus = pathlib.Path(__file__).resolve().parents[1] / "native" / "fuzz" / "corpus" / "obj"
    seeds = sorted(corpus.glob("*.obj"))
    assert len(seeds) >= 5
    for s in seeds:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                d = sio.read_obj(s)
            except ValueError:
                continue
        C = len(d.corner_vertices)
        assert d.face_offsets[-1] == C and (np.diff(d.face_offsets) >= 3).all()
        assert C == 0 or 0 <= d.corner_vertices.min() <= d.corner_vertices.max() < len(d.positions)


# --------------------------------------------------------------------------------------
# Magnitudes: the core computes in float32.

@pytest.mark.parametrize("scale", [1e20, 1e30, 1e36])
def test_huge_lattice_displacements_stay_finite(scale):
    """Vectors above ~1.8e19 overflowed the squared length in normalisation (0 * inf = NaN):
    a lattice scaled by 1e20 gave NaN positions. Fixed in core/hd.hpp normalized_or."""
    mesh = sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3, shape=(4, 4, 4))
    cp = lat.control_points * scale * np.array([1, -1.3, 0.7])
    r = smoothffd.deform(mesh, lat.with_control_points(cp), level=2, device="cpu")
    assert np.isfinite(r.positions).all() and np.isfinite(r.corner_normals).all()
    assert np.allclose(np.linalg.norm(r.corner_normals, axis=-1), 1, atol=1e-4)


def test_magnitudes_beyond_float32_are_refused():
    mesh = sphere_mesh(1)
    lat = smoothffd.BSplineLattice.identity([-1.1] * 3, [1.1] * 3, shape=(4, 4, 4))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow warnings on the way to the error either
        for scale in (1e38, 1e39, 1e300):
            with pytest.raises(ValueError, match="float32 range"):
                smoothffd.deform(mesh, lat.with_control_points(lat.control_points * scale), level=2,
                                 device="cpu")
            m2 = smoothffd.Mesh(mesh.positions * scale, (mesh.corner_vertices, mesh.face_offsets))
            with pytest.raises(ValueError, match="mesh: positions up to"):
                smoothffd.Deformer(m2, lat, level=2, device="cpu")
        with pytest.raises(ValueError, match="uvs: values out of the float32 range"):
            smoothffd.Mesh(mesh.positions, (mesh.corner_vertices, mesh.face_offsets),
                           uvs=np.full((len(mesh.corner_vertices), 2), 1e39))


_THREADS_UNDER_LIMIT = r"""
import resource, sys
sys.path.insert(0, sys.argv[1])
import numpy as np, smoothffd, workloads
mesh = workloads.torus(167, 140)   # W1: 2.7 M output vertices at level 10, so 2663 chunks
lo, hi = mesh.positions.min(0) - 0.05, mesh.positions.max(0) + 0.05
lat = smoothffd.BSplineLattice.identity(lo, hi, shape=(5, 5, 5), degree=(2, 2, 2))
pts = lat.control_points + 0.03 * np.random.default_rng(1).standard_normal(lat.control_points.shape)
ref = smoothffd.Deformer(mesh, lat, level=10, device="cpu", threads=2).deform(pts)
# 6 GiB of address space: room for the frame, not for 2663 thread stacks of 8 MiB.
resource.setrlimit(resource.RLIMIT_AS, (6 << 30, 6 << 30))
res = smoothffd.Deformer(mesh, lat, level=10, device="cpu", threads=4096).deform(pts)
print("same:", np.array_equal(res.positions, ref.positions)
      and np.array_equal(res.corner_normals, ref.corner_normals))
"""


def test_more_threads_than_the_system_grants():
    """threads=4096 under a memory limit: thread creation fails part way; the refused chunks
    run in the calling thread (it was std::terminate), with the same result bitwise."""
    import subprocess
    import sys
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(smoothffd.__file__)))
    r = subprocess.run([sys.executable, "-c", _THREADS_UNDER_LIMIT, os.path.join(root, "bench")],
                       capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stdout + r.stderr[-2000:]
    assert "same: True" in r.stdout, r.stdout + r.stderr[-2000:]
