// The reference path's two products through cuBLAS (the paper's formulation), loaded with
// dlopen when that path is first asked for: neither the module nor libsmoothffd_cuda.so needs
// libcublas to load, and the fused path runs without it (the shipped wheels carry no cuBLAS).
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <string>

namespace sffd {
namespace cuda_impl {

// The cuBLAS library this backend loads (libcublas.so.13 for the toolkit it is built with).
const std::string& cublas_library();

class CublasGemm {
 public:
  // Loads cuBLAS (CudaError saying what is missing and where it was looked for), creates a
  // handle on `stream` with plain FP32 math (no TF32) and a workspace of its own.
  explicit CublasGemm(cudaStream_t stream);
  ~CublasGemm();
  CublasGemm(const CublasGemm&) = delete;
  CublasGemm& operator=(const CublasGemm&) = delete;
  // C (m x n) = A^T B, column-major: A is k x m (lda), B k x n (ldb), C m x n (ldc).
  void gemm_tn(int m, int n, int k, const float* A, int lda, const float* B, int ldb, float* C, int ldc);

 private:
  void* handle_ = nullptr;
  void* workspace_ = nullptr;
};

}  // namespace cuda_impl
}  // namespace sffd
