// Host-side helpers of the CUDA backend (and of bench/native, which builds on it): errors as
// exceptions, device and pinned allocations owned by RAII holders, events, medians.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/cuda/cuda_error.hpp"

namespace sffd {
namespace cuda_impl {

// CudaError, or CudaOutOfMemory for an allocation failure, saying what failed and where.
[[noreturn]] inline void throw_cuda(cudaError_t err, const char* what, const char* file, int line) {
  // No iostreams here: in a module with a statically linked libstdc++ (the device image's
  // GCC) ostream formatting crashed; plain string concatenation does not need locales.
  std::string msg = std::string("CUDA error in ") + what + ": " + cudaGetErrorName(err) + " (" +
                    cudaGetErrorString(err) + ") at " + file + ":" + std::to_string(line);
  if (err == cudaErrorMemoryAllocation) throw CudaOutOfMemory("out of GPU memory: " + msg);
  throw CudaError(msg);
}

#define CK(expr)                                                                         \
  do {                                                                                   \
    cudaError_t err_ = (expr);                                                           \
    if (err_ != cudaSuccess) ::sffd::cuda_impl::throw_cuda(err_, #expr, __FILE__, __LINE__); \
  } while (0)

// After a launch: its configuration error, if any.
#define CK_LAUNCH(name) CK(cudaPeekAtLastError())

// Device allocation owned by a vector of frees.
struct DeviceArena {
  std::vector<void*> blocks;
  size_t bytes = 0;
  template <class T>
  T* alloc(size_t count) {
    if (count == 0) count = 1;
    void* p = nullptr;
    CK(cudaMalloc(&p, count * sizeof(T)));
    blocks.push_back(p);
    bytes += count * sizeof(T);
    return static_cast<T*>(p);
  }
  template <class T>
  T* upload(const std::vector<T>& v) {
    T* p = alloc<T>(v.size());
    if (!v.empty()) CK(cudaMemcpy(p, v.data(), v.size() * sizeof(T), cudaMemcpyHostToDevice));
    return p;
  }
  DeviceArena() = default;
  DeviceArena(const DeviceArena&) = delete;
  DeviceArena& operator=(const DeviceArena&) = delete;
  ~DeviceArena() {
    for (void* p : blocks) cudaFree(p);
  }
};

// Page-locked host memory, grown on demand.
struct PinnedBuffer {
  void* ptr = nullptr;
  size_t bytes = 0;
  void ensure(size_t n) {
    if (n <= bytes) return;
    if (ptr) cudaFreeHost(ptr);
    ptr = nullptr;
    bytes = 0;
    CK(cudaMallocHost(&ptr, n));
    bytes = n;
  }
  PinnedBuffer() = default;
  PinnedBuffer(const PinnedBuffer&) = delete;
  PinnedBuffer& operator=(const PinnedBuffer&) = delete;
  ~PinnedBuffer() {
    if (ptr) cudaFreeHost(ptr);
  }
};

// CUDA events, grown on demand.
struct Events {
  std::vector<cudaEvent_t> ev;
  void ensure(size_t n) {
    while (ev.size() < n) {
      cudaEvent_t e;
      CK(cudaEventCreate(&e));
      ev.push_back(e);
    }
  }
  Events() = default;
  Events(const Events&) = delete;
  Events& operator=(const Events&) = delete;
  ~Events() {
    for (auto e : ev) cudaEventDestroy(e);
  }
};

// ms between two recorded events.
inline float elapsed_ms(cudaEvent_t a, cudaEvent_t b) {
  float ms = 0;
  CK(cudaEventElapsedTime(&ms, a, b));
  return ms;
}

inline double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

inline unsigned blocks_for(long long n, int threads) { return (unsigned)((n + threads - 1) / threads); }

// (usable, message) of the device, and a CudaError saying why when it is not usable
// (device_status.cpp).
std::pair<bool, std::string> device_status();
void init_device();

}  // namespace cuda_impl
}  // namespace sffd
