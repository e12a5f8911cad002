// cuBLAS for the reference path (cublas_gemm.hpp): the few functions it calls, by their
// exported (_v2) names, from the library found at run time. Its own dependency, libcublasLt,
// is its business.
#include "smoothffd/cuda/cublas_gemm.hpp"

#include <cublas_v2.h>  // types only

#include <mutex>
#include <type_traits>

#include "smoothffd/core/platform.hpp"
#include "smoothffd/cuda/device_memory.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

const char* cublas_name(cublasStatus_t s) {
  switch (s) {
    case CUBLAS_STATUS_NOT_INITIALIZED: return "CUBLAS_STATUS_NOT_INITIALIZED";
    case CUBLAS_STATUS_ALLOC_FAILED: return "CUBLAS_STATUS_ALLOC_FAILED";
    case CUBLAS_STATUS_INVALID_VALUE: return "CUBLAS_STATUS_INVALID_VALUE";
    case CUBLAS_STATUS_ARCH_MISMATCH: return "CUBLAS_STATUS_ARCH_MISMATCH";
    case CUBLAS_STATUS_EXECUTION_FAILED: return "CUBLAS_STATUS_EXECUTION_FAILED";
    case CUBLAS_STATUS_INTERNAL_ERROR: return "CUBLAS_STATUS_INTERNAL_ERROR";
    case CUBLAS_STATUS_NOT_SUPPORTED: return "CUBLAS_STATUS_NOT_SUPPORTED";
    default: return "CUBLAS error";
  }
}

#define CKB(expr)                                                                         \
  do {                                                                                    \
    cublasStatus_t st_ = (expr);                                                          \
    if (st_ == CUBLAS_STATUS_ALLOC_FAILED)                                                \
      throw CudaOutOfMemory(std::string("out of GPU memory in cuBLAS: ") + #expr);        \
    if (st_ != CUBLAS_STATUS_SUCCESS)                                                     \
      throw CudaError(std::string("cuBLAS error in ") + #expr + ": " + cublas_name(st_)); \
  } while (0)

struct CublasApi {
  cublasStatus_t (*create)(cublasHandle_t*) = nullptr;
  cublasStatus_t (*destroy)(cublasHandle_t) = nullptr;
  cublasStatus_t (*set_stream)(cublasHandle_t, cudaStream_t) = nullptr;
  cublasStatus_t (*set_math_mode)(cublasHandle_t, cublasMath_t) = nullptr;
  cublasStatus_t (*set_workspace)(cublasHandle_t, void*, size_t) = nullptr;
  cublasStatus_t (*sgemm)(cublasHandle_t, cublasOperation_t, cublasOperation_t, int, int, int, const float*,
                          const float*, int, const float*, int, const float*, float*, int) = nullptr;
};

// The table, loaded once (never unloaded); throws CudaError saying what is missing.
const CublasApi& cublas_api() {
  static std::mutex mu;
  static CublasApi api;
  static std::string failure;
  static bool tried = false;
  std::lock_guard<std::mutex> lock(mu);
  if (!tried) {
    tried = true;
    // The system's search (LD_LIBRARY_PATH, ld.so.cache), then the toolkit's usual places.
    std::string why;
    void* h = platform::open_library(cublas_library(), &why);
    for (const std::string& d : platform::cuda_toolkit_library_dirs()) {
      if (h) break;
      h = platform::open_library(platform::path_join(d, cublas_library()), nullptr);
    }
    if (!h) {
      failure = "the cublas path needs " + cublas_library() + " from the CUDA toolkit: " + why + " (also not in " +
                platform::cuda_toolkit_library_dirs()[0] + "); the default path, 'fused', does not need it";
    } else {
      auto sym = [&](const char* name, auto& fn) {
        void* f = platform::library_symbol(h, name);
        if (!f && failure.empty()) failure = cublas_library() + " has no " + name;
        fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(f);
      };
      sym("cublasCreate_v2", api.create);
      sym("cublasDestroy_v2", api.destroy);
      sym("cublasSetStream_v2", api.set_stream);
      sym("cublasSetMathMode", api.set_math_mode);
      sym("cublasSetWorkspace_v2", api.set_workspace);
      sym("cublasSgemm_v2", api.sgemm);
    }
  }
  if (!failure.empty()) throw CudaError(failure);
  return api;
}

constexpr size_t kWorkspaceBytes = size_t(32) << 20;

}  // namespace

const std::string& cublas_library() {
  static const std::string name = platform::library_file_name("cublas", CUBLAS_VER_MAJOR);
  return name;
}

CublasGemm::CublasGemm(cudaStream_t stream) {
  const CublasApi& api = cublas_api();
  CK(cudaMalloc(&workspace_, kWorkspaceBytes));
  cublasHandle_t h = nullptr;
  try {
    CKB(api.create(&h));
    handle_ = h;
    CKB(api.set_stream(h, stream));
    CKB(api.set_math_mode(h, CUBLAS_DEFAULT_MATH));  // plain FP32, no TF32
    CKB(api.set_workspace(h, workspace_, kWorkspaceBytes));
  } catch (...) {
    if (handle_) api.destroy(static_cast<cublasHandle_t>(handle_));
    cudaFree(workspace_);
    throw;
  }
}

CublasGemm::~CublasGemm() {
  if (handle_) cublas_api().destroy(static_cast<cublasHandle_t>(handle_));
  if (workspace_) cudaFree(workspace_);
}

void CublasGemm::gemm_tn(int m, int n, int k, const float* A, int lda, const float* B, int ldb, float* C, int ldc) {
  const float one = 1.0f, zero = 0.0f;
  CKB(cublas_api().sgemm(static_cast<cublasHandle_t>(handle_), CUBLAS_OP_T, CUBLAS_OP_N, m, n, k, &one, A, lda, B,
                         ldb, &zero, C, ldc));
}

}  // namespace cuda_impl
}  // namespace sffd
