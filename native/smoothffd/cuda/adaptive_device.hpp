// Adaptive tessellation on the device (eval/adaptive.hpp; kernels in adaptive_kernels.cu):
// the reference patches by the shared scalar stages, the decisions of eval/adaptive_stages.hpp
// (count), exclusive scans of the edges' and patches' point and triangle counts (scan), then
// the mesh (emit), one thread an element. Compiled without fast math and without
// floating-point contraction, as the CPU driver is: the same counts, so the same topology,
// and the same floats as the CPU's adaptive frame.
#pragma once

#include <cuda_runtime_api.h>

#include <memory>

#include "smoothffd/eval/adaptive.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {
namespace cuda_impl {

struct AdaptiveSizes {
  long long vertices = 0, triangles = 0;
  double max_bound = 0;
  long long capped = 0;
};

class AdaptiveDevice {
 public:
  // device_view: the plan's tables on the device (the evaluator's PlanView); the few more the
  // emission reads are uploaded here, once.
  AdaptiveDevice(const Plan& plan, const PlanView& device_view);
  ~AdaptiveDevice();
  // One frame from the control values D (device memory), options as eval/adaptive.hpp's
  // (min_* are host arrays; threads, details and counts_only are not used), corner_uv the
  // input's C x 2 UVs in host memory or null. Returns when the sizes are known; the mesh is
  // then complete on the device once the stream reaches this point.
  AdaptiveSizes run(const float* D, const AdaptiveOptions& options, const float* corner_uv, cudaStream_t stream,
                    StageTimes& times);
  // The last frame's arrays into host memory (null: skipped); waits for the stream.
  void copy(float* positions, float* rest_positions, int* triangles, int* face_index, int* triangle_patch,
            float* corner_normals, float* uvs, int* edge_segments, int* patch_level, cudaStream_t stream);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cuda_impl
}  // namespace sffd
