// Whether a CUDA device can run the CUDA evaluator, and precisely why not (cuda_status).
#include <cuda_runtime.h>

#include <string>
#include <utility>

#include "smoothffd/core/platform.hpp"
#include "smoothffd/cuda/cuda_evaluator.hpp"
#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/cuda/kernels.hpp"

#ifdef SFFD_HAVE_BUILD_H
#include "sffd_cuda_build.h"  // SFFD_CUDA_ARCHS: the architectures built (native/CMakeLists.txt)
#endif
#ifndef SFFD_CUDA_ARCHS
#define SFFD_CUDA_ARCHS "unknown architectures"
#endif

namespace sffd {
namespace cuda_impl {

namespace {

std::string version_string(int v) { return std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10); }

std::string error_text(cudaError_t err) {
  return std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
}

}  // namespace

// cuda_status's checks, in the order a user would fix them.
std::pair<bool, std::string> device_status() {
  // 1. The driver. The CUDA runtime (linked statically) loads libcuda.so.1 itself; loading it
  //    here first tells "no driver" apart from the runtime's other errors.
  static void* libcuda = nullptr;  // kept loaded once found
  const std::string driver_library = platform::library_file_name("cuda", 1);
  std::string why;
  if (!libcuda) libcuda = platform::open_library(driver_library, &why);
  if (!libcuda)
    return {false, "no NVIDIA driver: " + driver_library + " could not be loaded (" + why +
                       "); install the NVIDIA driver to use the GPU"};
  int driver = 0;
  cudaError_t err = cudaDriverGetVersion(&driver);
  if (err != cudaSuccess || driver == 0) {
    cudaGetLastError();
    return {false, std::string("the NVIDIA driver (libcuda.so.1) did not report its CUDA version") +
                       (err != cudaSuccess ? " (" + error_text(err) + ")" : std::string())};
  }
  // 2. Driver vs runtime: a CUDA 13.x runtime needs a driver for CUDA 13 or newer.
  if (driver / 1000 < CUDART_VERSION / 1000)
    return {false, "the NVIDIA driver is too old: it supports CUDA " + version_string(driver) + ", this build's CUDA runtime " +
                       version_string(CUDART_VERSION) + " needs a driver for CUDA " +
                       std::to_string(CUDART_VERSION / 1000) + ".0 or newer (update the NVIDIA driver)"};
  // 3. A device.
  int n = 0;
  err = cudaGetDeviceCount(&n);
  if (err != cudaSuccess) {
    cudaGetLastError();
    if (err == cudaErrorInsufficientDriver)
      return {false, "the NVIDIA driver is too old for this build's CUDA runtime " + version_string(CUDART_VERSION) +
                         " (driver supports CUDA " + version_string(driver) + "): " + error_text(err)};
    if (err == cudaErrorNoDevice)
      return {false, "no CUDA device found (NVIDIA driver for CUDA " + version_string(driver) + " present)"};
    return {false, "cudaGetDeviceCount failed: " + error_text(err)};
  }
  if (n == 0) return {false, "no CUDA device found (NVIDIA driver for CUDA " + version_string(driver) + " present)"};
  int dev = 0;
  err = cudaGetDevice(&dev);
  cudaDeviceProp prop;
  if (err == cudaSuccess) err = cudaGetDeviceProperties(&prop, dev);
  if (err != cudaSuccess) {
    cudaGetLastError();
    return {false, "cudaGetDeviceProperties failed: " + error_text(err)};
  }
  const std::string cc = std::to_string(prop.major) + "." + std::to_string(prop.minor);
  // 4. Kernels for its architecture: SASS for it, or PTX the driver can compile for it.
  err = kernel_image_status();
  if (err != cudaSuccess) {
    cudaGetLastError();
    if (err == cudaErrorNoKernelImageForDevice || err == cudaErrorInvalidDeviceFunction ||
        err == cudaErrorUnsupportedPtxVersion || err == cudaErrorInvalidPtx || err == cudaErrorInvalidSource)
      return {false, std::string(prop.name) + " has compute capability " + cc +
                         ", for which this build has no kernels (built for " SFFD_CUDA_ARCHS "): " + error_text(err)};
    return {false, "CUDA initialization failed on " + std::string(prop.name) + ": " + error_text(err)};
  }
  // 5. A context.
  err = cudaFree(nullptr);
  if (err != cudaSuccess) {
    cudaGetLastError();
    return {false, "CUDA context creation failed on " + std::string(prop.name) + ": " + error_text(err)};
  }
  return {true, std::string(prop.name) + " (compute capability " + cc + ", " + std::to_string(prop.totalGlobalMem >> 20) +
                    " MiB, driver for CUDA " + version_string(driver) + ", runtime " + version_string(CUDART_VERSION) +
                    ", kernels " + SFFD_CUDA_ARCHS + ")"};
}

void init_device() {
  auto st = device_status();
  if (!st.first) throw CudaError("no usable CUDA device: " + st.second);
}

std::pair<bool, std::string> cuda_status() { return device_status(); }

const char* build_info() {
  static const std::string info = "CUDA runtime " + version_string(CUDART_VERSION) + " (static), kernels " SFFD_CUDA_ARCHS;
  return info.c_str();
}

}  // namespace cuda_impl
}  // namespace sffd
