// The CUDA backend's exceptions: CudaError (RuntimeError in Python) and CudaOutOfMemory
// (MemoryError). Thrown inside libsmoothffd_cuda.so (caught at its C boundary, cuda_api.cpp)
// and again by _core's proxy (cuda_proxy/cuda_proxy.cpp) from the boundary's error codes:
// with cuda_api.h, the one header of this library that _core includes.
#pragma once

#include <new>
#include <stdexcept>
#include <string>
#include <utility>

namespace sffd {

class CudaError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class CudaOutOfMemory : public std::bad_alloc {
 public:
  explicit CudaOutOfMemory(std::string msg) : msg_(std::move(msg)) {}
  const char* what() const noexcept override { return msg_.c_str(); }

 private:
  std::string msg_;
};

}  // namespace sffd
