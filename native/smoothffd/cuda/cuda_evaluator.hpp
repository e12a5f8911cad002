// CUDA evaluator, the host side (cuda_evaluator.cpp): the plan's tables are built
// (device_tables.hpp) and uploaded once, each frame uploads only the control values D (for
// the inline kernel and up to 256 control points: inside the launch's parameters) and
// launches the kernels through their launchers (kernels.hpp). The layout is OpenSubdiv's
// osd/cudaEvaluator.cpp + osd/cudaKernel.cu: this class, the kernels in inline_kernel.cu and
// reference_kernels.cu, the device tables in plain C++.
//
// Two paths, chosen by the constructor's `path`:
//   fused:  the default. One persistent kernel a frame, k_inline (inline_kernel.cu), in
//           which each patch evaluates its own samples, fits, adjusts its edges and
//           tessellates, with no intermediate buffers. Its tables live in shared memory where
//           they fit (the samples from the lattice boxes in power form, else from per-sample
//           weights), else in device memory (any plan); kernel() says which.
//   cublas: the paper's formulation, the reference. A sampling kernel and an edge kernel
//           write per-sample and per-edge buffers; gather the deformed samples and normals of
//           every patch into a matrix X (K x 6P), one SGEMM M_r (10 x K) X (Eq. 13), a
//           finishing kernel (exact corners, adjusted edges, centre), one SGEMM B_q (G x 10)
//           C (10 x 6P) (Eq. 14), then a kernel that scatters the welded positions and
//           normalizes normals. cuBLAS is loaded when this path is asked for.
//
// Device-resident output of a frame (compact): positions, N x 3 (welded output vertices), and
// normals per render vertex, R x 3 (Plan::render_*: an output vertex duplicated only where
// normals split; topology Plan::render_triangles, built once with the plan). Each normal is
// written once, by its render owner (patch, grid point). Positions per output vertex rather
// than per render vertex: 12 (N + R) bytes instead of 24 R (equal when nothing splits, fewer
// on sharp meshes), positions along a crease stay bitwise welded (one evaluation each, no
// ulp cracks between duplicates), and it is the layout Blender takes (vertex positions +
// corner normals); a vertex buffer reads positions[render_position[r]]. Per-corner normals
// (T x 3 x 3) exist only in the copy back to the host (evaluate), gathered there.
// Where an output vertex's patches have normals closer than the plan's sharp angle but not
// equal, every corner of its render vertex gets the owner's normal (the CPU evaluator keeps
// each patch's own): a difference below that angle.
//
// Errors (no device, launch failures, out of memory) throw CudaError (std::runtime_error) or
// CudaOutOfMemory (std::bad_alloc): never an abort.
//
// This is the implementation inside libsmoothffd_cuda.so (namespace sffd::cuda_impl), not an
// Evaluator: the library's C boundary (cuda_api.h, its table built in cuda_api.cpp) is the
// one surface others see, and _core's CudaEvaluator (cuda_proxy/cuda_proxy.hpp) the one
// Evaluator over it. The methods here carry that table's names. bench/native links the same
// objects for its timing harness (the hooks at the end of the class).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>

#include "smoothffd/cuda/adaptive_device.hpp"
#include "smoothffd/cuda/cuda_error.hpp"
#include "smoothffd/eval/evaluator.hpp"

namespace sffd {
namespace cuda_impl {

// (usable, message): whether a CUDA device can run the CUDA evaluator, and precisely why not
// (no driver, driver older than this CUDA runtime, no device, no kernel image for the
// device's architecture, context creation failed).
std::pair<bool, std::string> cuda_status();
// The CUDA runtime version and the architectures this library was built for.
const char* build_info();

// The shared-memory limits an evaluator plans its launches with (the device's own, or the
// emulated smaller device's), and what they gave the inline kernel (cuda_api.h's
// sffd_cuda_limits says each field).
struct DeviceLimits {
  int64_t per_block = 0;
  int64_t per_multiprocessor = 0;
  int64_t reserved_per_block = 0;
  int64_t inline_static = 0;
  int64_t inline_dynamic_max = 0;
  int64_t inline_dynamic = 0;
  int32_t inline_blocks_per_multiprocessor = 0;
  int32_t multiprocessors = 0;
  int32_t registers_per_multiprocessor = 0;
  int32_t compute_capability = 0;
};

class CudaEvaluator {
 public:
  // path: "fused" (or "", the default) or "cublas". shared_memory_limit: 0, the device's own
  // shared-memory limits; else the opt-in shared memory a block may use on a smaller device to
  // emulate (at least 48 KiB; tests): the inline kernel's mode (boxes, weights or global) and
  // blocks an SM are chosen for it.
  explicit CudaEvaluator(std::shared_ptr<const Plan> plan, const std::string& path = "",
                         int64_t shared_memory_limit = 0);
  ~CudaEvaluator();
  CudaEvaluator(const CudaEvaluator&) = delete;
  CudaEvaluator& operator=(const CudaEvaluator&) = delete;
  const Plan& plan() const { return *plan_; }

  // Whole frame: D up, device stages, compact copy back through pinned memory, per-corner
  // normals gathered on the host (threads) into corner_normals. corner_normals null:
  // positions only (the device computes everything as usual; only the normals' copy back
  // and host gather are skipped).
  StageTimes evaluate(const float* D, float* positions, float* corner_normals);
  // Whole frame into the compact layout (evaluator.hpp): only the device's own output
  // crosses the bus, straight into page-locked destinations, else overlapped with the host's
  // copy through pinned staging. render_normals null: positions only.
  StageTimes evaluate_compact(const float* D, float* positions, float* render_normals);
  // Device stages only; the result stays on the device. Times from CUDA events.
  StageTimes evaluate_device(const float* D);

  std::string path() const;
  // What runs a frame: "inline (boxes)" (where the lattice boxes fit in shared memory),
  // "inline (weights)", "inline (global)" (the tables in device memory), or "cublas" (the
  // reference path). A static string.
  const char* kernel() const;
  // Bytes of the compact device output of one frame: 12 (N + R).
  size_t output_bytes() const;
  size_t device_bytes() const;  // device memory held
  // The shared-memory limits the launches were planned with.
  DeviceLimits limits() const;

  // Adaptive tessellation (adaptive_device.hpp): one frame from the control values D (host),
  // options and the input's corner UVs (host, C x 2, or null) as eval/adaptive.hpp's; returns
  // the sizes and adds the stage times; adaptive_copy then brings the arrays back.
  AdaptiveSizes adaptive_frame(const float* D, const AdaptiveOptions& options, const float* corner_uv,
                               StageTimes& times);
  void adaptive_copy(float* positions, float* rest_positions, int* triangles, int* face_index, int* triangle_patch,
                     float* corner_normals, float* uvs, int* edge_segments, int* patch_level);

  // ---- Hooks for tests and tools, not for users.
  // Fills the device outputs and intermediates with NaN (tests: every element must be
  // written; the C boundary's testing entry).
  void testing_poison();
  // The stream frames run on (a cudaStream_t), and one frame's device stages enqueued on it
  // with no synchronisation: D (host memory) staged, then mark(name) called before each stage
  // and mark(nullptr) after the last (where bench/native's timing harness records its events).
  void* stream() const;
  void enqueue_frame(const float* D, const std::function<void(const char*)>& mark);

 private:
  struct Impl;
  std::shared_ptr<const Plan> plan_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace cuda_impl
}  // namespace sffd
