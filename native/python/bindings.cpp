// The whole Python surface of the native core, thin by design: the `smoothffd` package
// validates every argument before it gets here (python/smoothffd/), these bindings only move
// buffers. Heavy work runs with the GIL released; results are numpy arrays allocated first
// and filled in place (no copy).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/eval/cpu_evaluator.hpp"
#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/sources.hpp"
#include "smoothffd/eval/fit_error.hpp"
#include "smoothffd/eval/adaptive.hpp"
// The CUDA backend, loaded from libsmoothffd_cuda.so when first asked for: the module needs no
// CUDA library (cuda_proxy/cuda_proxy.hpp).
#include "smoothffd/cuda_proxy/cuda_proxy.hpp"

namespace py = pybind11;
using namespace sffd;

template <class T>
using Arr = py::array_t<T, py::array::c_style | py::array::forcecast>;

namespace {

// Ctrl-C during long native work. Python runs signal handlers in the main thread only, between
// bytecodes, so work that holds no GIL would delay KeyboardInterrupt until it ends (a
// 128k-corner polygon took half a minute). `interruptible(fn)` runs fn with the GIL released;
// in the main thread it installs a cancel check (core/cancel.hpp) that the core's loops poll,
// which every 100 ms of work takes the GIL and runs the pending handlers (PyErr_CheckSignals).
// A handler that raises stops the work (sffd::Cancelled unwinds it; nothing half-built is
// kept) and its exception, KeyboardInterrupt for Ctrl-C, is raised here. Work shorter than
// 100 ms never takes the GIL; other threads get no check (no handler could run there).
unsigned long main_thread_ident = 0;  // threading.main_thread().ident, set at import

template <class Fn>
auto interruptible(Fn&& fn) -> decltype(fn()) {
  std::optional<CancelScope> scope;
  if (PyThread_get_thread_ident() == main_thread_ident)
    scope.emplace([] {
      py::gil_scoped_acquire gil;
      return PyErr_CheckSignals() != 0;  // the handler's exception stays set for the catch below
    });
  try {
    py::gil_scoped_release release;
    return fn();
  } catch (const Cancelled&) {  // the GIL is held again here
    if (!PyErr_Occurred()) PyErr_SetNone(PyExc_KeyboardInterrupt);
    throw py::error_already_set();
  }
}

template <class T>
std::vector<T> to_vector(const Arr<T>& a) {
  return std::vector<T>(a.data(), a.data() + a.size());
}

// The add-on calls these bindings directly: a per-axis argument must have one entry an axis.
template <class V>
const V& per_axis(const V& v, const char* name) {
  if (v.size() != 3)
    throw std::invalid_argument(std::string(name) + ": expected 3 values (one per axis), got " +
                                std::to_string(v.size()));
  return v;
}

void set_map(LatticeSpec& spec, const Arr<double>& m) {
  if (m.size() != 12) throw std::invalid_argument("object_to_param: expected a 3 x 4 matrix");
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) spec.object_to_param[r][c] = m.data()[4 * r + c];
}

template <class T>
py::array_t<T> copy_out(const std::vector<T>& v, std::vector<py::ssize_t> shape) {
  py::array_t<T> a(shape);
  if (!v.empty()) std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

// A vector's storage handed to numpy without a copy (the array owns it).
template <class T>
py::array_t<T> move_out(std::vector<T>&& v, std::vector<py::ssize_t> shape) {
  if (v.empty()) return py::array_t<T>(shape);
  auto* owner = new std::vector<T>(std::move(v));
  py::capsule free_when_done(owner, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owner->data(), free_when_done);
}

py::dict times_dict(const StageTimes& t) {
  py::dict d;
  for (auto& kv : t) d[py::str(kv.first)] = kv.second;
  return d;
}

// Evaluates D with any backend into fresh numpy arrays.
// An output array to fill: `given` when it is a writable, C-contiguous float32 array of the
// right shape (a previous frame's result: no fresh pages to fault in), else a new one.
py::array_t<float> output_array(const py::object& given, std::vector<py::ssize_t> shape, const char* name) {
  if (given.is_none()) return py::array_t<float>(shape);
  if (!py::isinstance<py::array_t<float>>(given))
    throw std::invalid_argument(std::string("out: ") + name + " must be a float32 numpy array");
  auto a = given.cast<py::array_t<float>>();
  bool ok = a.ndim() == (py::ssize_t)shape.size() && a.writeable() &&
            (a.flags() & py::array::c_style);
  for (size_t i = 0; ok && i < shape.size(); ++i) ok = a.shape(i) == shape[i];
  if (!ok) throw std::invalid_argument(std::string("out: ") + name + " has the wrong shape or is not writable and C-contiguous");
  return a;
}

// D: (nu*nv*nw, components), components 3, or 4 for a plan with point weights (Plan::components).
void check_values(const Plan& plan, const Arr<float>& D) {
  if (D.ndim() != 2 || D.shape(1) != plan.components ||
      D.shape(0) != (py::ssize_t)plan.dims[0] * plan.dims[1] * plan.dims[2])
    throw std::invalid_argument("control values: expected an (nu*nv*nw, " + std::to_string(plan.components) +
                                ") array matching the plan");
}

Frame frame_of(bool incremental) { return incremental ? Frame::incremental : Frame::whole; }

// The adaptive frame's arguments checked against the plan (both backends' bindings).
AdaptiveOptions adaptive_options(const Plan& plan, const Arr<float>& D, double tolerance, int max_level, bool normals,
                                 const std::optional<Arr<float>>& corner_uv,
                                 const std::optional<Arr<int>>& min_edge_segments,
                                 const std::optional<Arr<int>>& min_patch_level, bool counts_only) {
  check_values(plan, D);
  if (corner_uv && corner_uv->size() != 2 * (py::ssize_t)plan.input_corners)
    throw std::invalid_argument("uvs: expected (C, 2) corner UVs of the planned mesh");
  AdaptiveOptions opt;
  opt.tolerance = tolerance;
  opt.max_level = max_level;
  opt.normals = normals;
  opt.counts_only = counts_only;
  if (min_edge_segments.has_value() != min_patch_level.has_value())
    throw std::invalid_argument("hold: expected both edge_segments and patch_level");
  if (min_edge_segments) {
    if (min_edge_segments->size() != (py::ssize_t)plan.edges || min_patch_level->size() != (py::ssize_t)plan.patches)
      throw std::invalid_argument("hold: expected edge_segments (" + std::to_string(plan.edges) +
                                  ",) and patch_level (" + std::to_string(plan.patches) + ",) of this plan");
    opt.min_edge_segments = min_edge_segments->data();
    opt.min_patch_level = min_patch_level->data();
  }
  return opt;
}

py::dict adaptive_dict(const Plan& plan, AdaptiveMesh&& a, const AdaptiveOptions& opt, bool uvs) {
  py::dict r;
  const py::ssize_t E = (py::ssize_t)a.edge_segments.size(), P = (py::ssize_t)a.patch_level.size();
  r["edge_segments"] = move_out(std::move(a.edge_segments), {E});
  r["patch_level"] = move_out(std::move(a.patch_level), {P});
  r["max_bound"] = a.max_bound;
  r["capped"] = a.capped;
  r["stage_ms"] = times_dict(a.times);
  if (opt.counts_only) return r;
  const py::ssize_t N = (py::ssize_t)a.positions.size() / 3, T = (py::ssize_t)a.face_index.size();
  r["positions"] = move_out(std::move(a.positions), {N, 3});
  r["triangles"] = move_out(std::move(a.triangles), {T, 3});
  r["face_index"] = move_out(std::move(a.face_index), {T});
  r["triangle_patch"] = move_out(std::move(a.triangle_patch), {T});
  r["corner_normals"] = opt.normals ? py::object(move_out(std::move(a.corner_normals), {T, 3, 3})) : py::object(py::none());
  r["uvs"] = uvs ? py::object(move_out(std::move(a.uvs), {T, 3, 2})) : py::object(py::none());
  r["rest_positions"] = move_out(std::move(a.rest_positions), {N, 3});
  const py::ssize_t K = (py::ssize_t)a.sharp_edges.size() / 2;
  r["sharp_edges"] = move_out(std::move(a.sharp_edges), {K, 2});
  if (!a.patch_uniform.empty())
    r["patch_uniform"] = copy_out(std::vector<uint8_t>(a.patch_uniform.begin(), a.patch_uniform.end()), {P});
  if (opt.details) {
    r["patch_control"] = move_out(std::move(a.patch_control), {(py::ssize_t)plan.patches, 10, 3});
    r["corner_bary"] = move_out(std::move(a.corner_bary), {T, 3, 3});
  }
  return r;
}

py::tuple run_evaluator(Evaluator& ev, const Arr<float>& D, const py::object& out_positions,
                        const py::object& out_normals, bool incremental) {
  const Plan& plan = ev.plan();
  check_values(plan, D);
  py::array_t<float> pos = output_array(out_positions, {(py::ssize_t)plan.output_vertices, 3}, "positions");
  py::array_t<float> nrm = output_array(out_normals, {(py::ssize_t)plan.output_triangles, 3, 3}, "corner_normals");
  const float* d = D.data();
  float* p = pos.mutable_data();
  float* n = nrm.mutable_data();
  StageTimes t = interruptible([&] { return ev.evaluate(d, p, n, frame_of(incremental)); });
  return py::make_tuple(pos, nrm, times_dict(t));
}

// Page-locked output arrays for the CUDA evaluator's compact layout: the device copies into
// them at the bus's speed, where a pageable array goes through a staging buffer (about twice
// the time on the H100 machine: docs/benchmarks.md). A block whose last numpy owner is gone
// returns to a small pool, so a frame loop that drops its previous result reuses blocks
// instead of pinning fresh memory (cudaHostAlloc costs milliseconds for such sizes).
class PinnedPool {
 public:
  static PinnedPool& get() {
    static PinnedPool* pool = new PinnedPool;  // never destroyed: no CUDA calls at exit
    return *pool;
  }
  void* take(size_t bytes) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto it = free_.begin(); it != free_.end(); ++it)
        if (it->second == bytes) {
          void* p = it->first;
          free_.erase(it);
          return p;
        }
    }
    return cuda_host_alloc(bytes);
  }
  void give(void* p, size_t bytes) {
    std::lock_guard<std::mutex> lock(mutex_);
    free_.emplace_back(p, bytes);
    while (free_.size() > kKeep) {  // the oldest free block goes back to the system
      cuda_host_free(free_.front().first);
      free_.pop_front();
    }
  }

 private:
  static constexpr size_t kKeep = 4;  // two results' positions and normals
  std::mutex mutex_;
  std::deque<std::pair<void*, size_t>> free_;
};

// A float32 array in a pooled page-locked block, or an ordinary one when the CUDA backend
// has no such memory to give.
py::array_t<float> pinned_array(const std::vector<py::ssize_t>& shape) {
  size_t bytes = sizeof(float);
  for (py::ssize_t s : shape) bytes *= (size_t)s;
  void* p = nullptr;
  try {
    p = PinnedPool::get().take(bytes);
  } catch (const std::exception&) {
    return py::array_t<float>(shape);
  }
  auto* block = new std::pair<void*, size_t>(p, bytes);
  py::capsule owner(block, [](void* b) {
    auto* q = static_cast<std::pair<void*, size_t>*>(b);
    PinnedPool::get().give(q->first, q->second);
    delete q;
  });
  return py::array_t<float>(shape, static_cast<float*>(p), owner);
}

// The compact layout: (positions (N, 3), render-vertex normals (R, 3) or None, stage times).
// normals=False: positions only (the out normals are neither needed nor touched). pinned: new
// arrays in page-locked memory (the CUDA evaluator).
py::tuple run_compact(Evaluator& ev, const Arr<float>& D, const py::object& out_positions,
                      const py::object& out_normals, bool normals, bool pinned, bool incremental) {
  const Plan& plan = ev.plan();
  check_values(plan, D);
  auto out = [&](const py::object& given, py::ssize_t rows, const char* name) {
    if (pinned && given.is_none()) return pinned_array({rows, 3});
    return output_array(given, {rows, 3}, name);
  };
  py::array_t<float> pos = out(out_positions, (py::ssize_t)plan.output_vertices, "positions");
  py::object nrm_obj = py::none();
  float* n = nullptr;
  if (normals) {
    py::array_t<float> nrm = out(out_normals, (py::ssize_t)plan.render_vertices, "normals");
    n = nrm.mutable_data();
    nrm_obj = nrm;
  }
  const float* d = D.data();
  float* p = pos.mutable_data();
  StageTimes t = interruptible([&] { return ev.evaluate_compact(d, p, n, frame_of(incremental)); });
  return py::make_tuple(pos, nrm_obj, times_dict(t));
}

// Positions only: (positions, stage times); validation and out-buffer reuse as run_evaluator's.
py::tuple run_positions(Evaluator& ev, const Arr<float>& D, const py::object& out_positions, bool incremental) {
  const Plan& plan = ev.plan();
  check_values(plan, D);
  py::array_t<float> pos = output_array(out_positions, {(py::ssize_t)plan.output_vertices, 3}, "positions");
  const float* d = D.data();
  float* p = pos.mutable_data();
  StageTimes t = interruptible([&] { return ev.evaluate_positions(d, p, frame_of(incremental)); });
  return py::make_tuple(pos, times_dict(t));
}

const char* const kIncrementalDoc =
    "incremental=True: recompute only what reads a control point whose values differ from the "
    "previous frame's; the output arrays passed must be the previous frame's, of the same kind, "
    "untouched since: the rest of them is kept. Otherwise (another kind or other arrays before, "
    "or none) a whole frame. Bitwise the whole frame's output. A backend without incremental "
    "frames (CUDA) runs a whole frame; last_frame says what ran.";

// The frames of eval/evaluator.hpp, the same methods on every evaluator class. pinned: new
// arrays of the compact layout in page-locked memory (the CUDA evaluator).
template <class Ev>
void def_frames(py::class_<Ev, std::shared_ptr<Ev>>& cls, bool pinned, const char* positions_doc) {
  cls.def("evaluate",
          [](Ev& ev, Arr<float> D, py::object positions, py::object corner_normals, bool incremental) {
            return run_evaluator(ev, D, positions, corner_normals, incremental);
          },
          py::arg("values"), py::arg("positions") = py::none(), py::arg("corner_normals") = py::none(),
          py::kw_only(), py::arg("incremental") = false, kIncrementalDoc)
      .def("evaluate_compact",
           [pinned](Ev& ev, Arr<float> D, py::object positions, py::object normals, bool with_normals,
                    bool incremental) {
             return run_compact(ev, D, positions, normals, with_normals, pinned, incremental);
           },
           py::arg("values"), py::arg("positions") = py::none(), py::arg("normals") = py::none(),
           py::arg("with_normals") = true, py::kw_only(), py::arg("incremental") = false,
           pinned ? "(positions (N, 3), render-vertex normals (R, 3) or None, stage times): the compact "
                    "layout (Plan.render_vertices() for its topology); new arrays are page-locked (pooled). "
                    "incremental: as evaluate's"
                  : "(positions (N, 3), render-vertex normals (R, 3) or None, stage times): the compact "
                    "layout (Plan.render_vertices() for its topology). incremental: as evaluate's")
      .def("evaluate_positions",
           [](Ev& ev, Arr<float> D, py::object positions, bool incremental) {
             return run_positions(ev, D, positions, incremental);
           },
           py::arg("values"), py::arg("positions") = py::none(), py::kw_only(), py::arg("incremental") = false,
           positions_doc)
      .def_property_readonly(
          "last_frame",
          [](const Ev& ev) {
            const FrameCounts c = ev.last_frame();
            py::dict d;
            d["changed_points"] = c.changed_points;
            d["patches"] = c.patches;
            return d;
          },
          "what the last frame recomputed: {'changed_points', 'patches'} (all of either: a whole frame)");
}

}  // namespace

PYBIND11_MODULE(_core, m) {
  m.doc() = "smoothffd native core: lattice bases, plan building, CPU and CUDA evaluators";
  // The core's limits and names, which the Python package, its command line and the Blender
  // add-on ask for instead of restating them.
  m.attr("MAX_LEVEL") = kMaxLevel;
  // What a Deformer runs on: "auto" (CUDA when usable, else the CPU) or an evaluator's name().
  m.attr("DEVICES") = py::make_tuple("auto", "cpu", "cuda");
  main_thread_ident = py::module_::import("threading").attr("main_thread")().attr("ident").cast<unsigned long>();

  py::class_<LatticeSpec, std::shared_ptr<LatticeSpec>>(m, "LatticeSpec")
      .def_static(
          "bspline",
          [](std::vector<int> degree, std::vector<Arr<double>> knots, std::vector<int> counts,
             Arr<double> object_to_param) {
            per_axis(degree, "degree"), per_axis(knots, "knots"), per_axis(counts, "counts");
            auto s = std::make_shared<LatticeSpec>();
            for (int a = 0; a < 3; ++a) s->axes[a] = AxisBasis::bspline(degree[a], to_vector(knots[a]), counts[a]);
            set_map(*s, object_to_param);
            return s;
          },
          py::arg("degree"), py::arg("knots"), py::arg("counts"), py::arg("object_to_param"))
      .def_static(
          "blender",
          [](std::vector<std::string> types, std::vector<int> counts, Arr<double> object_to_param,
             bool point_weights) {
            per_axis(types, "interpolation"), per_axis(counts, "counts");
            auto s = std::make_shared<LatticeSpec>();
            for (int a = 0; a < 3; ++a) s->axes[a] = AxisBasis::blender(parse_blender_interp(types[a]), counts[a]);
            set_map(*s, object_to_param);
            s->components = point_weights ? 4 : 3;
            return s;
          },
          py::arg("interpolation"), py::arg("counts"), py::arg("object_to_param"), py::arg("point_weights") = false,
          "point_weights: control values carry a 4th number, the point's weight (Blender's lattice vertex "
          "group): F = p + w^2 s d (LatticeSpec::components)")
      .def("planes",
           [](const LatticeSpec& s) {
             py::list out;
             for (int a = 0; a < 3; ++a) {
               auto p = s.axes[a].planes();
               out.append(copy_out(p, {(py::ssize_t)p.size()}));
             }
             return out;
           })
      .def_property_readonly("piece_counts",
                             [](const LatticeSpec& s) {
                               return py::make_tuple(s.axes[0].pieces().size(), s.axes[1].pieces().size(),
                                                     s.axes[2].pieces().size());
                             },
                             "polynomial pieces (knot spans) per axis; build_plan takes at most 1023")
      .def_property_readonly("components", [](const LatticeSpec& s) { return s.components; },
                             "control values a point: 3, or 4 with point weights")
      .def_property_readonly("degrees",
                             [](const LatticeSpec& s) {
                               return py::make_tuple(s.axes[0].degree(), s.axes[1].degree(), s.axes[2].degree());
                             })
      .def("evaluate",
           [](const LatticeSpec& s, Arr<double> points, Arr<double> D, Arr<double> weights) {
             py::ssize_t N = points.size() / 3;
             if ((size_t)D.size() != (size_t)s.components * (size_t)s.count())
               throw std::invalid_argument("control values: wrong size for this lattice");
             if (weights.size() != N) throw std::invalid_argument("weights: one per point");
             py::array_t<double> F({N, (py::ssize_t)3}), J({N, (py::ssize_t)3, (py::ssize_t)3});
             const double *p = points.data(), *d = D.data(), *w = weights.data();
             double *f = F.mutable_data(), *j = J.mutable_data();
             interruptible([&] {
               CancelPoller poller;
               for (py::ssize_t i = 0; i < N; ++i) {
                 poller.tick();
                 s.evaluate(p + 3 * i, d, w[i], f + 3 * i, j + 9 * i);
               }
             });
             return py::make_tuple(F, J);
           },
           py::arg("points"), py::arg("values"), py::arg("weights"));

  py::class_<Plan, std::shared_ptr<Plan>>(m, "Plan")
      .def_property_readonly("input_vertices", [](const Plan& p) { return p.input_vertices; })
      .def_property_readonly("sub_vertices", [](const Plan& p) { return p.sub_vertices; })
      .def_property_readonly("patches", [](const Plan& p) { return p.patches; })
      .def_property_readonly("edges", [](const Plan& p) { return p.edges; })
      .def_property_readonly("samples", [](const Plan& p) { return p.samples; })
      .def_property_readonly("fit_degree", [](const Plan& p) { return p.fit_degree; })
      .def_property_readonly("level", [](const Plan& p) { return p.level; })
      .def_property_readonly("output_vertices", [](const Plan& p) { return p.output_vertices; })
      .def_property_readonly("output_triangles", [](const Plan& p) { return p.output_triangles; })
      .def_property_readonly("render_vertex_count", [](const Plan& p) { return p.render_vertices; })
      .def_property_readonly("splits_normals", &Plan::splits_normals,
                             "whether any output vertex has more than one normal (render_vertex_count > "
                             "output_vertices: sharp edges or split input normals)")
      .def_property_readonly("flat_triangles", [](const Plan& p) { return p.flat_triangles; },
                             "input triangles of flat faces (every corner normal is the face's own): "
                             "their patches follow the triangles, not the normals")
      .def_property_readonly("bounded_vertices", [](const Plan& p) { return p.bounded_vertices; },
                             "input vertices whose normals the geometry follows only in part, so "
                             "that no patch folds (docs/algorithm.md)")
      .def_property_readonly("bounded_sub_vertices", [](const Plan& p) { return p.bounded_sub_vertices; },
                             "the same for the vertices of the sub-mesh clipped by the knot planes")
      .def_property_readonly("turned_normals", [](const Plan& p) { return p.turned_normals; },
                             "input triangle corners whose shading normal was turned toward the "
                             "geometry, which cannot follow it (docs/algorithm.md)")
      .def_property_readonly("turned_sub_normals", [](const Plan& p) { return p.turned_sub_normals; },
                             "the same for the corners of the patches (the sub-mesh clipped by the "
                             "knot planes), turned after its own bound")
      .def_property_readonly("pieces_held", [](const Plan& p) { return p.pieces_held; },
                             "whether the last follow_plan(hold=True) held the previous pieces (the "
                             "sub-mesh) instead of clipping the new pose again")
      .def("render_vertices",
           [](const Plan& p) {
             return py::make_tuple(copy_out(p.render_position, {(py::ssize_t)p.render_vertices}),
                                   copy_out(p.render_triangles, {(py::ssize_t)p.output_triangles, 3}));
           },
           "(render_position (R,), render_triangles (T, 3)): output vertex of each render vertex "
           "(an output vertex duplicated where normals split) and the triangles in render vertices")
      .def("render_owner", [](const Plan& p) { return copy_out(p.render_owner, {(py::ssize_t)p.render_vertices, 2}); })
      .def_property_readonly("dims", [](const Plan& p) { return py::make_tuple(p.dims[0], p.dims[1], p.dims[2]); })
      .def_property_readonly("components", [](const Plan& p) { return p.components; },
                             "control values a point: 3, or 4 with point weights (Blender's lattice vertex group)")
      .def_property_readonly("bytes", &Plan::bytes)
      .def_property_readonly("build_ms",
                             [](const Plan& p) { return times_dict(p.build_ms); })
      .def("rest_positions", [](const Plan& p) { return copy_out(p.rest_positions, {(py::ssize_t)p.output_vertices, 3}); })
      .def("triangles", [](const Plan& p) { return copy_out(p.triangles, {(py::ssize_t)p.output_triangles, 3}); })
      .def("face_index", [](const Plan& p) { return copy_out(p.face_index, {(py::ssize_t)p.output_triangles}); })
      .def("uvs",
           [](const Plan& p) -> py::object {
             if (p.uvs.empty()) return py::none();
             return copy_out(p.uvs, {(py::ssize_t)p.output_triangles, 3, 2});
           })
      .def("sharp_edges", [](const Plan& p) { return copy_out(p.sharp_edges, {(py::ssize_t)p.sharp_edges.size() / 2, 2}); })
      .def("patch_face", [](const Plan& p) { return copy_out(p.patch_face, {(py::ssize_t)p.patches}); })
      .def("edge_flags", [](const Plan& p) { return copy_out(p.edge_flags, {(py::ssize_t)p.edges}); })
      .def("edge_vertex", [](const Plan& p) { return copy_out(p.edge_vertex, {(py::ssize_t)p.edges, 2}); })
      .def("patch_vertex", [](const Plan& p) { return copy_out(p.patch_vertex, {(py::ssize_t)p.patches, 3}); })
      // Where the output lies on the input (plan/sources.hpp).
      .def("input_triangles",
           [](const Plan& p) {
             py::ssize_t n = (py::ssize_t)p.input_triangle_face.size();
             return py::make_tuple(copy_out(p.input_triangle_corner, {n, 3}), copy_out(p.input_triangle_face, {n}));
           },
           "(corners (Tin, 3), face (Tin,)): the core's triangulation of the input faces, as input "
           "corner indices, and the face of each triangle")
      .def("patch_sources",
           [](const Plan& p) {
             return py::make_tuple(copy_out(p.patch_triangle, {(py::ssize_t)p.patches}),
                                   copy_out(p.patch_bary, {(py::ssize_t)p.patches, 3, 3}));
           },
           "(triangle (P,), barycentrics (P, 3, 3) float64): the input triangle each patch is a piece "
           "of and its corners' points there; output triangle t belongs to patch t // level**2")
      .def("vertex_sources",
           [](const Plan& p) {
             py::array_t<int> tri((py::ssize_t)p.output_vertices);
             py::array_t<float> bary({(py::ssize_t)p.output_vertices, (py::ssize_t)3});
             int* t = tri.mutable_data();
             float* b = bary.mutable_data();
             interruptible([&] { vertex_sources(p, t, b); });
             return py::make_tuple(tri, bary);
           },
           "(triangle (N,), barycentrics (N, 3)): the input triangle each output vertex lies in "
           "(-1: an input vertex no face uses) and its barycentric point there")
      .def("interpolate_corners",
           [](const Plan& p, Arr<float> values) {
             if (values.ndim() < 1 || values.ndim() > 2 || values.shape(0) != (py::ssize_t)p.input_corners)
               throw std::invalid_argument("values: expected one row per input corner, (C,) or (C, k)");
             const int k = values.ndim() == 2 ? (int)values.shape(1) : 1;
             if (k < 1) throw std::invalid_argument("values: need at least one column");
             std::vector<py::ssize_t> shape = {(py::ssize_t)p.output_triangles, 3};
             if (values.ndim() == 2) shape.push_back(k);
             py::array_t<float> out(shape);
             const float* v = values.data();
             float* o = out.mutable_data();
             interruptible([&] { interpolate_corners(p, v, k, o); });
             return out;
           },
           py::arg("values"),
           "per-corner values (C,) or (C, k) -> (T, 3) or (T, 3, k) float32 at the output corners, "
           "interpolated as the UVs are (a UV map gives exactly Plan.uvs())")
      .def("fit_matrix", [](const Plan& p) { return copy_out(p.fit_matrix, {10, (py::ssize_t)p.columns}); });

  // The mesh arguments of build_plan and follow_plan.
  auto input_mesh = [](Arr<double> positions, Arr<int> corner_vertex, Arr<int> face_offset,
                       std::optional<Arr<float>> corner_normals, std::optional<Arr<float>> uvs,
                       std::optional<Arr<float>> vertex_weights) {
    InputMesh mesh;
    mesh.positions = to_vector(positions);
    mesh.corner_vertex = to_vector(corner_vertex);
    mesh.face_offset = to_vector(face_offset);
    if (corner_normals) mesh.corner_normal = to_vector(*corner_normals);
    if (uvs) mesh.corner_uv = to_vector(*uvs);
    if (vertex_weights) mesh.vertex_weight = to_vector(*vertex_weights);
    return mesh;
  };
  m.def(
      "build_plan",
      [input_mesh](Arr<double> positions, Arr<int> corner_vertex, Arr<int> face_offset,
                   std::optional<Arr<float>> corner_normals, std::optional<Arr<float>> uvs,
                   std::optional<Arr<float>> vertex_weights, const LatticeSpec& spec, int level,
                   double sharp_angle_degrees, double memory_limit, std::optional<py::tuple> triangulation,
                   std::shared_ptr<Plan> like, bool centre_rows) {
        InputMesh mesh = input_mesh(positions, corner_vertex, face_offset, corner_normals, uvs, vertex_weights);
        PlanOptions opt;
        opt.level = level;
        opt.sharp_angle_degrees = sharp_angle_degrees;
        opt.memory_limit = memory_limit;
        opt.centre_rows = centre_rows;
        Triangulation tr;
        if (triangulation) {
          if (triangulation->size() != 2)
            throw std::invalid_argument("triangulation: expected (triangle corners (T, 3), triangle faces (T,))");
          tr.corners = to_vector((*triangulation)[0].cast<Arr<int>>());
          tr.face = to_vector((*triangulation)[1].cast<Arr<int>>());
        }
        const Triangulation* given = triangulation ? &tr : nullptr;
        if (like && given)
          throw std::invalid_argument("build_plan: give triangulation or like, not both (like brings its own)");
        if (like) return interruptible([&] { return std::make_shared<Plan>(build_plan_like(mesh, spec, opt, *like)); });
        return interruptible([&] { return std::make_shared<Plan>(build_plan(mesh, spec, opt, given)); });
      },
      py::arg("positions"), py::arg("corner_vertices"), py::arg("face_offsets"),
      py::arg("corner_normals"), py::arg("uvs"), py::arg("vertex_weights"), py::arg("lattice"),
      py::arg("level"), py::arg("sharp_angle_degrees") = 1.0, py::arg("memory_limit") = 0.0,
      py::arg("triangulation") = py::none(), py::arg("like") = nullptr, py::arg("centre_rows") = true,
      "triangulation: (corners (T, 3), faces (T,)) the input's triangles (a plan's "
      "input_triangles() for the same connectivity), or None: ear clipping by the current shape. "
      "like: a plan of the same connectivity in another pose, whose triangles, and whose pieces' "
      "triangles where the faces cross the knot planes alike, the new plan keeps (follow_plan's "
      "result is build_plan(..., like=the plan before it))");
  m.def(
      "follow_plan",
      [input_mesh](const std::shared_ptr<Plan>& plan, Arr<double> positions, Arr<int> corner_vertex, Arr<int> face_offset,
                   std::optional<Arr<float>> corner_normals, std::optional<Arr<float>> uvs,
                   std::optional<Arr<float>> vertex_weights, const LatticeSpec& spec,
                   double sharp_angle_degrees, double memory_limit, bool centre_rows, int hold) {
        // The Python object and its argument caster hold the plan; anything more is an
        // evaluator (or another owner) that would read tables changed under it.
        if (plan.use_count() > 2)
          throw std::runtime_error("follow_plan: an evaluator still uses this plan; drop it first");
        InputMesh mesh = input_mesh(positions, corner_vertex, face_offset, corner_normals, uvs, vertex_weights);
        PlanOptions opt;
        opt.level = plan->level;
        opt.sharp_angle_degrees = sharp_angle_degrees;
        opt.memory_limit = memory_limit;
        opt.centre_rows = centre_rows;
        if (hold < 0 || hold > 2) throw std::invalid_argument("hold: 0 (clip), 1 (hold the pieces where they stay in their knot boxes) or 2 (hold them)");
        return interruptible([&] { return follow_plan(*plan, mesh, spec, opt, static_cast<HoldPieces>(hold)); });
      },
      py::arg("plan").none(false), py::arg("positions"), py::arg("corner_vertices"), py::arg("face_offsets"),
      py::arg("corner_normals"), py::arg("uvs"), py::arg("vertex_weights"), py::arg("lattice"),
      py::arg("sharp_angle_degrees") = 1.0, py::arg("memory_limit") = 0.0, py::arg("centre_rows") = true,
      py::arg("hold") = 0,
      "Replaces plan by the plan of the same input in a new pose (build_plan with the plan's own "
      "triangulation), keeping its output topology where no face crosses the knot planes "
      "differently and no normal splits or joins; returns whether it was kept. hold: 0 clip the new "
      "pose; 1 keep the previous pieces while each still lies in its knot box (Plan.pieces_held), "
      "the output topology with them unless a normal splits or joins; 2 keep them wherever they "
      "lie. Refused "
      "while an evaluator holds the plan.");
  m.def("estimate_plan_bytes", &estimate_plan_bytes, py::arg("patches"), py::arg("sub_vertices"),
        py::arg("level"), py::arg("fit_degree"), py::arg("uvs"),
        "bytes of a plan, one frame's buffers and one per-corner result (build_plan's memory_limit check)");

  m.def(
      "estimate_fit_errors",
      [](std::shared_ptr<Plan> plan, Arr<float> D, int threads) {
        check_values(*plan, D);
        py::array_t<float> geometry((py::ssize_t)plan->patches), normal((py::ssize_t)plan->patches);
        const float* d = D.data();
        float* g = geometry.mutable_data();
        float* n = normal.mutable_data();
        interruptible([&] {
          estimate_fit_errors(*plan, d, threads, g, n);
          return 0;
        });
        return py::make_tuple(geometry, normal);
      },
      py::arg("plan").none(false), py::arg("values"), py::arg("threads") = 0,
      "(geometry (P,), normal degrees (P,)): per patch, a bound on the distance between the "
      "fitted cubic patch and the exact FFD of its flat piece, and an estimate of the normal "
      "patch's angle from the deformed normal field (eval/fit_error.hpp)");

  m.def(
      "adaptive_frame",
      [](std::shared_ptr<Plan> plan, Arr<float> D, double tolerance, int max_level, int threads, bool normals,
         std::optional<Arr<float>> corner_uv, bool details, std::optional<Arr<int>> min_edge_segments,
         std::optional<Arr<int>> min_patch_level, bool counts_only) {
        AdaptiveOptions opt = adaptive_options(*plan, D, tolerance, max_level, normals, corner_uv, min_edge_segments,
                                               min_patch_level, counts_only);
        opt.threads = threads;
        opt.details = details;
        const float* d = D.data();
        const float* uv = corner_uv ? corner_uv->data() : nullptr;
        return adaptive_dict(*plan, interruptible([&] { return adaptive_frame(*plan, d, uv, opt); }), opt,
                             uv != nullptr);
      },
      py::arg("plan").none(false), py::arg("values"), py::arg("tolerance"), py::arg("max_level"),
      py::arg("threads") = 0, py::arg("normals") = true, py::arg("uvs") = py::none(),
      py::arg("details") = false, py::arg("min_edge_segments") = py::none(), py::arg("min_patch_level") = py::none(),
      py::arg("counts_only") = false,
      "one adaptive frame on the CPU (eval/adaptive.hpp): a dict of the mesh's arrays (positions, "
      "triangles, face_index, triangle_patch, corner_normals, uvs, rest_positions, sharp_edges), the "
      "counts (edge_segments, patch_level, patch_uniform), max_bound, capped and stage_ms; "
      "counts_only: the counts alone; details: also patch_control and corner_bary (tests)");
  m.def(
      "adaptive_bounds",
      [](Arr<float> cp, Arr<double> st, int m, Arr<float> curve, int n) {
        if (cp.size() != 30 || st.size() != 6 || curve.size() != 12)
          throw std::invalid_argument("adaptive_bounds: expected (10, 3), (3, 2), m, (4, 3), n");
        double t[3][2];
        for (int i = 0; i < 6; ++i) t[i / 2][i % 2] = st.data()[i];
        const float* c = curve.data();
        return py::make_tuple(triangle_bound(cp.data(), t), uniform_bound(cp.data(), m),
                              edge_bound(c, c + 3, c + 6, c + 9, n));
      },
      py::arg("control_points"), py::arg("triangle"), py::arg("m"), py::arg("curve"), py::arg("n"),
      "(triangle_bound, uniform_bound, edge_bound) of eval/adaptive.hpp (tests)");

  m.def("cpu_isa", &cpu_isa,
        "the CPU evaluator's default per-frame code path on this CPU: on x86-64 'x86-64-v3' "
        "(AVX2 + FMA, chosen by CPUID) or the baseline 'x86-64-v2'; on 64-bit Arm 'armv8-a' "
        "(NEON, the only path); CpuEvaluator(..., isa=...) picks one");
  py::class_<CpuEvaluator, std::shared_ptr<CpuEvaluator>> cpu(m, "CpuEvaluator");
  py::class_<BufferPool, std::shared_ptr<BufferPool>>(
      m, "BufferPool",
      "Per-frame buffers, and the tables an evaluator derives from its plan, handed from an evaluator "
      "to the next one given the same pool (a plan that follows a moving input gets a new evaluator "
      "each frame): no fresh memory to fault in, and the sample batches and output tables taken "
      "over where the followed plan kept what they are made from")
      .def(py::init<>())
      .def_property_readonly("bytes", &BufferPool::bytes, "memory kept for the next evaluator");
  cpu.def(py::init([](std::shared_ptr<Plan> plan, int threads, const std::string& isa,
                      std::shared_ptr<BufferPool> pool) {
            return interruptible([&] { return std::make_shared<CpuEvaluator>(plan, threads, isa, pool); });
          }),
          // .none(false): None was a null plan and a segfault (found by fuzz_bindings.py)
          py::arg("plan").none(false), py::arg("threads") = 0, py::kw_only(), py::arg("isa") = "auto",
          py::arg("pool") = nullptr, py::keep_alive<1, 2>())
      .def_property_readonly("threads", &CpuEvaluator::threads)
      .def_property_readonly("took_sample_batches", &CpuEvaluator::took_sample_batches,
                             "whether it took its sample batches over from the evaluator before it "
                             "(pool), batching again only the samples whose lattice pieces changed")
      .def_property_readonly("took_output_tables", &CpuEvaluator::took_output_tables,
                             "whether it took its tables of the vertices each patch writes over from "
                             "the evaluator before it (pool): the followed plan kept its output topology")
      .def_property_readonly("isa", &CpuEvaluator::isa,
                             "per-frame code path: 'x86-64-v2' (baseline) or 'x86-64-v3' (AVX2 + FMA)")
      .def_property_readonly("update_bytes", &CpuEvaluator::update_bytes,
                             "host memory of the incremental frames' tables (0 before the first)");
  def_frames(cpu, /*pinned=*/false,
             "(positions (N, 3), stage times): evaluate's positions, bitwise, without the normals "
             "(Jacobians only at the sub-vertices, no normal patches). incremental: as evaluate's");

  // Whether the CUDA backend (libsmoothffd_cuda.so) is next to the module: loads nothing.
  m.attr("cuda_compiled") = cuda_library_present();
  m.attr("cuda_library") = cuda_library_path();
  m.def("cuda_status", []() { return cuda_status(); },
        "(usable, message): whether a CUDA device can run the CUDA evaluator, and precisely why not "
        "(backend not installed or failed to load, no NVIDIA driver, driver too old, no device, no "
        "kernels for the device's architecture); loads the CUDA backend on first call");
  // CUDA errors arrive as CudaError (RuntimeError) or CudaOutOfMemory (MemoryError).
  py::class_<CudaEvaluator, std::shared_ptr<CudaEvaluator>> cuda(m, "CudaEvaluator");
  cuda.def(py::init([](std::shared_ptr<Plan> plan, const std::string& path, int64_t shared_memory_limit) {
             return std::make_shared<CudaEvaluator>(plan, path, shared_memory_limit);
           }),
           py::arg("plan").none(false), py::arg("path") = "", py::arg("shared_memory_limit") = 0, py::keep_alive<1, 2>(),
           "path: 'fused' (or '', the default: one kernel a frame) or 'cublas' (the paper's reference, "
           "needs the toolkit's cuBLAS); shared_memory_limit: 0 (the device's own limits) or the shared "
           "memory (bytes, at least 48 KiB) a block may opt in to on a smaller GPU to emulate: the "
           "launches are planned for it (tests)")
      .def_property_readonly("path", &CudaEvaluator::path, "'fused' or 'cublas' (the constructor's)")
      .def_property_readonly("output_bytes", &CudaEvaluator::output_bytes)
      .def_property_readonly("device_bytes", &CudaEvaluator::device_bytes)
      .def_property_readonly("kernel", &CudaEvaluator::kernel,
                             "what runs a frame: 'inline (boxes)', 'inline (weights)', 'inline (global)' "
                             "(the fused path's kernel, by where its tables fit) or 'cublas'")
      .def_property_readonly(
          "shared_memory",
          [](const CudaEvaluator& ev) {
            const sffd_cuda_limits l = ev.limits();
            py::dict d;
            d["per_block"] = l.per_block;
            d["per_multiprocessor"] = l.per_multiprocessor;
            d["reserved_per_block"] = l.reserved_per_block;
            d["inline_static"] = l.inline_static;
            d["inline_dynamic_max"] = l.inline_dynamic_max;
            d["inline_dynamic"] = l.inline_dynamic;
            d["inline_blocks_per_multiprocessor"] = l.inline_blocks_per_multiprocessor;
            d["multiprocessors"] = l.multiprocessors;
            d["registers_per_multiprocessor"] = l.registers_per_multiprocessor;
            d["compute_capability"] = l.compute_capability;
            return d;
          },
          "the shared-memory limits the launches are planned with (the device's or the emulated "
          "device's) and what they leave the inline kernel")
      .def("evaluate_device",
           [](CudaEvaluator& ev, Arr<float> D) {
             const Plan& plan = ev.plan();
             check_values(plan, D);
             StageTimes t;
             {
               py::gil_scoped_release release;
               t = ev.evaluate_device(D.data());
             }
             return times_dict(t);
           },
           py::arg("values"), "runs the frame on the device only; returns stage times (ms, CUDA events)");
  cuda.def(
      "adaptive_frame",
      [](CudaEvaluator& ev, Arr<float> D, double tolerance, int max_level, bool normals,
         std::optional<Arr<float>> corner_uv, std::optional<Arr<int>> min_edge_segments,
         std::optional<Arr<int>> min_patch_level, bool counts_only) {
        const Plan& plan = ev.plan();
        const AdaptiveOptions opt = adaptive_options(plan, D, tolerance, max_level, normals, corner_uv,
                                                     min_edge_segments, min_patch_level, counts_only);
        const float* d = D.data();
        const float* uv = corner_uv ? corner_uv->data() : nullptr;
        AdaptiveMesh a;
        {
          py::gil_scoped_release release;
          a = ev.adaptive_frame(d, uv, opt);
        }
        return adaptive_dict(plan, std::move(a), opt, uv != nullptr);
      },
      py::arg("values"), py::arg("tolerance"), py::arg("max_level"), py::arg("normals") = true,
      py::arg("uvs") = py::none(), py::arg("min_edge_segments") = py::none(), py::arg("min_patch_level") = py::none(),
      py::arg("counts_only") = false,
      "one adaptive frame on the device: the dict of the CPU's smoothffd._core.adaptive_frame, the same counts "
      "and topology");
  def_frames(cuda, /*pinned=*/true,
             "(positions (N, 3), stage times): the whole frame on the device, positions copied "
             "back, the normals' copy back and gather skipped");

  // Test hooks, not for users: smoothffd._core._testing (the GPU tests use it, also against the
  // installed wheel; it costs nothing until called).
  py::module_ t = m.def_submodule("_testing", "test hooks of the CUDA backend (not an API)");
  t.def("poison", [](CudaEvaluator& ev) { ev.testing_poison(); }, py::arg("evaluator"),
        "fills the evaluator's device outputs and intermediates with NaN: a test then sees every "
        "element a frame must write");
}
