// bench/native: what measures the CUDA backend but is no part of it (OpenSubdiv keeps its
// far_perf and osd_regression outside the library the same way). Built on the very objects of
// libsmoothffd_cuda.so, in development builds only, as the Python module sffd_bench
// (bench_module.cpp) that bench/bench_gpu.py and bench/ab_time.py use.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "smoothffd/cuda/cuda_evaluator.hpp"
#include "smoothffd/eval/evaluator.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {
namespace bench {

// The timing harness (timing.cu): medians over `iters` frames of the evaluator's stages
// (CUDA events around each, host-paced: "<stage>", "total_events"), the same frames queued
// behind a kernel that holds the stream for 50 us so that the device time alone is measured
// ("total_events_queued", as nvbench's blocking kernel), the whole frame as a CUDA graph
// replayed back to back ("total_graph"), and the floor of this run: a device-to-device copy
// of the frame's output bytes ("d2d_copy_ms", "d2d_bandwidth_GBps", "floor_ms",
// "output_bytes").
StageTimes benchmark(cuda_impl::CudaEvaluator& ev, const float* D, int iters);

// The paper's uniform upsampling baseline (sec. 6.4, Table 5; upsampling_baseline.cu): every
// point of an upsampled rest mesh (PN triangles at a finer level, built by the caller) is
// deformed by the lattice of `plan` (sample_point, eval/stages.hpp), its normal by the
// cofactor of the Jacobian. points: M x 3 rest points, normals: M x 3 unit rest normals,
// pieces: M packed piece indices (10 bits an axis, as Plan::sample_piece).
class UpsamplingBaseline {
 public:
  UpsamplingBaseline(std::shared_ptr<const Plan> plan, const std::vector<float>& points,
                     const std::vector<float>& normals, const std::vector<uint32_t>& pieces);
  ~UpsamplingBaseline();
  int points() const { return count_; }
  size_t output_bytes() const { return 24 * (size_t)count_; }
  size_t control_values() const;  // floats of D: 3 nu nv nw
  // Positions and normals (M x 3 each) to host memory.
  void evaluate(const float* D, float* positions, float* normals);
  // Median ms of the deformation kernel ("deform_samples") over `iters` launches.
  StageTimes benchmark(const float* D, int iters);

 private:
  struct Impl;
  std::shared_ptr<const Plan> plan_;
  int count_ = 0;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bench
}  // namespace sffd
