// The C boundary of libsmoothffd_cuda.so (cuda_api.h): sffd_cuda_api_v1, the library's only
// exported symbol (cuda_api.map), returns the table of C functions over the library's C++
// implementation (cuda_evaluator.hpp). Every exception stops here and becomes an error code
// and message; every C++ type becomes its C counterpart of cuda_api.h.
#include "smoothffd/cuda/cuda_api.h"

#include <cuda_runtime.h>

#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "smoothffd/cuda/cuda_evaluator.hpp"

using sffd::Plan;
using sffd::StageTimes;
using sffd::cuda_impl::CudaEvaluator;

struct sffd_cuda_evaluator {
  std::unique_ptr<CudaEvaluator> ev;
};

namespace {

void copy_text(char* dst, size_t size, const char* src) {
  if (!dst || size == 0) return;
  std::strncpy(dst, src ? src : "", size - 1);
  dst[size - 1] = '\0';
}

void set_error(sffd_cuda_error* err, int code, const char* msg) {
  if (!err) return;
  err->code = code;
  copy_text(err->message, sizeof(err->message), msg);
}

// Runs fn; any exception becomes the code of the exception the caller's wrapper raises.
template <class Fn>
int guarded(sffd_cuda_error* err, Fn&& fn) noexcept {
  try {
    fn();
    set_error(err, SFFD_CUDA_OK, "");
    return SFFD_CUDA_OK;
  } catch (const sffd::CudaOutOfMemory& e) {
    set_error(err, SFFD_CUDA_OUT_OF_MEMORY, e.what());
  } catch (const std::bad_alloc&) {
    set_error(err, SFFD_CUDA_OUT_OF_MEMORY, "out of host memory in the CUDA backend");
  } catch (const std::invalid_argument& e) {
    set_error(err, SFFD_CUDA_INVALID_ARGUMENT, e.what());
  } catch (const std::logic_error& e) {
    set_error(err, SFFD_CUDA_INTERNAL, e.what());
  } catch (const std::exception& e) {
    set_error(err, SFFD_CUDA_ERROR, e.what());
  } catch (...) {
    set_error(err, SFFD_CUDA_ERROR, "unknown exception in the CUDA backend");
  }
  return err ? err->code : SFFD_CUDA_ERROR;
}

void put_times(const StageTimes& t, sffd_cuda_times* out) {
  if (!out) return;
  out->count = 0;
  for (const auto& kv : t) {
    if (out->count >= SFFD_CUDA_MAX_STAGES) break;
    copy_text(out->name[out->count], sizeof(out->name[0]), kv.first.c_str());
    out->ms[out->count] = kv.second;
    ++out->count;
  }
}

// The caller owns the plan and keeps it alive as long as the evaluator: a non-owning pointer.
std::shared_ptr<const Plan> borrowed(const void* plan) {
  if (!plan) throw std::invalid_argument("plan: null");
  return std::shared_ptr<const Plan>(static_cast<const Plan*>(plan), [](const Plan*) {});
}

uint64_t plan_tail() {
  static const Plan p;
  return (uint64_t)(reinterpret_cast<const char*>(&p.build_ms) - reinterpret_cast<const char*>(&p));
}

int cuda_status(char* message, size_t size) {
  try {
    auto st = sffd::cuda_impl::cuda_status();
    copy_text(message, size, st.second.c_str());
    return st.first ? 1 : 0;
  } catch (const std::exception& e) {
    copy_text(message, size, (std::string("CUDA status check failed: ") + e.what()).c_str());
  } catch (...) {
    copy_text(message, size, "CUDA status check failed");
  }
  return 0;
}

int evaluator_create(const void* plan, const char* path, int64_t limit, sffd_cuda_evaluator** out,
                     sffd_cuda_error* err) {
  return guarded(err, [&] {
    if (!out) throw std::invalid_argument("evaluator_create: null output");
    *out = nullptr;
    auto h = std::make_unique<sffd_cuda_evaluator>();
    h->ev = std::make_unique<CudaEvaluator>(borrowed(plan), path ? path : "", limit);
    *out = h.release();
  });
}

void evaluator_destroy(sffd_cuda_evaluator* ev) {
  try {
    delete ev;
  } catch (...) {
  }
}

int evaluate(sffd_cuda_evaluator* ev, const float* D, float* positions, float* corner_normals, sffd_cuda_times* times,
             sffd_cuda_error* err) {
  return guarded(err, [&] { put_times(ev->ev->evaluate(D, positions, corner_normals), times); });
}

int evaluate_device(sffd_cuda_evaluator* ev, const float* D, sffd_cuda_times* times, sffd_cuda_error* err) {
  return guarded(err, [&] { put_times(ev->ev->evaluate_device(D), times); });
}

const char* path(const sffd_cuda_evaluator* ev) {
  try {
    return ev->ev->path() == "cublas" ? "cublas" : "fused";
  } catch (...) {
    return "fused";
  }
}

const char* kernel(const sffd_cuda_evaluator* ev) { return ev->ev->kernel(); }

uint64_t output_bytes(const sffd_cuda_evaluator* ev) { return ev->ev->output_bytes(); }
uint64_t device_bytes(const sffd_cuda_evaluator* ev) { return ev->ev->device_bytes(); }

void limits(const sffd_cuda_evaluator* ev, sffd_cuda_limits* out) {
  if (!out) return;
  const sffd::cuda_impl::DeviceLimits l = ev->ev->limits();
  *out = sffd_cuda_limits{};
  out->per_block = l.per_block;
  out->per_multiprocessor = l.per_multiprocessor;
  out->reserved_per_block = l.reserved_per_block;
  out->inline_static = l.inline_static;
  out->inline_dynamic_max = l.inline_dynamic_max;
  out->inline_dynamic = l.inline_dynamic;
  out->inline_blocks_per_multiprocessor = l.inline_blocks_per_multiprocessor;
  out->multiprocessors = l.multiprocessors;
  out->registers_per_multiprocessor = l.registers_per_multiprocessor;
  out->compute_capability = l.compute_capability;
}

int testing_poison(sffd_cuda_evaluator* ev, sffd_cuda_error* err) {
  return guarded(err, [&] { ev->ev->testing_poison(); });
}

int evaluate_compact(sffd_cuda_evaluator* ev, const float* D, float* positions, float* render_normals,
                     sffd_cuda_times* times, sffd_cuda_error* err) {
  return guarded(err, [&] { put_times(ev->ev->evaluate_compact(D, positions, render_normals), times); });
}

int adaptive_frame(sffd_cuda_evaluator* ev, const float* D, double tolerance, int max_level,
                   const int* min_edge_segments, const int* min_patch_level, const float* corner_uv, int with_normals,
                   int64_t* vertices, int64_t* triangles, double* max_bound, int64_t* capped, sffd_cuda_times* times,
                   sffd_cuda_error* err) {
  return guarded(err, [&] {
    sffd::AdaptiveOptions o;
    o.tolerance = tolerance;
    o.max_level = max_level;
    o.normals = with_normals != 0;
    o.min_edge_segments = min_edge_segments;
    o.min_patch_level = min_patch_level;
    StageTimes t;
    const sffd::cuda_impl::AdaptiveSizes z = ev->ev->adaptive_frame(D, o, corner_uv, t);
    *vertices = z.vertices;
    *triangles = z.triangles;
    *max_bound = z.max_bound;
    *capped = z.capped;
    put_times(t, times);
  });
}

int adaptive_copy(sffd_cuda_evaluator* ev, float* positions, float* rest_positions, int* triangles, int* face_index,
                  int* triangle_patch, float* corner_normals, float* uvs, int* edge_segments, int* patch_level,
                  sffd_cuda_error* err) {
  return guarded(err, [&] {
    ev->ev->adaptive_copy(positions, rest_positions, triangles, face_index, triangle_patch, corner_normals, uvs,
                          edge_segments, patch_level);
  });
}

int host_alloc(uint64_t bytes, void** out, sffd_cuda_error* err) {
  return guarded(err, [&] {
    if (!out) throw std::invalid_argument("host_alloc: null output");
    *out = nullptr;
    const cudaError_t rc = cudaHostAlloc(out, bytes ? bytes : 1, cudaHostAllocDefault);
    if (rc == cudaErrorMemoryAllocation) {
      (void)cudaGetLastError();
      throw sffd::CudaOutOfMemory("no page-locked host memory for " + std::to_string(bytes) + " bytes");
    }
    if (rc != cudaSuccess) {
      (void)cudaGetLastError();
      throw sffd::CudaError(std::string("cudaHostAlloc: ") + cudaGetErrorString(rc));
    }
  });
}

void host_free(void* ptr) {
  if (ptr) (void)cudaFreeHost(ptr);
}

sffd_cuda_api make_api() noexcept {
  sffd_cuda_api a{};
  a.abi_version = SFFD_CUDA_ABI_VERSION;
  a.api_size = sizeof(sffd_cuda_api);
  a.plan_size = sizeof(Plan);
  try {
    a.plan_tail = plan_tail();
    a.build_info = sffd::cuda_impl::build_info();
  } catch (...) {
    a.plan_tail = 0;
    a.build_info = "";
  }
  a.cuda_status = cuda_status;
  a.evaluator_create = evaluator_create;
  a.evaluator_destroy = evaluator_destroy;
  a.evaluate = evaluate;
  a.evaluate_device = evaluate_device;
  a.path = path;
  a.kernel = kernel;
  a.output_bytes = output_bytes;
  a.device_bytes = device_bytes;
  a.limits = limits;
  a.evaluate_compact = evaluate_compact;
  a.host_alloc = host_alloc;
  a.host_free = host_free;
  a.testing_poison = testing_poison;
  a.adaptive_frame = adaptive_frame;
  a.adaptive_copy = adaptive_copy;
  return a;
}

}  // namespace

// The library's one exported name (Linux: the version script hides the rest as well).
#if defined(_WIN32)
#define SFFD_CUDA_EXPORT __declspec(dllexport)
#else
#define SFFD_CUDA_EXPORT __attribute__((visibility("default")))
#endif

extern "C" SFFD_CUDA_EXPORT const sffd_cuda_api* sffd_cuda_api_v1(void) {
  static const sffd_cuda_api api = make_api();
  return &api;
}
