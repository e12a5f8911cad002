"""Memory: build_plan refuses, with the size in the message, a plan whose tables, frame
buffers and result would not fit (checked after the knot-box clipping, which decides the
patch count, before any large table exists); the estimate is held to what real plans take
on the heap, as the C library's allocator counts it; lattices with more knot spans than the
core numbers are refused where they are made."""

import ctypes
import gc
import importlib
import io
import json

import numpy as np
import pytest

import meshes
import smoothffd
from smoothffd import _core, lattice_json

deform = importlib.import_module("smoothffd.deform")  # the module (smoothffd.deform is the function)


def two_triangles():
    V = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * 0.99
    return smoothffd.Mesh(V, np.array([[0, 1, 2], [0, 2, 3]]))


class _MallInfo2(ctypes.Structure):
    _fields_ = [(n, ctypes.c_size_t) for n in
                "arena ordblks smblks hblks hblkhd usmblks fsmblks uordblks fordblks keepcost".split()]


def heap_bytes():
    """Bytes the C library's malloc has handed out and not got back, in every arena and in
    mmapped blocks (glibc's mallinfo2): what the core's vectors and numpy's arrays hold, counted
    by the allocator, not by the code under test."""
    libc = ctypes.CDLL(None)
    libc.mallinfo2.restype = _MallInfo2
    m = libc.mallinfo2()
    return m.uordblks + m.hblkhd


@pytest.mark.parametrize("mesh,shape,degree,level", [
    (meshes.sphere_mesh(2), (4, 4, 4), (2, 2, 2), 8),
    (meshes.sphere_mesh(1), (6, 6, 6), (3, 3, 3), 4),
    (two_triangles(), (12, 12, 2), (1, 1, 1), 6),
])
def test_estimate_matches_real_plans(mesh, shape, degree, level):
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=shape, degree=degree)
    # What the Deformer, its CPU evaluator's frame buffers and one per-corner result hold on
    # the heap (the numpy copies of the static tables included). The collector stays off so
    # that no unrelated object is freed in between.
    gc.collect()
    gc.disable()
    try:
        before = heap_bytes()
        d = smoothffd.Deformer(mesh, lat, level=level, device="cpu")
        result = d.deform()   # also makes the numpy copies of the static tables
        real = heap_bytes() - before
    finally:
        gc.enable()
    assert result.corner_normals is not None
    p = d.plan
    est = _core.estimate_plan_bytes(p.patches, p.sub_vertices, level, p.fit_degree, False)
    assert 0.95 <= est / real <= 1.15, f"estimate {est / 2**20:.3f} MiB, heap {real / 2**20:.3f} MiB"


def test_clipping_into_too_many_patches_is_refused_before_allocating():
    """Two triangles in a 300 x 300 x 2 lattice: about 180k patches after clipping, several
    GiB at level 10. With a 1 GiB limit the plan is refused by name and size."""
    mesh = two_triangles()
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(301, 301, 2), degree=(1, 1, 1))
    with pytest.raises(MemoryError, match=r"patches need about [0-9.]+ GiB .* more than the 1.00 GiB"):
        _core.build_plan(mesh.positions, mesh.corner_vertices, mesh.face_offsets, None, None, None,
                         lat._spec, 10, memory_limit=float(2**30))
    # The same lattice at level 1 fits the limit and plans.
    plan = _core.build_plan(mesh.positions, mesh.corner_vertices, mesh.face_offsets, None, None, None,
                            lat._spec, 1, memory_limit=float(2**30))
    assert plan.patches > 100_000


def test_deformer_checks_available_memory(monkeypatch):
    monkeypatch.setattr(deform, "_available_memory", lambda: 2**30)
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(301, 301, 2), degree=(1, 1, 1))
    with pytest.raises(MemoryError, match="GiB"):
        smoothffd.Deformer(two_triangles(), lat, level=10, device="cpu")


def _meminfo(monkeypatch, text):
    """deform._available_memory reads `text` as /proc/meminfo (one read of a fixed file: the
    real one changes between two reads)."""
    real_open = open

    def fake_open(path, *args, **kw):
        if path == "/proc/meminfo":
            return io.BytesIO(text.encode())
        return real_open(path, *args, **kw)
    monkeypatch.setattr(deform, "open", fake_open, raising=False)


def test_available_memory_is_memavailable(monkeypatch):
    # MemFree alone (free pages: the old check) undercounts; MemAvailable adds what the kernel
    # can reclaim (page cache and the like).
    _meminfo(monkeypatch, "MemTotal:       16000000 kB\nMemFree:          1000000 kB\n"
                          "MemAvailable:    9000000 kB\nBuffers:          200000 kB\n")
    assert deform._available_memory() == 9000000 * 1024


def test_available_memory_without_memavailable_is_free_pages(monkeypatch):
    """Older kernels have no MemAvailable: the free pages then."""
    _meminfo(monkeypatch, "MemTotal:       16000000 kB\nMemFree:          1000000 kB\n")
    pages = {"SC_AVPHYS_PAGES": 250000, "SC_PAGE_SIZE": 4096}
    monkeypatch.setattr(deform.os, "sysconf", pages.__getitem__)
    assert deform._available_memory() == 250000 * 4096


def test_too_many_knot_spans_refused_where_the_lattice_is_made():
    def lattice(n):
        return smoothffd.BSplineLattice(np.zeros((n, 2, 2, 3)), degree=(1, 1, 1),
                                        box_min=[-1, -1, -1], box_max=[1, 1, 1])

    # n points of degree 1: n - 1 spans inside the box and one piece on each side outside it.
    with pytest.raises(ValueError, match=r"control_points: axis u has 1101 knot spans"):
        lattice(1100)
    with pytest.raises(ValueError, match=r"axis u has 1024 knot spans"):
        lattice(1023)
    lattice(1022)  # 1023 pieces: the most the core takes
    doc = {"format": lattice_json.FORMAT, "version": lattice_json.VERSION, "kind": "bspline",
           "shape": [2000, 2, 2], "degree": [1, 1, 1], "control_points": []}
    with pytest.raises(ValueError, match=r"shape\[0\].*2001 polynomial pieces"):
        lattice_json.parse_lattice(json.loads(json.dumps(doc)))
