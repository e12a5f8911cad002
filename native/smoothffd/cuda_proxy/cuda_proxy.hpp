// The CUDA backend as the Python module sees it: the one C++ proxy over the C boundary of
// libsmoothffd_cuda.so (cuda/cuda_api.h, the only file of that library included here). The
// library is looked for next to the module's own file and dlopened the first time the backend
// is asked for (cuda_status(), or creating an evaluator), so the module itself needs no CUDA
// library at all: without the library, the driver or a GPU, everything on the CPU works and
// cuda_status() says why CUDA does not.
//
// This folder holds the files compiled into _core; cuda/ those of libsmoothffd_cuda.so.
//
// Error codes from the library come back as CudaError (RuntimeError in Python),
// CudaOutOfMemory (MemoryError), std::invalid_argument (ValueError) or std::logic_error.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/cuda/cuda_api.h"
#include "smoothffd/cuda/cuda_error.hpp"
#include "smoothffd/eval/adaptive.hpp"
#include "smoothffd/eval/evaluator.hpp"

namespace sffd {

// Where the module looks for the library: libsmoothffd_cuda.so in the folder of the file that
// holds this code (core/platform.hpp), made absolute once.
std::string cuda_library_path();
// Whether that file exists (the backend was built or shipped); loads nothing.
bool cuda_library_present();
// (usable, message): the device and runtime, or precisely why CUDA cannot be used here: the
// library is not there, failed to load (the loader's message), was built from other sources,
// no NVIDIA driver, driver too old, no device, no kernels for the device's architecture.
std::pair<bool, std::string> cuda_status();
// Page-locked host memory from the CUDA backend (CudaError / CudaOutOfMemory when there is
// none), and its release.
void* cuda_host_alloc(size_t bytes);
void cuda_host_free(void* ptr);

// The CUDA evaluator: each method is one call of the library's table (cuda_api.h says what
// each does), except the frames the table has no entry for, made of those it has:
//   evaluate_positions: evaluate with null corner normals (the whole frame on the device,
//                       positions copied back, the normals' copy back and gather skipped);
//   Frame::incremental: the backend has no incremental path, every frame is a whole one
//                       (last_frame() says so: every control point, every patch).
class CudaEvaluator : public Evaluator {
 public:
  // path: "fused" (or "") or "cublas". shared_memory_limit: 0 (the device's own) or the
  // shared memory a block may opt in to on a smaller device to emulate (at least 48 KiB;
  // tests of the launch choices).
  explicit CudaEvaluator(std::shared_ptr<const Plan> plan, const std::string& path = "",
                         int64_t shared_memory_limit = 0);
  ~CudaEvaluator() override;
  CudaEvaluator(const CudaEvaluator&) = delete;
  CudaEvaluator& operator=(const CudaEvaluator&) = delete;
  std::string name() const override { return "cuda"; }
  const Plan& plan() const override { return *plan_; }

  StageTimes evaluate(const float* D, float* positions, float* corner_normals, Frame frame) override;
  StageTimes evaluate_compact(const float* D, float* positions, float* render_normals, Frame frame) override;
  StageTimes evaluate_positions(const float* D, float* positions, Frame frame) override;
  FrameCounts last_frame() const override { return last_counts_; }

  StageTimes evaluate_device(const float* D);
  std::string path() const;
  std::string kernel() const;
  size_t output_bytes() const;
  size_t device_bytes() const;
  sffd_cuda_limits limits() const;
  // One adaptive frame on the device (cuda_api.h's adaptive_frame and adaptive_copy): the same
  // mesh as the CPU's adaptive_frame (eval/adaptive.hpp), the same counts. options.threads is
  // not used; details is not supported (the CPU's test hook).
  AdaptiveMesh adaptive_frame(const float* D, const float* corner_uv, const AdaptiveOptions& options);
  // Testing (smoothffd._core._testing): the device outputs filled with NaN.
  void testing_poison();

 private:
  // A whole frame's counts: every control point, every patch.
  void count_whole_frame();
  std::shared_ptr<const Plan> plan_;
  const sffd_cuda_api* api_ = nullptr;
  sffd_cuda_evaluator* handle_ = nullptr;
  FrameCounts last_counts_;
};

}  // namespace sffd
