// sffd_bench: bench/native as a Python module for bench/bench_gpu.py and bench/ab_time.py
// (development builds only; next to those scripts). Plans come from smoothffd._core (import
// it first: its Plan type is the one these functions take).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench_native.hpp"

namespace py = pybind11;
using sffd::Plan;
using sffd::StageTimes;

namespace {

template <class T>
using Arr = py::array_t<T, py::array::c_style | py::array::forcecast>;

template <class T>
std::vector<T> to_vector(const Arr<T>& a) {
  return std::vector<T>(a.data(), a.data() + a.size());
}

py::dict times_dict(const StageTimes& t) {
  py::dict d;
  for (const auto& kv : t) d[py::str(kv.first)] = kv.second;
  return d;
}

void check_values(size_t expected, const Arr<float>& D) {
  if ((size_t)D.size() != expected)
    throw std::invalid_argument("control values: expected an (nu*nv*nw, 3) array matching the plan");
}

}  // namespace

PYBIND11_MODULE(sffd_bench, m) {
  m.doc() = "bench/native: the CUDA timing harness and the paper's upsampling baseline";
  m.def(
      "benchmark",
      [](std::shared_ptr<Plan> plan, Arr<float> D, int iters, const std::string& path, int64_t shared_memory_limit) {
        check_values(3 * (size_t)plan->dims[0] * plan->dims[1] * plan->dims[2], D);
        StageTimes t;
        std::string kernel;
        {
          py::gil_scoped_release release;
          sffd::cuda_impl::CudaEvaluator ev(plan, path, shared_memory_limit);
          t = sffd::bench::benchmark(ev, D.data(), iters);
          kernel = ev.kernel();
        }
        py::dict d = times_dict(t);
        d["kernel"] = kernel;
        return d;
      },
      py::arg("plan"), py::arg("values"), py::arg("iters") = 200, py::arg("path") = "fused",
      py::arg("shared_memory_limit") = 0,
      "a CudaEvaluator of the plan (path, shared_memory_limit as smoothffd._core.CudaEvaluator's) "
      "timed over `iters` frames: per-stage medians (ms), total_events, total_events_queued, "
      "total_graph, the d2d floor; 'kernel': what ran (CudaEvaluator.kernel)");
  py::class_<sffd::bench::UpsamplingBaseline, std::shared_ptr<sffd::bench::UpsamplingBaseline>>(m, "UpsamplingBaseline")
      .def(py::init([](std::shared_ptr<Plan> plan, Arr<float> points, Arr<float> normals, Arr<uint32_t> pieces) {
             return std::make_shared<sffd::bench::UpsamplingBaseline>(plan, to_vector(points), to_vector(normals),
                                                                      to_vector(pieces));
           }),
           py::arg("plan"), py::arg("points"), py::arg("normals"), py::arg("pieces"), py::keep_alive<1, 2>())
      .def_property_readonly("points", &sffd::bench::UpsamplingBaseline::points)
      .def_property_readonly("output_bytes", &sffd::bench::UpsamplingBaseline::output_bytes)
      .def(
          "evaluate",
          [](sffd::bench::UpsamplingBaseline& b, Arr<float> D) {
            check_values(b.control_values(), D);
            py::array_t<float> pos({(py::ssize_t)b.points(), (py::ssize_t)3});
            py::array_t<float> nrm({(py::ssize_t)b.points(), (py::ssize_t)3});
            b.evaluate(D.data(), pos.mutable_data(), nrm.mutable_data());
            return py::make_tuple(pos, nrm);
          },
          py::arg("values"))
      .def(
          "benchmark",
          [](sffd::bench::UpsamplingBaseline& b, Arr<float> D, int iters) {
            check_values(b.control_values(), D);
            return times_dict(b.benchmark(D.data(), iters));
          },
          py::arg("values"), py::arg("iters") = 200);
}
