"""`deform` and the reusable `Deformer`: plan once, evaluate per frame."""

import logging
import os
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import _core
from ._validate import finite_float, flag, positive_int
from .lattice import BlenderLattice, BSplineLattice, _Lattice
from .mesh import Mesh

log = logging.getLogger("smoothffd")

# The core's limits and names (smoothffd.MAX_LEVEL, smoothffd.DEVICES).
MAX_LEVEL = _core.MAX_LEVEL
DEVICES = _core.DEVICES


@dataclass
class Result:
    """Output of one deformation (see docs/api.md)."""

    positions: np.ndarray        # (N, 3) float32; [:V] are the deformed input vertices
    triangles: np.ndarray        # (T, 3) int32
    corner_normals: object       # (T, 3, 3) float32, unit; None from deform(normals=False)
    uvs: object                  # (T, 3, 2) float32 or None
    face_index: np.ndarray       # (T,) int32: input face of each output triangle
    rest_positions: np.ndarray   # (N, 3) float32: preimage on the flat input faces
    sharp_edges: np.ndarray      # (K, 2) int32: output edges where the normals split
    stats: dict = field(default_factory=dict)
    # deform(estimate_error=True), else None: per input face, see Deformer.estimate_errors
    face_error: object = None          # (F,) float32, object units
    face_normal_error: object = None   # (F,) float32, degrees
    # Adaptive results (Deformer's tolerance), else None: the counts this frame used,
    # {"edge_segments": (E,) int32, "patch_level": (P,) int32}; see Deformer.tessellation_counts
    counts: object = None


@dataclass
class CompactResult:
    """Output of one deformation in the compact layout (see docs/api.md).

    Render vertices: an output vertex duplicated only where its normals split (sharp edges),
    so a renderer's vertex buffer is `positions[render_vertex]` with `normals`, indexed by
    `render_triangles`. Only `positions` and `normals` change from frame to frame; the
    topology arrays are made once per plan (read-only, shared between results).
    """

    positions: np.ndarray        # (N, 3) float32 welded output vertices, as Result.positions
    normals: object              # (R, 3) float32 unit normal per render vertex; None (normals=False)
    render_vertex: np.ndarray    # (R,) int32: the output vertex (position) of each render vertex
    render_triangles: np.ndarray # (T, 3) int32: triangles in render vertices
    triangles: np.ndarray        # (T, 3) int32: the same triangles in output vertices
    uvs: object                  # (T, 3, 2) float32 or None
    face_index: np.ndarray       # (T,) int32
    rest_positions: np.ndarray   # (N, 3) float32
    sharp_edges: np.ndarray      # (K, 2) int32
    stats: dict = field(default_factory=dict)
    face_error: object = None          # as Result's
    face_normal_error: object = None

    def corner_normals(self):
        """(T, 3, 3) per-corner normals, Result.corner_normals' layout (a new array)."""
        if self.normals is None:
            return None
        return self.normals[self.render_triangles]


_LAYOUTS = ("corners", "compact")


def cuda_status():
    """(usable, message): whether the CUDA evaluator can run here, and if not, why."""
    return tuple(_core.cuda_status())


def _available_memory():
    """Bytes the system can give without swapping: Linux's MemAvailable (free memory plus the
    page cache and other memory it can reclaim), Windows' available physical memory, else free
    pages, else None (no check)."""
    if sys.platform == "win32":
        return _windows_available_memory()
    try:
        with open("/proc/meminfo", "rb") as fh:
            for line in fh:
                if line.startswith(b"MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _windows_available_memory():
    """GlobalMemoryStatusEx's ullAvailPhys (physical memory free or reclaimable), or None."""
    import ctypes

    class MemoryStatusEx(ctypes.Structure):
        _fields_ = [("dwLength", ctypes.c_uint32), ("dwMemoryLoad", ctypes.c_uint32),
                    ("ullTotalPhys", ctypes.c_uint64), ("ullAvailPhys", ctypes.c_uint64),
                    ("ullTotalPageFile", ctypes.c_uint64), ("ullAvailPageFile", ctypes.c_uint64),
                    ("ullTotalVirtual", ctypes.c_uint64), ("ullAvailVirtual", ctypes.c_uint64),
                    ("ullAvailExtendedVirtual", ctypes.c_uint64)]

    status = MemoryStatusEx()
    status.dwLength = ctypes.sizeof(MemoryStatusEx)
    try:
        if ctypes.windll.kernel32.GlobalMemoryStatusEx(ctypes.byref(status)):
            return int(status.ullAvailPhys)
    except (AttributeError, OSError):
        pass
    return None


def _estimate_bytes(mesh, lattice, level):
    """Lower bound before planning: the input's triangles as patches, as if no knot plane cut
    them (build_plan checks the real count after clipping against memory_limit)."""
    tris = float(np.sum(np.diff(mesh.face_offsets) - 2))
    return _core.estimate_plan_bytes(tris, float(mesh.vertex_count), level,
                                     sum(lattice.degrees), mesh.uvs is not None)


def _positive_distance(value):
    value = finite_float(value, "tolerance")
    if not value > 0:
        raise ValueError(f"tolerance: expected a positive distance, got {value!r}")
    return value


# The core computes in float32: magnitudes near its limit (3.4e38) overflow to inf/NaN in the
# output (a lattice scaled by 1e38, a mesh at 1e38: found by tests/test_robustness.py). Refuse
# them by name instead of returning a silently broken mesh; 1e37 leaves headroom for the sums.
_F32_LIMIT = 1e37


def _control_values_f32(lat):
    values = lat._core_values()   # (n, 3), or (n, 4): a BlenderLattice's point weights last
    for col, what in ((slice(0, 3), "control_points/points: displacements"),
                      (slice(3, 4), "point_weights: strength * weights")):
        big = float(np.abs(values[:, col]).max(initial=0.0))
        if not big <= _F32_LIMIT:
            raise ValueError(f"{what} up to {big:.3g} exceed the float32 range the core "
                             f"computes in (limit {_F32_LIMIT:g})")
    return np.ascontiguousarray(values, dtype=np.float32)


def _check_inputs(mesh, lattice):
    """The mesh and lattice a Deformer plans or follows: their types, and positions within the
    float32 range the core computes in."""
    if not isinstance(mesh, Mesh):
        raise TypeError(f"mesh: expected smoothffd.Mesh, got {type(mesh).__name__}")
    if not isinstance(lattice, _Lattice):
        raise TypeError("lattice: expected smoothffd.BSplineLattice or smoothffd.BlenderLattice, "
                        f"got {type(lattice).__name__}")
    big = float(np.abs(mesh.positions).max(initial=0.0))
    if not big <= _F32_LIMIT:
        raise ValueError(f"mesh: positions up to {big:.3g} exceed the float32 range the core "
                         f"computes in (limit {_F32_LIMIT:g})")


class Deformer:
    """Plans a mesh for a lattice structure once; `deform` then only pushes control values.

    device: "auto" (CUDA when a usable GPU exists, else the CPU), "cpu" or "cuda" (raises
    RuntimeError when no usable GPU). threads: CPU threads (0: all cores).

    tolerance: None (every patch tessellated at `level`, L^2 triangles) or a distance in object
    units: adaptive tessellation, each patch edge and interior as fine as needed for every
    output triangle to be within `tolerance` of the smooth patch it approximates, recomputed
    each frame (docs/algorithm.md, "Adaptive tessellation"); at most `max_level` segments an
    edge. `level` is then unused. Both devices decide the same counts, so give the same
    topology; normals come per corner (layout "corners").
    """

    def __init__(self, mesh, lattice, level=10, device="auto", threads=0, tolerance=None,
                 max_level=MAX_LEVEL):
        _check_inputs(mesh, lattice)
        self.level = positive_int(level, "level", 1, MAX_LEVEL)
        if device not in DEVICES:
            raise ValueError(f"device: expected one of {DEVICES}, got {device!r}")
        self.threads = positive_int(threads, "threads", 0, 4096)
        self._tolerance = None
        if tolerance is not None:
            self._tolerance = _positive_distance(tolerance)
            self.level = 1  # the plan's uniform tables are not used
        self.max_level = max_level
        self.mesh = mesh
        self.requested_device = device
        self._triangulation = None  # the first plan's, once the mesh follows a pose
        self._pool = None  # the CPU evaluators' buffers, once the mesh follows a pose
        # The evaluators keep per-frame buffers, and native work runs without the GIL: calls
        # from several threads take turns instead of racing on those buffers.
        self._lock = threading.Lock()
        need, avail = _estimate_bytes(mesh, lattice, self.level), _available_memory()
        if avail is not None and need > avail:
            raise MemoryError(f"level {self.level}: the plan and output need at least {need / 2**30:.2f} "
                              f"GiB, only {avail / 2**30:.2f} GiB of memory is available")
        self._plan_for(lattice)

    def _plan_for(self, lattice):
        t0 = time.perf_counter()
        m = self.mesh
        avail = _available_memory()
        # A mesh that has followed a pose keeps the triangles of its first plan (follow).
        self.plan = _core.build_plan(m.positions, m.corner_vertices, m.face_offsets,
                                     m.corner_normals, m.uvs, m.vertex_weights,
                                     lattice._spec, self.level,
                                     memory_limit=float(avail) if avail else 0.0,
                                     triangulation=self._triangulation)
        self.plan_ms = (time.perf_counter() - t0) * 1e3
        self.lattice = lattice
        self._key = lattice.structure_key()
        self._static = None
        self.device, self.device_message = self._choose_device()
        self._make_evaluator()

    def _make_evaluator(self):
        self._evaluator = None
        if self.device == "cuda":
            try:
                self._evaluator = _core.CudaEvaluator(self.plan)
            except (RuntimeError, MemoryError) as exc:  # no memory for the plan, driver error
                self._fall_back_to_cpu(exc)
        if self._evaluator is None:
            self._evaluator = _core.CpuEvaluator(self.plan, self.threads, pool=self._pool)

    def follow(self, mesh=None, lattice=None, hold=False):
        """Moves the planned mesh to a new pose without planning it again (an Armature, shape
        keys or a Wave above the lattice, or a lattice that moves with a bone: docs/algorithm.md,
        "A plan that follows the pose").

        mesh: the planned mesh's faces (equal corner_vertices and face_offsets) with new
        positions, and its own corner normals, UVs and vertex weights; None: the mesh as it is.
        lattice: None, or a lattice that differs from the current one at most in its values and
        in where it lies (an equal `basis_key()`: the same kind, degrees or interpolation,
        counts, knots and point weighting; another box or lattice_to_object), which becomes the
        current lattice. The triangles of the
        first plan are kept (not those of the new shape), everything that depends on positions
        is computed again, and the output topology is kept while no face crosses the lattice's
        knot planes differently and no normal splits or joins. Returns True when it was kept:
        the next results' triangles, face_index, sharp_edges and render tables are then the very
        arrays of the last ones (only positions, normals, UVs and rest positions change). The
        next results equal those of a Deformer planned afresh for `mesh` with this plan's
        triangles (`Plan.input_triangles()`) within float rounding.

        hold=True: keep the pieces the faces were cut into by the knot planes (the sub-mesh)
        while each still lies in its knot box, to within what the lattice's weights barely
        tell apart (docs/algorithm.md, "Holding the pieces"); the output topology is then kept
        (unless a normal splits or joins) where a new clipping changes it as soon as one face
        crosses a knot plane differently, which in an animation is nearly every frame. The
        results then differ from a fresh plan's by a small part of the fit's own error, not by
        float rounding. `plan.pieces_held` says whether they were held; where a piece has left
        its box the pose is clipped again as without hold. hold='always': keep them wherever
        they now lie (one topology over a render's motion-blur subframes; the farther a piece
        reaches into the next knot box, the less accurate its patch).
        """
        mesh = self.mesh if mesh is None else mesh
        lattice = self.lattice if lattice is None else lattice
        _check_inputs(mesh, lattice)
        if lattice.basis_key() != self.lattice.basis_key():
            raise ValueError("lattice: its kind, degrees, counts, knots or point weighting differ from "
                             "the planned lattice's (follow moves a lattice, it does not change its basis); "
                             "pass it to deform, which plans it")
        old = self.mesh
        if mesh.vertex_count != old.vertex_count or not (
                np.array_equal(mesh.face_offsets, old.face_offsets)
                and np.array_equal(mesh.corner_vertices, old.corner_vertices)):
            raise ValueError("mesh: its faces differ from the planned mesh's (follow moves the same "
                             "faces to a new pose); plan it with a new Deformer")
        codes = {False: 0, True: 1, "always": 2}
        if not isinstance(hold, (bool, str)) or hold not in codes:
            raise ValueError(f"hold: False, True or 'always', got {hold!r}")
        hold_code = codes[hold]
        with self._lock:
            t0 = time.perf_counter()
            if self._triangulation is None:
                self._triangulation = self.plan.input_triangles()
            avail = _available_memory()
            if self._pool is None:  # the next CPU evaluators take over their predecessor's buffers
                self._pool = _core.BufferPool()
            self._evaluator = None  # the core refuses to change a plan an evaluator reads
            try:
                kept = _core.follow_plan(self.plan, mesh.positions, mesh.corner_vertices,
                                         mesh.face_offsets, mesh.corner_normals, mesh.uvs,
                                         mesh.vertex_weights, lattice._spec,
                                         memory_limit=float(avail) if avail else 0.0,
                                         centre_rows=False, hold=hold_code)
            finally:
                self._make_evaluator()
            self.mesh = mesh
            self.lattice, self._key = lattice, lattice.structure_key()
            if kept and self._static is not None:
                self._static.update(uvs=self.plan.uvs(), rest_positions=self.plan.rest_positions())
                self._freeze()
            else:
                self._static = None
            self.plan_ms = (time.perf_counter() - t0) * 1e3
            return kept

    def _fall_back_to_cpu(self, exc):
        """device='auto': continue on the CPU, saying why; device='cuda': raise."""
        if self.requested_device == "cuda":
            raise exc
        msg = f"smoothffd: CUDA failed ({exc}); continuing on the CPU"
        warnings.warn(msg, RuntimeWarning, stacklevel=3)
        log.warning(msg)
        self.device, self.device_message = "cpu", f"CPU fallback: {exc}"
        self._evaluator = _core.CpuEvaluator(self.plan, self.threads, pool=self._pool)

    def _choose_device(self):
        if self.requested_device == "cpu":
            return "cpu", "CPU requested"
        usable, why = cuda_status()
        if usable:
            return "cuda", why
        if self.requested_device == "cuda":
            raise RuntimeError(f"device='cuda': no usable CUDA device ({why})")
        log.info("smoothffd: using the CPU (%s)", why)
        return "cpu", f"CPU fallback: {why}"

    def _static_arrays(self, compact=False):
        """The plan's arrays that are the same every frame, read-only, made once per plan (the
        render tables only when a compact result asks for them: a corner-layout caller never
        pays for their copy)."""
        p = self.plan
        if self._static is None:
            self._static = dict(triangles=p.triangles(), face_index=p.face_index(), uvs=p.uvs(),
                                rest_positions=p.rest_positions(), sharp_edges=p.sharp_edges())
            self._freeze()
        if compact and "render_vertex" not in self._static:
            self._static["render_vertex"], self._static["render_triangles"] = p.render_vertices()
            self._freeze()
        return self._static

    def _freeze(self):
        for a in self._static.values():
            if a is not None:
                a.setflags(write=False)

    def deform(self, lattice_or_points=None, out=None, normals=True, layout="corners",
               incremental=False, estimate_error=False, hold=None):
        """Deform with new control values.

        Pass a lattice (replanned automatically if its structure differs from the planned
        one) or just its new points: (nu, nv, nw, 3) `points` for a BlenderLattice, control
        points for a BSplineLattice. None re-evaluates the current lattice.

        out: a previous Result of this Deformer whose `positions` and `corner_normals` are
        overwritten in place and returned again (per-frame loops: no fresh 100+ MB arrays to
        fault in). An array of `out` that is None or of another shape (the plan changed) is
        allocated afresh instead.

        normals: False computes the positions only and returns `corner_normals=None`, for
        callers that shade the dense mesh from its own geometry (the Blender add-on's
        viewport). The positions are bitwise the same as with normals=True; on the CPU the
        normal half of the work (the Jacobians the edge adjustment does not need, the normal
        patches, the normal tessellation) is skipped: well under half the time
        (docs/benchmarks.md). On CUDA the device computes
        everything as usual and only the normals' copy back is skipped. `out`'s normals are
        left as they were.

        layout: "corners" returns a Result (normals per triangle corner, (T, 3, 3)); "compact"
        a CompactResult: normals once per render vertex (R, 3), duplicated only where they
        split, the layout renderers and Blender take. Much less memory to write and move
        (docs/benchmarks.md); `out` is then a previous CompactResult.

        incremental: with `out` the result this Deformer returned last (same normals and
        layout, its arrays untouched since), recompute only what reads a control point that
        moved since that call: dragging one point of a large lattice costs the part of the mesh
        it reaches (docs/benchmarks.md). The rest of `out` is kept as it is; the output is
        bitwise a whole frame's. Anything else (no `out`, another result, other normals or
        layout, a new plan) runs a whole frame, as does every frame of the CUDA backend (it
        has no incremental path). `stats["recomputed_patches"]` says what ran.

        estimate_error: also fill `face_error` and `face_normal_error` (estimate_errors) and
        put their maxima in `stats` ("max_face_error", "max_face_normal_error_deg"). Costs
        about one more CPU pass over the samples, on either backend.

        hold (adaptive Deformers only): counts to hold, as `tessellation_counts` returns them
        (the largest over several frames): every frame deformed with the same `hold` gets the
        same topology (a motion-blur shutter, a cache over a frame range), each edge and patch
        at least as fine as held and no finer than its own need; `stats["tolerance_met"]` says
        whether the held counts met the tolerance here.
        """
        if layout not in _LAYOUTS:
            raise ValueError(f"layout: expected one of {_LAYOUTS}, got {layout!r}")
        if self.tolerance is not None and layout != "corners":
            raise ValueError("layout: adaptive tessellation (tolerance) gives normals per corner; "
                             "use layout='corners'")
        estimate_error = flag(estimate_error, "estimate_error")
        if hold is not None and self.tolerance is None:
            raise ValueError("hold: only adaptive Deformers (tolerance=...) have counts to hold")
        with self._lock:
            if hold is not None:
                res = self._deform_adaptive(lattice_or_points, flag(normals, "normals"), hold)
            else:
                res = self._deform(lattice_or_points, out, flag(normals, "normals"), layout,
                                   flag(incremental, "incremental"))
            if estimate_error:
                t0 = time.perf_counter()
                res.face_error, res.face_normal_error = self._face_errors(_control_values_f32(self.lattice))
                res.stats["max_face_error"] = float(res.face_error.max(initial=0.0))
                res.stats["max_face_normal_error_deg"] = float(res.face_normal_error.max(initial=0.0))
                res.stats["estimate_error_ms"] = (time.perf_counter() - t0) * 1e3
            return res

    def estimate_errors(self, lattice_or_points=None):
        """(face_error, face_normal_error), each (F,) float32 for the mesh's F faces: how far
        the smooth result of each input face can be from the exact free-form deformation of the
        face itself, for this lattice (None: the current one) or these new points.

        face_error (object units) bounds, over the face, the distance between each cubic patch
        as fitted and the exact FFD of its flat piece (docs/algorithm.md, "Error estimate"):
        where the face's normals say it is flat, the output's whole distance from the exact
        image; on a smooth face the deliberate rounding toward its normals comes on top and
        is not counted. face_normal_error (degrees) estimates the normal patches' angle from
        the exactly deformed normal field. Per patch the largest over a face; computed on the
        CPU from the plan and the control values. Large values say the lattice is too coarse
        for the mesh there (or too strongly bent): smaller knot spans, or a finer mesh.
        """
        with self._lock:
            values = self._take(lattice_or_points)
            return self._face_errors(values)

    def _take(self, lattice_or_points):
        """Makes a lattice, or new points for the planned one (None: the current lattice), the
        current lattice, replanning when its structure differs; returns its control values
        for the core. Checked before any state changes: a rejected call keeps them."""
        lat = lattice_or_points
        if lat is None:
            lat = self.lattice
        elif not isinstance(lat, _Lattice):
            shape = tuple(np.shape(lat))
            want = self.lattice.shape + (3,)
            if shape != want:
                raise ValueError(f"control_points/points: expected shape {want} like the planned "
                                 f"lattice, got {shape}")
            lat = self.lattice.with_points(lat)
        values = _control_values_f32(lat)
        if lat.structure_key() != self._key:
            self._plan_for(lat)
        self.lattice = lat
        return values

    def _face_errors(self, values):
        geometry, normal = _core.estimate_fit_errors(self.plan, values, self.threads)
        faces = self.plan.patch_face()
        fe = np.zeros(self.mesh.face_count, np.float32)
        fn = np.zeros(self.mesh.face_count, np.float32)
        np.maximum.at(fe, faces, geometry)
        np.maximum.at(fn, faces, normal)
        return fe, fn

    def _deform(self, lattice_or_points, out=None, normals=True, layout="corners",
                incremental=False):
        if self.tolerance is not None:
            return self._deform_adaptive(lattice_or_points, normals)
        values = self._take(lattice_or_points)
        t0 = time.perf_counter()
        compact = layout == "compact"
        nname = "normals" if compact else "corner_normals"
        bufs = {}
        if out is not None:
            kind = CompactResult if compact else Result
            if not isinstance(out, kind):
                raise TypeError(f"out: expected a smoothffd.{kind.__name__} (layout={layout!r}), "
                                f"got {type(out).__name__}")
            # Each array separately: a positions-only result has no normals to reuse.
            p = self.plan
            shapes = {"positions": (p.output_vertices, 3),
                      nname: (p.render_vertex_count, 3) if compact else (p.output_triangles, 3, 3)}
            for name, shape in shapes.items():
                a = getattr(out, name)
                if isinstance(a, np.ndarray) and a.shape == shape and (normals or name == "positions"):
                    bufs[name] = a
            if len(bufs) == 2 and np.shares_memory(bufs["positions"], bufs[nname]):
                raise ValueError(f"out: its positions and {nname} share memory; each frame "
                                 "writes both, so they must be separate arrays")
        # Incremental only into the arrays given (the evaluator also checks they are the ones
        # it wrote last): a fresh array may sit where a dropped one was.
        incremental = incremental and len(bufs) == (2 if normals else 1)
        try:
            positions, nrm, stages = self._evaluate(values, bufs, normals, compact, incremental)
        except (RuntimeError, MemoryError) as exc:
            if self.device != "cuda":
                raise
            self._fall_back_to_cpu(exc)  # e.g. out of device memory for the copy back
            positions, nrm, stages = self._evaluate(values, bufs, normals, compact)
        total = (time.perf_counter() - t0) * 1e3
        s = self._static_arrays(compact)
        p = self.plan
        stats = dict(device=self.device, device_message=self.device_message,
                     plan_ms=self.plan_ms, deform_ms=total, stage_ms=dict(stages),
                     input_vertices=p.input_vertices, patches=p.patches,
                     sub_vertices=p.sub_vertices, output_vertices=p.output_vertices,
                     output_triangles=p.output_triangles, fit_degree=p.fit_degree,
                     level=self.level)
        stats["layout"] = layout
        frame = self._evaluator.last_frame
        stats["changed_points"] = frame["changed_points"]
        stats["recomputed_patches"] = frame["patches"]
        if compact:
            return CompactResult(positions=positions, normals=nrm, render_vertex=s["render_vertex"],
                                 render_triangles=s["render_triangles"], triangles=s["triangles"],
                                 uvs=s["uvs"], face_index=s["face_index"],
                                 rest_positions=s["rest_positions"], sharp_edges=s["sharp_edges"],
                                 stats=stats)
        return Result(positions=positions, triangles=s["triangles"], corner_normals=nrm,
                      uvs=s["uvs"], face_index=s["face_index"],
                      rest_positions=s["rest_positions"], sharp_edges=s["sharp_edges"],
                      stats=stats)

    def tessellation_counts(self, lattice_or_points=None, hold=None):
        """The adaptive counts of a frame without computing its mesh: {"edge_segments": (E,),
        "patch_level": (P,)} int32 (E sub-edges, P patches of the plan). np.maximum of two
        frames' counts, passed as `deform(hold=...)`, gives both frames one topology."""
        if self.tolerance is None:
            raise ValueError("tessellation_counts: only adaptive Deformers (tolerance=...) have counts")
        with self._lock:
            values = self._take(lattice_or_points)
            r = self._adaptive(values, False, None, self._hold_arrays(hold), counts_only=True)
            return {"edge_segments": r["edge_segments"], "patch_level": r["patch_level"]}

    def _hold_arrays(self, hold):
        if hold is None:
            return None, None
        if not isinstance(hold, dict) or set(hold) != {"edge_segments", "patch_level"}:
            raise TypeError("hold: expected a dict with 'edge_segments' and 'patch_level' "
                            "(Deformer.tessellation_counts or Result.counts)")
        p = self.plan
        out = []
        for name, n in (("edge_segments", p.edges), ("patch_level", p.patches)):
            a = np.asarray(hold[name])
            if a.shape != (n,) or a.dtype.kind not in "iu":
                raise ValueError(f"hold[{name!r}]: expected ({n},) integers for this plan, got "
                                 f"{a.shape} {a.dtype}")
            out.append(np.ascontiguousarray(np.clip(a, 1, MAX_LEVEL), dtype=np.int32))
        return out

    def _adaptive(self, values, normals, uvs, held, counts_only=False):
        """The core's adaptive frame on this Deformer's device (CUDA falls back as _deform's)."""
        args = (values, self.tolerance, self.max_level)
        if self.device == "cuda":
            try:
                return self._evaluator.adaptive_frame(*args, normals, uvs, *held, counts_only=counts_only)
            except (RuntimeError, MemoryError) as exc:
                self._fall_back_to_cpu(exc)
        return _core.adaptive_frame(self.plan, *args, self.threads, normals, uvs, False, *held,
                                    counts_only=counts_only)

    def _deform_adaptive(self, lattice_or_points, normals, hold=None):
        """One adaptive frame (Deformer's tolerance): a Result whose topology follows the
        deformed patches; `out` and `incremental` do not apply (each frame is new)."""
        values = self._take(lattice_or_points)
        held = self._hold_arrays(hold)
        t0 = time.perf_counter()
        m = self.mesh
        uvs = None if m.uvs is None else np.ascontiguousarray(m.uvs, dtype=np.float32)
        r = self._adaptive(values, normals, uvs, held)
        total = (time.perf_counter() - t0) * 1e3
        p = self.plan
        stats = dict(device=self.device, device_message=self.device_message, plan_ms=self.plan_ms,
                     deform_ms=total, stage_ms=dict(r["stage_ms"]), input_vertices=p.input_vertices,
                     patches=p.patches, sub_vertices=p.sub_vertices,
                     output_vertices=len(r["positions"]), output_triangles=len(r["triangles"]),
                     fit_degree=p.fit_degree, level=None, layout="corners",
                     tolerance=self.tolerance, max_level=self.max_level,
                     max_tessellation_bound=float(r["max_bound"]), tolerance_met=r["capped"] == 0,
                     capped=int(r["capped"]), max_edge_segments=int(r["edge_segments"].max(initial=0)),
                     max_patch_level=int(r["patch_level"].max(initial=0)),
                     changed_points=None, recomputed_patches=p.patches)
        return Result(positions=r["positions"], triangles=r["triangles"],
                      corner_normals=r["corner_normals"], uvs=r["uvs"], face_index=r["face_index"],
                      rest_positions=r["rest_positions"], sharp_edges=r["sharp_edges"], stats=stats,
                      counts={"edge_segments": r["edge_segments"], "patch_level": r["patch_level"]})

    def _evaluate(self, values, bufs, normals, compact=False, incremental=False):
        """(positions, normals or None, stage times) from the evaluator."""
        kw = dict(bufs, incremental=incremental)
        if compact:
            return self._evaluator.evaluate_compact(values, with_normals=normals, **kw)
        if normals:
            return self._evaluator.evaluate(values, **kw)
        positions, stages = self._evaluator.evaluate_positions(values, **kw)
        return positions, None, stages

    @property
    def tolerance(self):
        """The adaptive tessellation's tolerance (object units), or None (uniform `level`).
        An adaptive Deformer's may be changed between frames (the plan does not depend on it,
        e.g. a screen-space tolerance that follows a camera); a uniform one has none to change."""
        return self._tolerance

    @tolerance.setter
    def tolerance(self, value):
        if self._tolerance is None:
            raise ValueError("tolerance: this Deformer was planned for a uniform level; make one with "
                             "tolerance=... for adaptive tessellation")
        with self._lock:
            self._tolerance = _positive_distance(value)

    @property
    def max_level(self):
        """The most segments an adaptive frame gives a patch edge (1..MAX_LEVEL); settable."""
        return self._max_level

    @max_level.setter
    def max_level(self, value):
        self._max_level = positive_int(value, "max_level", 1, MAX_LEVEL)

    @property
    def splits_normals(self):
        """Whether any output vertex has more than one normal (the plan's splits_normals: sharp
        edges or split input normals). Without splits the "compact" layout's normals are one
        per output vertex."""
        return self.plan.splits_normals

    def deform_on_device(self, lattice_or_points=None):
        """CUDA only: run the frame and keep the result in device memory (no copy back).

        Returns the per-stage device times in ms (CUDA events), for measuring the compute
        apart from the transfer. Raises RuntimeError when this Deformer runs on the CPU.
        """
        if self.device != "cuda":
            raise RuntimeError(f"deform_on_device: this Deformer runs on the CPU ({self.device_message})")
        with self._lock:
            values = self._take(lattice_or_points)
            return dict(self._evaluator.evaluate_device(values))


def deform(mesh, lattice, level=10, device="auto", normals=True, layout="corners", estimate_error=False,
           tolerance=None, max_level=MAX_LEVEL):
    """One-shot smooth FFD of `mesh` by `lattice`; see `Deformer` and docs/api.md."""
    return Deformer(mesh, lattice, level=level, device=device, tolerance=tolerance,
                    max_level=max_level).deform(normals=normals, layout=layout,
                                                estimate_error=estimate_error)
