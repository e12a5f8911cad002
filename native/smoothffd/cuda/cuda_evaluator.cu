// CUDA evaluator (see cuda_evaluator.hpp). Kernels call the stage functions of
// eval/stages.hpp; this file only adds the launch structure, the two product paths, memory
// management, timing and error handling.
#include "smoothffd/cuda/cuda_evaluator.hpp"

#include <cublas_v2.h>  // types only: libcublas is loaded when the cublas path is first asked for
#include <cuda_pipeline.h>
#include <cuda_runtime.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <system_error>
#include <thread>
#include <type_traits>
#include <unordered_map>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/core/platform.hpp"
#include "smoothffd/eval/stages.hpp"
#include "smoothffd/plan/tessellation.hpp"

#ifdef SFFD_HAVE_BUILD_H
#include "sffd_cuda_build.h"  // SFFD_CUDA_ARCHS: the architectures built (native/CMakeLists.txt)
#endif
#ifndef SFFD_CUDA_ARCHS
#define SFFD_CUDA_ARCHS "unknown architectures"
#endif

namespace sffd {
namespace cuda_impl {

namespace {

[[noreturn]] void throw_cuda(cudaError_t err, const char* what, const char* file, int line) {
  // No iostreams here: in a module with a statically linked libstdc++ (the device image's
  // GCC) ostream formatting crashed; plain string concatenation does not need locales.
  std::string msg = std::string("CUDA error in ") + what + ": " + cudaGetErrorName(err) + " (" +
                    cudaGetErrorString(err) + ") at " + file + ":" + std::to_string(line);
  if (err == cudaErrorMemoryAllocation) throw CudaOutOfMemory("out of GPU memory: " + msg);
  throw CudaError(msg);
}

#define CK(expr)                                                     \
  do {                                                               \
    cudaError_t err_ = (expr);                                       \
    if (err_ != cudaSuccess) throw_cuda(err_, #expr, __FILE__, __LINE__); \
  } while (0)

#define CK_LAUNCH(name) CK(cudaPeekAtLastError())

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

#define CKB(expr)                                                                            \
  do {                                                                                       \
    cublasStatus_t st_ = (expr);                                                             \
    if (st_ == CUBLAS_STATUS_ALLOC_FAILED)                                                   \
      throw CudaOutOfMemory(std::string("out of GPU memory in cuBLAS: ") + #expr);           \
    if (st_ != CUBLAS_STATUS_SUCCESS)                                                        \
      throw CudaError(std::string("cuBLAS error in ") + #expr + ": " + cublas_name(st_));    \
  } while (0)

// cuBLAS, only for the paper's reference "cublas" path: loaded with dlopen when that path is
// first asked for (so that neither the module nor this library needs libcublas to load, and the
// default fused path runs without it). Its own dependency, libcublasLt, is its business. The
// few functions the path calls, by their exported (_v2) names.
struct CublasApi {
  cublasStatus_t (*create)(cublasHandle_t*) = nullptr;
  cublasStatus_t (*destroy)(cublasHandle_t) = nullptr;
  cublasStatus_t (*set_stream)(cublasHandle_t, cudaStream_t) = nullptr;
  cublasStatus_t (*set_math_mode)(cublasHandle_t, cublasMath_t) = nullptr;
  cublasStatus_t (*set_workspace)(cublasHandle_t, void*, size_t) = nullptr;
  cublasStatus_t (*sgemm)(cublasHandle_t, cublasOperation_t, cublasOperation_t, int, int, int, const float*,
                          const float*, int, const float*, int, const float*, float*, int) = nullptr;
};

// libcublas.so.13 for the toolkit this library is built with.
const std::string& cublas_library() {
  static const std::string name = platform::library_file_name("cublas", CUBLAS_VER_MAJOR);
  return name;
}

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
    for (const char* const* d = platform::cuda_toolkit_library_dirs(); !h && *d; ++d)
      h = platform::open_library(platform::path_join(*d, cublas_library()), nullptr);
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
  ~DeviceArena() {
    for (void* p : blocks) cudaFree(p);
  }
};

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
  ~PinnedBuffer() {
    if (ptr) cudaFreeHost(ptr);
  }
};

struct Events {
  std::vector<cudaEvent_t> ev;
  void ensure(size_t n) {
    while (ev.size() < n) {
      cudaEvent_t e;
      CK(cudaEventCreate(&e));
      ev.push_back(e);
    }
  }
  ~Events() {
    for (auto e : ev) cudaEventDestroy(e);
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

inline unsigned blocks_for(long long n, int threads) { return (unsigned)((n + threads - 1) / threads); }

// Holds its stream for ns nanoseconds of the device's global timer (benchmark: the frame
// behind it is queued in full before the device reaches it).
__global__ void k_hold(long long ns) {
  long long t0, t;
  asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t0));
  do {
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t));
  } while (t - t0 < ns);
}

// Per grid point of the tessellation: kind (0 corner, 1 edge, 2 interior), which, step; and
// `order`: entry g holds the grid point at position g of the order the tessellation walks
// (the 3L boundary points first, then the interior points by `which`).
struct GridInfo {
  int kind, which, step, order;
};

// q = j / d for 0 <= j < 2^22 and 0 < d, inv = 1.0f / d: a float product and one correction
// instead of the ~20 instructions of an integer division.
__device__ __forceinline__ int div_small(int j, int d, float inv) {
  int q = (int)(((float)j + 0.5f) * inv);
  if (q * d > j) --q;
  else if ((q + 1) * d <= j) ++q;
  return q;
}

// PTS consecutive points' coordinates (3 PTS floats) from dst on: two points as three 8-byte
// stores (dst 8-byte aligned), one as three 4-byte stores. (Four points a thread, as three
// 16-byte stores, measured 6% slower on W1: docs/benchmarks.md.)
template <int PTS>
__device__ __forceinline__ void store_points(float* dst, const V3 v[PTS]) {
  if constexpr (PTS == 2) {
    float2* d = reinterpret_cast<float2*>(dst);
    d[0] = make_float2(v[0].x, v[0].y);
    d[1] = make_float2(v[0].z, v[1].x);
    d[2] = make_float2(v[1].y, v[1].z);
  } else {
    store3(dst, v[0]);
  }
}

// Control points of a patch in the fused kernels' shared memory: 30 floats padded to 32, so
// that tessellation reads them as eight 16-byte vectors.
constexpr int kCtrlStride = 32;

// One patch's geometry (ctrl[q][0]) and normal (ctrl[q][1]) control points in shared memory,
// and its unit_patch_normal fallback (the normalized sum of the corners' normal control
// points, set by k_inline before the tessellation). Those 16 bytes also put
// consecutive patches 4 banks apart: without them the patches of a warp sit 256 bytes apart,
// in the same banks, and every per-patch store (one lane a patch) and every vector load that
// spans two patches (tessellation) is an 8-way / 2-way conflict.
struct __align__(16) PatchCtrl {
  float g[kCtrlStride];
  float n[kCtrlStride];
  float fallback[4];
  __device__ float* operator[](int i) { return i ? n : g; }
  __device__ const float* operator[](int i) const { return i ? n : g; }
};

// A patch field (kCtrlStride floats, 16-byte aligned, shared memory) as 10 points, read as
// eight 16-byte vectors (instead of 30 scalar loads).
__device__ __forceinline__ void load_field(const float* f, V3 out[10]) {
  float v[kCtrlStride];
#pragma unroll
  for (int i = 0; i < kCtrlStride / 4; ++i) {
    const float4 q = reinterpret_cast<const float4*>(f)[i];
    v[4 * i] = q.x, v[4 * i + 1] = q.y, v[4 * i + 2] = q.z, v[4 * i + 3] = q.w;
  }
#pragma unroll
  for (int k = 0; k < 10; ++k) out[k] = v3(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
}

// The inverse of load_field: 10 points into a patch field as eight 16-byte stores.
__device__ __forceinline__ void store_field(float* f, const V3 in[10]) {
  float v[kCtrlStride];
#pragma unroll
  for (int k = 0; k < 10; ++k) v[3 * k] = in[k].x, v[3 * k + 1] = in[k].y, v[3 * k + 2] = in[k].z;
  v[30] = v[31] = 0.0f;
#pragma unroll
  for (int i = 0; i < kCtrlStride / 4; ++i)
    reinterpret_cast<float4*>(f)[i] = make_float4(v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]);
}

// Positions x and unit normals n of a patch at N grid points (s[i], t[i]) (grid_st): cg and
// cn its geometry and normal patches in power form (to_power_form), fallback its
// unit_patch_normal fallback; one read of the power forms for all N. The same surface as
// eval_cubic and unit_patch_normal (stages.hpp), which the CPU evaluates in Bernstein form, up
// to rounding.
template <int N>
__device__ __forceinline__ void eval_points(const float s[N], const float t[N], const float* cg, const float* cn,
                                            V3 fallback, V3 x[N], V3 n[N]) {
  V3 g[10], c[10];
  load_field(cg, g);
  load_field(cn, c);
#pragma unroll
  for (int i = 0; i < N; ++i) {
    x[i] = cubic_power_eval(g, s[i], t[i]);
    n[i] = normalized_or(cubic_power_eval(c, s[i], t[i]), fallback);
  }
}

// eval_points at one point.
__device__ __forceinline__ void eval_point(float s, float t, const float* cg, const float* cn, V3 fallback, V3& x,
                                           V3& n) {
  eval_points<1>(&s, &t, cg, cn, fallback, &x, &n);
}

// Output vertex of (patch p, grid point g) when p writes it, else -1 (corners are written by
// the sampling kernel; an edge point by the patch that owns it in the plan).
__device__ __forceinline__ long long owned_vertex(const PlanView& pv, const GridInfo* gi, const uint8_t* owns,
                                                  int p, int g) {
  GridInfo q = gi[g];
  const int L = pv.level;
  if (q.kind == 1) {
    if (!((owns[p] >> q.which) & 1)) return -1;
    int m = pv.patch_edge_reversed[3 * p + q.which] ? L - q.step : q.step;
    return pv.sub_vertices + (long long)pv.patch_edge[3 * p + q.which] * (L - 1) + (m - 1);
  }
  if (q.kind == 2)
    return pv.sub_vertices + (long long)pv.edges * (L - 1) + (long long)p * ((L - 1) * (L - 2) / 2) + q.which;
  return -1;
}

// Which render vertices (plan.hpp) patch p writes the normal of, derived from the plan's
// render_owner / patch_grid_render once (and checked against them for every grid point):
// corner[k]: render vertex of corner k, or -1 when another patch owns it; edge_base[k]: render
// vertex of step m = 1 (counted from the sub-edge's end a) on p's side of edge k, or -1 when
// another patch owns the edge's points; step m has base + (m - 1) * edge_stride[k]. Interior
// points: render vertex = output vertex + render_shift (R - N).
struct PatchRender {
  int corner[3], edge_base[3], edge_stride[3];
};

// Render vertex whose normal (patch p, grid point q) writes, or -1.
__device__ __forceinline__ long long render_written(const PlanView& pv, const PatchRender& pr, GridInfo q,
                                                    bool reversed, long long interior_o, long long shift) {
  if (q.kind == 2) return interior_o + shift;
  if (q.kind == 0) return pr.corner[q.which];
  int b = pr.edge_base[q.which];
  if (b < 0) return -1;
  int m = reversed ? pv.level - q.step : q.step;
  return b + (long long)(m - 1) * pr.edge_stride[q.which];
}

// ---------------------------------------------------------------- kernels shared by both paths

// sample_point (stages.hpp) with C terms an axis at compile time instead of kMaxTerms, for
// plans whose pieces all have count <= C and degree < C: the padded terms are exact zeros
// either way (fma(0, d, x) = x), so the result is the same as sample_point's.
template <int C>
__device__ __forceinline__ void sample_point_c(const PlanView& pv, const float* __restrict__ D, int s, float* F, float* J) {
  float p[3] = {pv.sample_position[3 * s], pv.sample_position[3 * s + 1], pv.sample_position[3 * s + 2]};
  int idx[3][C];
  float w[3][C], dw[3][C], value[3], grad[9];
  sample_weights<C>(pv, p, pv.sample_piece[s], idx, w, dw);
  tensor_eval_fixed<float, float, C, C, C>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2], dw[2], D,
                                           pv.dims[1], pv.dims[2], value, grad);
  finish_sample(pv, p, s, value, grad, F, J);
}

// The reference path's sampling: F and J of every sample into the frame's buffers, and the
// positions of the sub-vertices (input and clip vertices), which are samples themselves. C
// terms an axis (the plan's largest), registers capped by MINB blocks of 256 an SM (C = 3:
// 4 blocks, 64 registers, measured fastest; docs/benchmarks.md's history).
template <int C, int MINB>
__global__ void __launch_bounds__(256, MINB) k_sample(PlanView pv, FrameView fv, const float* __restrict__ D) {
  int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= pv.samples) return;
  sample_point_c<C>(pv, D, s, fv.sample_value + 3 * (long long)s, fv.sample_jacobian + 9 * (long long)s);
  if (s < pv.sub_vertices) tessellate_position(pv, fv, s);  // input and clip vertices
}

__global__ void k_edge(PlanView pv, FrameView fv) {
  int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e < pv.edges) adjust_edge(pv, fv, e);
}

// ---------------------------------------------------------------- fused path

// Where tessellate_interior finds an interior point's (s, t) (its PTS points' at once): k_inline's
// table of (s, t) in walk order, whose interior starts at an even index so that a thread's
// two points are one 16-byte load (as one float4 a point with scalar loads of s and t, the
// loads of a warp were 5-way bank conflicts: the shared-memory pipe is k_inline's busiest unit).
struct WalkST {
  const float2* st;
  int interior;  // index of the first interior point (even)
  template <int PTS>
  __device__ __forceinline__ void operator()(int jj, float s[PTS], float t[PTS]) const {
    if constexpr (PTS == 2) {
      const float4 q = *reinterpret_cast<const float4*>(st + interior + jj);
      s[0] = q.x, t[0] = q.y, s[1] = q.z, t[1] = q.w;
    } else {
      const float2 q = st[interior + jj];
      s[0] = q.x, t[0] = q.y;
    }
  }
};

// The interior points of k_inline's group of patches (tessellate_listed), PTS consecutive
// ones a thread (1, or 2 when no pair straddles two patches): each warp takes 32 PTS
// consecutive points of the group's run, the block's last warp the first run (when the runs
// do not divide evenly, the warps at the end take one more: the boundary list gives its extra
// points to the first warps). The thread's (patch q, interior point jj) advances by a
// constant step instead of a division a point. Each thread stores its points straight from
// registers (PTS = 2: three 8-byte stores a field, aligned since the evaluator's buffers put
// the interior's first output and render vertex on 16 bytes): no shared-memory round trip
// and no warp barriers, about 1% faster on W1 than staging them for coalesced stores.
template <int PTS, int kThreads>
__device__ __forceinline__ void tessellate_interior(const FrameView& fv, const WalkST& st, const PatchCtrl* ctrl,
                                                    int n_int, int IG, long long o0, long long render_shift,
                                                    float* __restrict__ normals) {
  constexpr int kRun = 32 * PTS, kStep = PTS * kThreads;
  const int warp = kThreads / 32 - 1 - (int)threadIdx.x / 32, wl = threadIdx.x & 31;
  const float inv_ig = 1.0f / (float)IG;
  const int step_q = div_small(kStep, IG, inv_ig), step_j = kStep - step_q * IG;
  int q = div_small(warp * kRun + PTS * wl, IG, inv_ig), jj = warp * kRun + PTS * wl - q * IG;
  float* pos = fv.positions + 3 * (o0 + warp * kRun);  // the warp's run of vertices
  float* nrm = normals + 3 * (o0 + warp * kRun + render_shift);
  for (int j0 = warp * kRun; j0 < n_int; j0 += kStep, pos += 3 * kStep, nrm += 3 * kStep) {
    const bool mine = j0 + PTS * wl < n_int;
    if (mine) {
      V3 x[PTS], n[PTS];
      float s[PTS], t[PTS];
      st.template operator()<PTS>(jj, s, t);
      eval_points<PTS>(s, t, ctrl[q][0], ctrl[q][1], load3(ctrl[q].fallback), x, n);
      store_points<PTS>(pos + 3 * PTS * wl, x);
      store_points<PTS>(nrm + 3 * PTS * wl, n);
    }
    q += step_q, jj += step_j;
    if (jj >= IG) jj -= IG, ++q;
  }
}

// Sum of v over the LANES lanes of a patch (a power of two, within one warp), in every lane.
template <int LANES>
__device__ __forceinline__ V3 lanes_sum(V3 v) {
#pragma unroll
  for (int off = 1; off < LANES; off <<= 1) {
    v.x += __shfl_xor_sync(0xffffffffu, v.x, off);
    v.y += __shfl_xor_sync(0xffffffffu, v.y, off);
    v.z += __shfl_xor_sync(0xffffffffu, v.z, off);
  }
  return v;
}

#include "smoothffd/cuda/inline_kernels.cuh"

// ---------------------------------------------------------------- cuBLAS path

// X (K x 6P, column-major): column 6p + c holds, for c < 3, coordinate c of the deformed
// samples of patch p and, for c >= 3, coordinate c - 3 of their deformed normals.
__global__ void k_gather(PlanView pv, FrameView fv, float* __restrict__ X) {
  long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x;
  const int K = pv.columns;
  if (i >= (long long)pv.patches * K) return;
  int p = (int)(i / K), k = (int)(i - (long long)p * K);
  V3 rn[3];
  for (int c = 0; c < 3; ++c) rn[c] = load3(pv.patch_render_normal + 9 * (long long)p + 3 * c);
  V3 x, n;
  fit_column(pv, fv, p, k, rn, x, n);
  float* col = X + (long long)6 * p * K + k;
  col[0] = x.x;
  col[K] = x.y;
  col[2 * K] = x.z;
  col[3 * K] = n.x;
  col[4 * K] = n.y;
  col[5 * K] = n.z;
}

// F (10 x 6P) = M X; finishes the geometry patches and writes C (10 x 6P, same layout) plus
// the plan-layout patch_control / patch_normal.
__global__ void k_finish(PlanView pv, FrameView fv, const float* __restrict__ F, float* __restrict__ C) {
  int p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= pv.patches) return;
  const float* f = F + 60 * (long long)p;
  V3 g[10];
  for (int r = 0; r < 10; ++r) g[r] = v3(f[r], f[10 + r], f[20 + r]);
  finish_patch(pv, fv, p, g);
  float* c = C + 60 * (long long)p;
  for (int r = 0; r < 10; ++r) {
    c[r] = g[r].x;
    c[10 + r] = g[r].y;
    c[20 + r] = g[r].z;
    c[30 + r] = f[30 + r];
    c[40 + r] = f[40 + r];
    c[50 + r] = f[50 + r];
  }
}

// Q (G x 6P) = B C: positions to their welded vertices, normals normalized per (patch, grid).
__global__ void k_scatter(PlanView pv, FrameView fv, const float* __restrict__ Q, const float* __restrict__ C,
                          const GridInfo* __restrict__ gi, const uint8_t* __restrict__ owns,
                          const PatchRender* __restrict__ prender, long long render_shift,
                          float* __restrict__ normals) {
  long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x;
  const int G = pv.grid;
  if (i >= (long long)pv.patches * G) return;
  int p = (int)(i / G), g = (int)(i - (long long)p * G);
  const float* q = Q + 6 * (long long)p * G + g;
  const float* c = C + 60 * (long long)p + 30;
  float corners[9];
  for (int k = 0; k < 3; ++k)
    for (int d = 0; d < 3; ++d) corners[3 * k + d] = c[10 * d + k];
  GridInfo t = gi[g];
  bool rev = t.kind == 1 && pv.patch_edge_reversed[3 * p + t.which];
  const int L = pv.level;
  long long oi = pv.sub_vertices + (long long)pv.edges * (L - 1) + (long long)p * ((L - 1) * (L - 2) / 2) + t.which;
  long long r = render_written(pv, prender[p], t, rev, oi, render_shift);
  if (r >= 0) store3(normals + 3 * r, unit_patch_normal(v3(q[3 * G], q[4 * G], q[5 * G]), corners));
  long long o = owned_vertex(pv, gi, owns, p, g);
  if (o >= 0) store3(fv.positions + 3 * o, v3(q[0], q[G], q[2 * G]));
}

// ---------------------------------------------------------------- copy back

__global__ void k_fill_nan(float* p, long long n) {
  long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x;
  if (i < n) p[i] = __int_as_float(0x7fffffff);
}

// ---------------------------------------------------------------- baseline

__global__ void k_baseline(PlanView pv, const float* __restrict__ D, const float* __restrict__ rest_normal,
                           float* __restrict__ pos, float* __restrict__ nrm) {
  int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= pv.samples) return;
  float F[3], J[9];
  sample_point(pv, D, s, F, J);
  V3 n0 = load3(rest_normal + 3 * (long long)s);
  store3(pos + 3 * (long long)s, load3(F));
  store3(nrm + 3 * (long long)s, normalized_or(cofactor_apply(J, n0), n0));
}

enum Path { kFused = 0, kCublas = 1 };

Path parse_path(const std::string& v) {
  if (v.empty() || v == "fused") return kFused;
  if (v == "cublas") return kCublas;
  throw std::invalid_argument("CUDA path: expected 'fused' or 'cublas', got '" + v + "'");
}

std::string version_string(int v) { return std::to_string(v / 1000) + "." + std::to_string(v % 1000 / 10); }

std::string error_text(cudaError_t err) {
  return std::string(cudaGetErrorName(err)) + ": " + cudaGetErrorString(err);
}

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
  cudaFuncAttributes fa;
  err = cudaFuncGetAttributes(&fa, k_fill_nan);
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

// PatchRender of every patch from the plan's render vertices; every (patch, grid point) is
// checked: it writes render vertex r exactly when render_owner[r] is that pair.
std::vector<PatchRender> build_patch_render(const Plan& p, const TessellationTables& tt) {
  const int P = p.patches, G = p.grid, L = p.level;
  const long long shift = (long long)p.render_vertices - p.output_vertices;
  std::vector<PatchRender> pr((size_t)P);
  auto owner_is = [&](int r, int pp, int g) { return p.render_owner[2 * (size_t)r] == pp && p.render_owner[2 * (size_t)r + 1] == g; };
  std::atomic<bool> bad{false};  // no throwing inside the worker threads
  parallel_for(P, default_threads(), [&](long long b, long long e) {
    for (long long pp = b; pp < e; ++pp) {
      PatchRender& x = pr[pp];
      const int* gr = &p.patch_grid_render[(size_t)pp * G];
      for (int k = 0; k < 3; ++k) x.corner[k] = x.edge_base[k] = -1, x.edge_stride[k] = 0;
      for (int g = 0; g < G; ++g) {
        const GridPoint& q = tt.points[g];
        if (q.kind == 0 && owner_is(gr[g], (int)pp, g)) x.corner[q.which] = gr[g];
        if (q.kind == 1) {
          int m = p.patch_edge_reversed[3 * pp + q.which] ? L - q.step : q.step;
          if (m == 1 && owner_is(gr[g], (int)pp, g)) x.edge_base[q.which] = gr[g];
          if (m == 2) x.edge_stride[q.which] = gr[g];
        }
      }
      for (int k = 0; k < 3; ++k)
        if (L > 2) {
          int g1 = -1;
          for (int g = 0; g < G; ++g)
            if (tt.points[g].kind == 1 && tt.points[g].which == k &&
                (p.patch_edge_reversed[3 * pp + k] ? L - tt.points[g].step : tt.points[g].step) == 1)
              g1 = g;
          x.edge_stride[k] -= gr[g1];
        }
      for (int g = 0; g < G; ++g) {  // the check
        const GridPoint& q = tt.points[g];
        bool rev = q.kind == 1 && p.patch_edge_reversed[3 * pp + q.which];
        long long r = -1;
        if (q.kind == 2) {
          r = p.patch_grid_vertex[(size_t)pp * G + g] + shift;
        } else if (q.kind == 0) {
          r = x.corner[q.which];
        } else if (x.edge_base[q.which] >= 0) {
          int m = rev ? L - q.step : q.step;
          r = x.edge_base[q.which] + (long long)(m - 1) * x.edge_stride[q.which];
        }
        bool owns = owner_is(gr[g], (int)pp, g);
        if (owns != (r >= 0) || (owns && r != gr[g])) bad = true;
      }
    }
  });
  if (bad) throw std::logic_error("CudaEvaluator: render vertex table not in the layout of plan.hpp");
  return pr;
}

// The inline kernel's per-patch records (InlinePatch, inline_kernels.cuh). owns: bit k, the
// patch writes the points of its edge k; corner_owns: bit k, the position of its corner k.
std::vector<InlinePatch> build_patch_records(const Plan& p, const std::vector<uint8_t>& owns,
                                             const std::vector<PatchRender>& pr,
                                             const std::vector<uint8_t>& corner_owns) {
  std::vector<InlinePatch> rec((size_t)p.patches);
  for (int q = 0; q < p.patches; ++q) {
    InlinePatch& r = rec[q];
    r = InlinePatch{};
    for (int i = 0; i < 9; ++i) {
      r.rest[i] = p.patch_render_normal[9 * (size_t)q + i];
      r.adjust[i] = p.patch_adjust_normal[9 * (size_t)q + i];
    }
    uint32_t f = owns[q] | uint32_t(corner_owns[q]) << 8;
    const int L = p.level;
    for (int k = 0; k < 3; ++k) {
      const int e = p.patch_edge[3 * (size_t)q + k], k1 = (k + 1) % 3;
      const bool rev = p.patch_edge_reversed[3 * (size_t)q + k] != 0;
      r.vertex[k] = p.patch_vertex[3 * (size_t)q + k];
      // PatchBoundary: the point at step s from corner k is step m = s (rev: L - s) from the
      // edge's end a, output vertex sub_vertices + e (L - 1) + m - 1 and render vertex
      // edge_base + (m - 1) edge_stride (owned_vertex and render_written).
      const int ob = p.sub_vertices + e * (L - 1), rb = pr[q].edge_base[k], rs = pr[q].edge_stride[k];
      const bool owned = (owns[q] >> k) & 1;
      r.bound.edge[k] = make_int4(owned ? (rev ? ob + L - 1 : ob - 1) : -1, owned ? (rev ? -1 : 1) : 0,
                                  rb >= 0 ? (rev ? rb + (L - 1) * rs : rb - rs) : -1, rb >= 0 ? (rev ? -rs : rs) : 0);
      r.bound.corner[k] = pr[q].corner[k];
      // -1 means "writes nothing" to the kernel and the boundary lists: a base it writes to
      // must not be negative (render vertices of edge points come after the sub-vertices').
      if ((owned && r.bound.edge[k].x < 0) || (rb >= 0 && r.bound.edge[k].z < 0))
        throw std::logic_error("CudaEvaluator: unexpected render table");
      const int p0 = p.edge_patch[2 * (size_t)e], p1 = p.edge_patch[2 * (size_t)e + 1];
      const uint8_t ef = p.edge_flags[e];
      const bool self1 = p1 == q;
      uint32_t bits = (ef & kSharpAtA ? 1u : 0u) | (ef & kSharpAtB ? 2u : 0u) | (ef & kNonManifold ? 4u : 0u) |
                      (p1 >= 0 ? 8u : 0u);
      if (!(ef & kNonManifold)) {
        // This patch's corner at each end must be the slot the edge table has for its side.
        const int ka = rev ? k1 : k, kb = rev ? k : k1, side = self1 ? 1 : 0;
        if ((self1 ? p1 : p0) != q || p.edge_slot[4 * (size_t)e + 2 * side] != ka ||
            p.edge_slot[4 * (size_t)e + 2 * side + 1] != kb)
          throw std::logic_error("CudaEvaluator: unexpected edge table");
        if (p1 >= 0) {
          const int other = self1 ? p0 : p1;
          for (int end = 0; end < 2; ++end) {
            const int slot = p.edge_slot[4 * (size_t)e + 2 * (1 - side) + end];
            for (int i = 0; i < 3; ++i) r.nb[k][3 * end + i] = p.patch_adjust_normal[9 * (size_t)other + 3 * slot + i];
          }
        }
      }
      f |= (rev ? 8u : 0u) << k | bits << (12 + 4 * k) | (self1 ? 1u : 0u) << (24 + k);
    }
    r.flags = f;
  }
  return rec;
}

// Each patch record's corner samples and the box of each evaluated column's sample
// (InlinePatch::corner, box), and the check that inline_sample_point puts every sample where
// the plan has it (within rounding: the plan rounds its double positions to float), so that
// k_inline needs no per-sample records. False when a sample is not where expected.
bool place_samples(const Plan& p, const std::vector<InlineColumn>& col, const std::vector<int>& evaluated,
                   const std::vector<uint32_t>& box_of, std::vector<InlinePatch>& rec) {
  const int K = p.columns;
  std::atomic<bool> ok{true};
  parallel_for(p.patches, default_threads(), [&](long long b, long long e) {
    for (long long q = b; q < e; ++q) {
      InlinePatch& r = rec[q];
      for (int c = 0; c < 3; ++c) {
        const size_t v = (size_t)p.patch_vertex[3 * q + c];
        r.corner[c] = make_float4(p.sample_position[3 * v], p.sample_position[3 * v + 1], p.sample_position[3 * v + 2],
                                  p.sample_weight[v]);
      }
      std::fill(std::begin(r.box), std::end(r.box), uint8_t(0));
      for (size_t i = 0; i < evaluated.size(); ++i) {
        const size_t s = (size_t)p.patch_samples[(size_t)q * K + evaluated[i]];
        r.box[i] = (uint8_t)box_of[s];
        const float4 x = inline_sample_point(col[evaluated[i]], r.flags, r.corner[0], r.corner[1], r.corner[2]);
        const float got[4] = {x.x, x.y, x.z, x.w};
        for (int a = 0; a < 4; ++a) {
          const float want = a < 3 ? p.sample_position[3 * s + a] : p.sample_weight[s];
          const float scale = std::max({1.0f, std::fabs(r.corner[0].x), std::fabs(r.corner[0].y),
                                        std::fabs(r.corner[0].z), std::fabs(want)});
          if (!(std::fabs(got[a] - want) <= 2e-6f * scale)) ok = false;
        }
      }
    }
  });
  return ok;
}

}  // namespace

std::pair<bool, std::string> cuda_status() { return device_status(); }

const char* build_info() {
  static const std::string info = "CUDA runtime " + version_string(CUDART_VERSION) + " (static), kernels " SFFD_CUDA_ARCHS;
  return info.c_str();
}

// ================================================================= CudaEvaluator

// Whether the constraint columns of every patch are its corners and its edges' 1/3 and 2/3
// samples in the order k_inline reads them (plan/fit_matrix.hpp), checked once per plan.
bool constraint_columns_as_expected(const Plan& p) {
  const int K = p.columns, K0 = K - 9;
  if (K0 < 0) return false;
  for (int q = 0; q < p.patches; ++q) {
    const int* col = p.patch_samples.data() + (size_t)q * K + K0;
    for (int k = 0; k < 3; ++k) {
      const int e = p.patch_edge[3 * q + k];
      const bool rev = p.patch_edge_reversed[3 * q + k];
      const int ka = rev ? (k + 1) % 3 : k, kb = rev ? k : (k + 1) % 3;
      if (col[k] != p.patch_vertex[3 * q + k]) return false;
      if (p.edge_vertex[2 * e] != p.patch_vertex[3 * q + ka] || p.edge_vertex[2 * e + 1] != p.patch_vertex[3 * q + kb])
        return false;
      if (col[3 + 2 * k] != p.edge_constraint[2 * e + (rev ? 1 : 0)] ||
          col[4 + 2 * k] != p.edge_constraint[2 * e + (rev ? 0 : 1)])
        return false;
    }
  }
  return true;
}


// The terms an axis the kernels are instantiated for: the plan's largest term count rounded up.
int kernel_terms(int max_terms) { return max_terms <= 2 ? 2 : max_terms <= 4 ? max_terms : kMaxTerms; }

// Calls f(std::integral_constant<int, C>) for the terms of kernel_terms.
template <class F>
void with_terms(int C, F&& f) {
  switch (C) {
    case 2: return f(std::integral_constant<int, 2>{});
    case 3: return f(std::integral_constant<int, 3>{});
    case 4: return f(std::integral_constant<int, 4>{});
    default: return f(std::integral_constant<int, kMaxTerms>{});
  }
}

// Register caps (blocks of the kernel an SM): k_inline 4 blocks of 128 with 3 terms (128
// registers, no spills; 5 blocks spilled and measured 6% slower), 2 with 2 or 4, 1 beyond;
// the reference path's sampling kernel (256 threads) 4 blocks up to 3 terms, then 3, then 2.
constexpr int inline_min_blocks(int C) { return C == 3 ? 4 : C <= 4 ? 2 : 1; }
constexpr int sample_min_blocks(int C) { return C <= 3 ? 4 : C == 4 ? 3 : 2; }

struct CudaEvaluator::Impl {
  Path path = kFused;
  DeviceArena arena;
  PlanView pv{};
  FrameView fv{};
  GridInfo* grid_info = nullptr;
  uint8_t* owns = nullptr;
  PatchRender* prender = nullptr;  // P
  long long render_shift = 0;      // R - N
  int max_terms = kMaxTerms;       // largest count / degree + 1 over the plan's pieces
  // The inline kernel for this plan: its InlineMode (-1: none, the fused path then runs the
  // reference kernels) and terms an axis; why the shared-memory modes do not serve the plan.
  int inline_mode = -1, inline_terms = 0;
  std::string inline_why;
  InlineArgs inline_args{};
  int inline_grid = 0;             // resident blocks of the inline kernel (persistent grid)
  int* loose = nullptr;            // sub-vertices in no patch
  int loose_count = 0;
  float* D = nullptr;
  float* normals = nullptr;  // R x 3 (render vertices)
  // cuBLAS path scratch (allocated on first use)
  float* X = nullptr;  // K x 6P
  float* F = nullptr;  // 10 x 6P
  float* C = nullptr;  // 10 x 6P
  float* Q = nullptr;  // G x 6P
  float* fit_matrix_cm = nullptr;  // M as column-major 10 x K
  // copy back
  PinnedBuffer h_D, h_out;
  cudaStream_t stream = nullptr;
  const CublasApi* cb = nullptr;  // set with the handle (ensure_cublas)
  cublasHandle_t cublas = nullptr;
  void* cublas_ws = nullptr;
  Events events;
  size_t nD = 0;
  // Shared-memory limits the launches are planned with (plan_limits): the device's own, or
  // those of the smaller device emulated (shared_memory_limit > 0).
  int64_t shared_memory_limit = 0;
  sffd_cuda_limits lim{};
  size_t inline_dyn_max = 0;     // largest dynamic table of the inline kernel on this device
  size_t inline_dyn_device = 0;  // the same on the real device (the kernels' opt-in attribute)

  ~Impl() {
    if (cublas) cb->destroy(cublas);
    if (cublas_ws) cudaFree(cublas_ws);
    if (stream) cudaStreamDestroy(stream);
  }

  // The cuBLAS path's handle (libcublas loaded on first use: CudaError when it is missing)
  // and scratch.
  void ensure_cublas() {
    if (cublas) return;
    const CublasApi& api = cublas_api();
    const long long P = pv.patches, K = pv.columns, G = pv.grid;
    if (!X) {
      X = arena.alloc<float>(K * 6 * P);
      F = arena.alloc<float>(10 * 6 * P);
      C = arena.alloc<float>(10 * 6 * P);
      Q = arena.alloc<float>(G * 6 * P);
    }
    if (!cublas_ws) {
      const size_t ws = 32u << 20;
      CK(cudaMalloc(&cublas_ws, ws));
    }
    cublasHandle_t h = nullptr;
    CKB(api.create(&h));
    cb = &api;
    cublas = h;
    CKB(api.set_stream(cublas, stream));
    CKB(api.set_math_mode(cublas, CUBLAS_DEFAULT_MATH));  // plain FP32, no TF32
    CKB(api.set_workspace(cublas, cublas_ws, 32u << 20));
  }

  // The static shared memory of the inline kernels this plan may run (the modes' static
  // tables are the same; the largest, to be safe).
  template <int C>
  static size_t inline_static_as() {
    cudaFuncAttributes a{}, b{}, g{};
    if constexpr (C <= 4) {
      CK(cudaFuncGetAttributes(&a, k_inline<C, kInlineBoxes, 32, 4, inline_min_blocks(C)>));
      CK(cudaFuncGetAttributes(&b, k_inline<C, kInlineWeights, 32, 4, inline_min_blocks(C)>));
    }
    CK(cudaFuncGetAttributes(&g, k_inline<C, kInlineGlobal, 32, 4, inline_min_blocks(C)>));
    return std::max({a.sharedSizeBytes, b.sharedSizeBytes, g.sharedSizeBytes});
  }
  size_t inline_static() const {
    size_t st = 0;
    with_terms(kernel_terms(max_terms), [&](auto c) { st = inline_static_as<decltype(c)::value>(); });
    return st;
  }

  // The device's limits (or the emulated device's) and the inline kernel's dynamic budget:
  // static + dynamic within what a block may opt in to, and one block (plus the memory the
  // system reserves a block) within a multiprocessor. Consumer GPUs give a block far less than
  // an H100 (227 KB): 99 KB on sm_86 / sm_89, 64 KB on sm_75, 163 KB on sm_80.
  void plan_limits() {
    int dev = 0, optin = 0, per_sm = 0, reserved = 0, sms = 0, regs = 0, major = 0, minor = 0;
    CK(cudaGetDevice(&dev));
    CK(cudaDeviceGetAttribute(&optin, cudaDevAttrMaxSharedMemoryPerBlockOptin, dev));
    CK(cudaDeviceGetAttribute(&per_sm, cudaDevAttrMaxSharedMemoryPerMultiprocessor, dev));
    CK(cudaDeviceGetAttribute(&reserved, cudaDevAttrReservedSharedMemoryPerBlock, dev));
    CK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev));
    CK(cudaDeviceGetAttribute(&regs, cudaDevAttrMaxRegistersPerMultiprocessor, dev));
    CK(cudaDeviceGetAttribute(&major, cudaDevAttrComputeCapabilityMajor, dev));
    CK(cudaDeviceGetAttribute(&minor, cudaDevAttrComputeCapabilityMinor, dev));
    lim = sffd_cuda_limits{};
    lim.per_block = optin;
    lim.per_multiprocessor = per_sm;
    if (shared_memory_limit > 0) {
      lim.per_block = std::min<int64_t>(optin, shared_memory_limit);
      lim.per_multiprocessor = std::min<int64_t>(per_sm, shared_memory_limit + reserved);
    }
    lim.reserved_per_block = reserved;
    lim.multiprocessors = sms;
    lim.registers_per_multiprocessor = regs;
    lim.compute_capability = 10 * major + minor;
    const size_t st = inline_static();
    lim.inline_static = (int64_t)st;
    auto budget = [&](int64_t block, int64_t sm) {
      const int64_t room = std::min(block, sm - reserved) - (int64_t)st;
      return (size_t)std::max<int64_t>(0, std::min<int64_t>(room, (int64_t)kInlineSharedBytes));
    };
    inline_dyn_max = st ? budget(lim.per_block, lim.per_multiprocessor) : 0;
    inline_dyn_device = st ? budget(optin, per_sm) : 0;
    lim.inline_dynamic_max = (int64_t)inline_dyn_max;
  }

  // The inline kernel's tables (InlineArgs, inline_kernels.cuh), corner ownership and loose
  // vertices, and its mode for this plan (inline_mode): the lattice tables in shared memory
  // where they fit (boxes, else the per-sample weights), else in device memory (global).
  // owns and pr: the tessellation's per-patch tables.
  void build_inline_tables(const Plan& p, const TessellationTables& tt, const std::vector<GridInfo>& gi,
                           const std::vector<uint8_t>& owns, const std::vector<PatchRender>& pr) {
    const int points = p.dims[0] * p.dims[1] * p.dims[2], n_pieces = (int)p.pieces.size();
    InlineArgs& ia = inline_args;
    ia = InlineArgs{};
    ia.points = points;
    ia.n_pieces = n_pieces;
    inline_mode = -1;
    inline_terms = kernel_terms(max_terms);
    if (!constraint_columns_as_expected(p)) {
      inline_why = "the plan's constraint columns are not where the inline kernel reads them";
      return;
    }
    // The boxes that hold samples, numbered in order of first use; box_of[s]: sample s's.
    std::vector<uint32_t> box_of((size_t)p.samples);
    std::vector<int4> box_list;
    {
      std::unordered_map<uint32_t, uint32_t> index;
      for (int s = 0; s < p.samples; ++s) {
        auto it = index.emplace(p.sample_piece[s], (uint32_t)box_list.size());
        if (it.second) {
          int b[3];
          for (int a = 0; a < 3; ++a) b[a] = p.axis_offset[a] + (int)((p.sample_piece[s] >> (10 * a)) & 1023u);
          box_list.push_back(make_int4(b[0], b[1], b[2], b[0] | b[1] << 10 | b[2] << 20));
        }
        box_of[s] = it.first->second;
      }
    }
    const int interior_points = (p.level - 1) * (p.level - 2) / 2, boundary_points = p.grid - interior_points;
    ia.walk_boundary = boundary_points;
    ia.st_interior = (boundary_points + 1) / 2 * 2;
    ia.st_count = ia.st_interior + interior_points;
    ia.box_count = (int)box_list.size();
    // Constraint columns that are grid points with the same sample in every patch.
    const int K = p.columns, K0 = K - 9;
    ColumnMap cm{};
    std::fill(std::begin(cm.con_of), std::end(cm.con_of), int8_t(-1));
    std::vector<int> evaluated;  // the grid's columns, then the constraint columns that are none
    for (int k = 0; k < K0; ++k) evaluated.push_back(k);
    for (int j = 0; j < 9; ++j) {
      int dup = -1;
      for (int k = 0; k < K0 && dup < 0; ++k) {
        bool same = true;
        for (int c = 0; c < 3; ++c) same = same && p.column_bary[3 * k + c] == p.column_bary[3 * (K0 + j) + c];
        for (int q = 0; same && q < p.patches; ++q)
          same = p.patch_samples[(size_t)q * K + k] == p.patch_samples[(size_t)q * K + K0 + j];
        if (same) dup = k;
      }
      if (dup >= 0)
        cm.con_of[dup] = int8_t(j);
      else
        evaluated.push_back(K0 + j);
    }
    if (K0 > kMaxInlineGrid || (int)evaluated.size() > kMaxInlineColumns)
      throw std::logic_error("CudaEvaluator: more fitting columns than the fitting degree allows");
    // The shared-memory modes: at most 4 terms an axis, every piece in the boxes' 10 bits,
    // the boundary list's 11 bits of walk position, InlinePatch::box (a byte a column, an
    // index into at most 256 boxes).
    if (max_terms > 4)
      inline_why = "more than 4 terms an axis";
    else if (n_pieces >= 1024)
      inline_why = "1024 or more axis pieces";
    else if (boundary_points > 2048)
      inline_why = "more than 2048 boundary points a patch";
    else if (ia.box_count > 256)
      inline_why = "more than 256 lattice boxes hold samples";
    else if ((int)evaluated.size() > kMaxBoxColumns)
      inline_why = "more columns a patch than the patch records hold";
    // Where each column's sample lies (InlineColumn): its barycentric point has exactly 1 at a
    // corner and exactly 0 at the corner opposite an edge; the edge parameter is the plan's
    // numerator over 3n, from either end.
    const int N3 = 3 * p.fit_degree;
    std::vector<InlineColumn> col((size_t)K);
    for (int k = 0; k < K; ++k) {
      const float* b = &p.column_bary[3 * (size_t)k];
      InlineColumn& c = col[k];
      c.bary = make_float4(b[0], b[1], b[2], k < K0 ? p.fit_matrix[(size_t)kCentre * K + k] : 0.0f);
      c.t_fwd = c.t_rev = 0.0f;
      c.edge = c.corner = -1;
      for (int i = 0; i < 3; ++i) {
        if (b[i] == 1.0f) c.corner = i;
        if (b[i] == 0.0f && b[(i + 1) % 3] != 0.0f && b[(i + 2) % 3] != 0.0f) {
          c.edge = (i + 1) % 3;  // the edge from corner i + 1 to i + 2
          const long long q = std::llround((double)b[(i + 2) % 3] * N3);  // the far corner's numerator
          c.t_fwd = (float)(q / (double)N3);
          c.t_rev = (float)((N3 - q) / (double)N3);
        }
      }
    }
    ia.column = arena.upload(col);
    // The kernel's order of the evaluated columns: corners, edge points, interior points.
    auto kind = [&](int k) { return col[k].corner >= 0 ? 0 : col[k].edge >= 0 ? 1 : 2; };
    std::stable_sort(evaluated.begin(), evaluated.end(), [&](int a, int b) { return kind(a) < kind(b); });
    for (size_t i = 0; i < evaluated.size(); ++i) cm.order[i] = uint8_t(evaluated[i]);
    cm.n_cols = uint8_t(evaluated.size());
    ia.column_map = arena.upload(std::vector<ColumnMap>{cm});
    // M_r's last 9 columns, and the sum of its six edge rows in the order finish_patch_from
    // adds the fitted edge control points (edge k: the point next to corner k, then k + 1).
    for (int r = 0; r < 10; ++r)
      for (int q = 0; q < 9; ++q) ia.mrow[r][q] = p.fit_matrix[(size_t)r * K + K0 + q];
    for (int q = 0; q < 9; ++q) {
      float s = 0.0f;
      for (int k = 0; k < 3; ++k)
        s += ia.mrow[edge_control_index(k, false)][q] + ia.mrow[edge_control_index(k, true)][q];
      ia.mrow[10][q] = s;
    }
    // Axis pieces in the kernel's form: t = dot(map.xyz, p) + map.w, the coefficients (zero
    // beyond the piece's own) and each term's offset in the control values.
    const int stride[3] = {p.dims[1] * p.dims[2], p.dims[2], 1};
    std::vector<InlinePiece> pcs((size_t)n_pieces);
    std::vector<InlinePieceWide> wide((size_t)n_pieces);
    for (int a = 0; a < 3; ++a) {
      const int end = a < 2 ? p.axis_offset[a + 1] : n_pieces;
      for (int i = p.axis_offset[a]; i < end; ++i) {
        const AxisPieceF& src = p.pieces[i];
        InlinePieceWide& d = wide[i];
        const float* m = p.param_map + 4 * a;
        const double s = src.inv_scale;
        d.map = src.degree == 0 ? make_float4(0, 0, 0, 0)
                                : make_float4((float)(m[0] * s), (float)(m[1] * s), (float)(m[2] * s),
                                              (float)(((double)m[3] - src.origin) * s));
        for (int k = 0; k < kMaxTerms; ++k) {
          for (int q = 0; q < kMaxTerms; ++q) d.coef[k][q] = src.coef[k][q];
          d.off[k] = src.index[k] * stride[a];
        }
        InlinePiece& n = pcs[i];
        n.map = d.map;
        for (int k = 0; k < 4; ++k) n.coef[k] = make_float4(d.coef[k][0], d.coef[k][1], d.coef[k][2], d.coef[k][3]);
        n.off = make_int4(d.off[0], d.off[1], d.off[2], d.off[3]);
      }
    }
    std::vector<uint8_t> mine((size_t)p.patches, 0);
    std::vector<char> seen((size_t)p.sub_vertices, 0);
    for (int q = 0; q < p.patches; ++q)
      for (int k = 0; k < 3; ++k) {
        const int v = p.patch_vertex[3 * q + k];
        if (!seen[v]) {
          seen[v] = 1;
          mine[q] |= uint8_t(1u << k);
        }
      }
    std::vector<int> lv;
    for (int v = 0; v < p.sub_vertices; ++v)
      if (!seen[v]) lv.push_back(v);
    loose_count = (int)lv.size();
    if (loose_count) loose = arena.upload(lv);
    std::vector<InlinePatch> rec = build_patch_records(p, owns, pr, mine);
    if (inline_why.empty() && !place_samples(p, col, evaluated, box_of, rec))
      inline_why = "a sample is not where the patch's corners place it";
    // The walk's (s, t) table (WalkST), an even number of entries (copied as 16-byte pieces),
    // and its boundary points' GridInfo.
    std::vector<float2> st((size_t)(ia.st_count + 1) / 2 * 2, make_float2(0.0f, 0.0f));
    std::vector<GridInfo> walk((size_t)p.grid);
    for (int w = 0; w < p.grid; ++w) {
      const size_t g = (size_t)gi[w].order;
      const int i = w < boundary_points ? w : ia.st_interior + (w - boundary_points);
      st[i] = make_float2((float)tt.bary[3 * g + 1], (float)tt.bary[3 * g + 2]);
      walk[w] = gi[g];
    }
    ia.grid_st = arena.upload(st);
    ia.grid_walk = arena.upload(std::vector<GridInfo>(walk.begin(), walk.begin() + boundary_points));
    // The mode: the boxes where their polynomials fit the device's budget (plan_limits), else
    // the per-sample weights, else the tables in device memory.
    const int C = inline_terms;
    if (inline_why.empty()) {
      ia.list_stride = (32 * boundary_points + 7) / 8 * 8;
      ia.boxes = ia.box_count;
      if (points <= kBoxPoints && ia.shared_bytes(K, C) <= inline_dyn_max) {
        inline_mode = kInlineBoxes;
      } else {
        ia.boxes = 0;
        if (ia.shared_bytes(K, C) <= inline_dyn_max)
          inline_mode = kInlineWeights;
        else
          inline_why = "the lattice and grid tables do not fit in shared memory";
      }
    }
    if (inline_mode < 0) {
      inline_mode = kInlineGlobal;
      ia.boxes = ia.box_count = ia.list_stride = 0;
      ia.pieces_wide = arena.upload(wide);
      ia.patch_rec = arena.upload(rec);
      return;
    }
    ia.box_list = arena.upload(box_list);
    ia.pieces = arena.upload(pcs);
    // Each group's boundary list: the (patch, walk position) pairs that write a position or a
    // normal, in the order of the full walk (so neighbouring threads still store neighbouring
    // points of an edge).
    const int NB = boundary_points;
    const long long groups = blocks_for(p.patches, 32);
    std::vector<uint16_t> list((size_t)groups * ia.list_stride, 0);
    for (long long g = 0; g < groups; ++g) {
      int n = 0;
      const int q_end = (int)std::min<long long>(32, p.patches - g * 32);
      for (int q = 0; q < q_end; ++q) {
        const PatchBoundary& b = rec[(size_t)(g * 32 + q)].bound;
        for (int w = 0; w < NB; ++w) {
          const GridInfo& t = walk[w];
          const bool writes = t.kind == 0 ? b.corner[t.which] >= 0
                                          : b.edge[t.which].x >= 0 || b.edge[t.which].z >= 0;
          if (writes) list[(size_t)g * ia.list_stride + n++] = uint16_t(q | w << 5);
        }
      }
      for (int q = 0; q < q_end; ++q) rec[(size_t)(g * 32 + q)].bound.items = n;
    }
    ia.boundary_list = arena.upload(list);
    ia.patch_rec = arena.upload(rec);
  }

  void stage_D(const float* Dh) { std::memcpy(h_D.ptr, Dh, nD * sizeof(float)); }

  // Whether a frame of the inline path passes the control values as launch parameters
  // (InlineControls) instead of copying them to the device first.
  bool inline_params() const {
    return inline_mode != kInlineGlobal && nD <= 3 * (size_t)kParamPoints && loose_count == 0;
  }
  // Whether this frame runs the inline kernel (else the reference kernels).
  bool inline_path() const { return path == kFused && inline_mode >= 0; }

  // The inline kernel's launch: a persistent grid of as many blocks as fit on the device at
  // once (queried at the first launch), each taking groups of 32 patches until none is left;
  // plus, first, one for the loose vertices when the mesh has any.
  template <class Mark>
  void run_inline(Mark& mark) {
    with_terms(inline_terms, [&](auto c) {
      constexpr int C = decltype(c)::value;
      if (inline_mode == kInlineGlobal)
        run_inline_as<C, kInlineGlobal>(mark);
      else if constexpr (C <= 4) {
        if (inline_mode == kInlineBoxes)
          run_inline_as<C, kInlineBoxes>(mark);
        else
          run_inline_as<C, kInlineWeights>(mark);
      }
    });
  }

  template <int C, int MODE, class Mark>
  void run_inline_as(Mark& mark) {
    auto kern = k_inline<C, MODE, 32, 4, inline_min_blocks(C)>;
    const size_t smem = MODE == kInlineGlobal ? 0 : inline_args.shared_bytes(pv.columns, C);
    InlineControls dp;
    if (inline_params()) std::memcpy(dp.v, h_D.ptr, nD * sizeof(float));
    if (loose_count > 0) {
      mark("loose_vertices");
      k_loose_vertices<C><<<blocks_for(loose_count, 256), 256, 0, stream>>>(pv, fv, D, loose, loose_count);
      CK_LAUNCH(k_loose_vertices);
    }
    mark("sample_fit_tessellate");
    if (pv.patches > 0) {
      if (inline_grid == 0) {
        int per_sm = 0, sms = 0, dev = 0;
        CK(cudaGetDevice(&dev));
        CK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev));
        // Opt in to the largest table any plan may bring on this device (a per-function
        // setting, shared by every evaluator: the real device's budget, also when this one
        // emulates a smaller device), then ask how many blocks of this plan's size fit an SM.
        if (MODE != kInlineGlobal)
          CK(cudaFuncSetAttribute(kern, cudaFuncAttributeMaxDynamicSharedMemorySize, (int)inline_dyn_device));
        CK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kern, 128, smem));
        if (shared_memory_limit > 0) {  // the emulated device's multiprocessor holds fewer
          cudaFuncAttributes fa{};
          CK(cudaFuncGetAttributes(&fa, kern));
          const int64_t block = (int64_t)fa.sharedSizeBytes + (int64_t)smem + lim.reserved_per_block;
          per_sm = std::min<int>(per_sm, (int)(lim.per_multiprocessor / block));
        }
        lim.inline_blocks_per_multiprocessor = std::max(1, per_sm);
        inline_grid = std::max(1, per_sm) * std::max(1, sms);
      }
      InlineArgs ia = inline_args;
      ia.groups = (int)blocks_for(pv.patches, 32);
      ia.D = inline_params() ? nullptr : D;
      kern<<<std::min(ia.groups, inline_grid), 128, smem, stream>>>(pv, fv, ia, dp, render_shift, normals);
      CK_LAUNCH(k_inline);
    }
    mark(nullptr);
  }

  // The reference path (the paper's formulation): sampling and edge kernels, then the two
  // products with cuBLAS around a finishing kernel, then the scatter.
  template <class Mark>
  void run_reference(Mark& mark) {
    const int T = 256;
    mark("sampling");
    if (pv.samples > 0) {
      with_terms(kernel_terms(max_terms), [&](auto c) {
        constexpr int C = decltype(c)::value;
        k_sample<C, sample_min_blocks(C)><<<blocks_for(pv.samples, T), T, 0, stream>>>(pv, fv, D);
      });
      CK_LAUNCH(k_sample);
    }
    mark("edge_adjustment");
    if (pv.edges > 0) {
      k_edge<<<blocks_for(pv.edges, T), T, 0, stream>>>(pv, fv);
      CK_LAUNCH(k_edge);
    }
    if (pv.patches == 0) {
      mark(nullptr);
      return;
    }
    const long long P = pv.patches, K = pv.columns, G = pv.grid;
    mark("gather");
    k_gather<<<blocks_for(P * K, T), T, 0, stream>>>(pv, fv, X);
    CK_LAUNCH(k_gather);
    const float one = 1.0f, zero = 0.0f;
    mark("fit_gemm");
    // F (10 x 6P) = M (10 x K) X (K x 6P); M stored row-major = column-major K x 10.
    CKB(cb->sgemm(cublas, CUBLAS_OP_T, CUBLAS_OP_N, 10, (int)(6 * P), (int)K, &one, pv.fit_matrix, (int)K, X, (int)K,
                  &zero, F, 10));
    mark("fit_finish");
    k_finish<<<blocks_for(P, T), T, 0, stream>>>(pv, fv, F, C);
    CK_LAUNCH(k_finish);
    mark("tessellate_gemm");
    // Q (G x 6P) = B (G x 10) C (10 x 6P); grid_basis stored row-major = column-major 10 x G.
    CKB(cb->sgemm(cublas, CUBLAS_OP_T, CUBLAS_OP_N, (int)G, (int)(6 * P), 10, &one, pv.grid_basis, 10, C, 10, &zero,
                  Q, (int)G));
    mark("tessellate_scatter");
    k_scatter<<<blocks_for(P * G, T), T, 0, stream>>>(pv, fv, Q, C, grid_info, owns, prender, render_shift, normals);
    CK_LAUNCH(k_scatter);
    mark(nullptr);
  }

  // Enqueues the device stages; records events[i] before stage i and returns the stage names
  // (events.size() == names.size() + 1 used).
  void run_stages(std::vector<const char*>* names, bool record) {
    int e = 0;
    auto mark = [&](const char* name) {
      if (!record) return;
      if (name && names) names->push_back(name);
      CK(cudaEventRecord(events.ev[e++], stream));
    };
    if (!(inline_path() && inline_params())) {  // else the control values ride in the launch
      mark("upload");
      CK(cudaMemcpyAsync(D, h_D.ptr, nD * sizeof(float), cudaMemcpyHostToDevice, stream));
    }
    if (inline_path())
      run_inline(mark);
    else
      run_reference(mark);
  }

  // Copies device bytes to host memory behind the work queued on `stream`: straight into a
  // page-locked destination; into any other through the pinned staging buffer in 1 MiB
  // chunks, host threads copying each chunk on as soon as its transfer has finished (bus and
  // host copy overlap, so a pageable destination costs about one chunk's host copy more than
  // the transfer; 4 MiB chunks left a 0.4 ms tail on the H100 machine). Event `from` must be recorded already; events after it are used. Returns
  // the ms from event `from` to the end of the transfers.
  struct HostCopy {
    void* dst;
    const void* src;
    size_t bytes;
  };
  float copy_to_host(const std::vector<HostCopy>& segs, size_t from) {
    constexpr size_t kChunk = size_t(1) << 20;
    struct Chunk {
      char* dst;
      const char* src;
      char* stage;
      size_t bytes;
    };
    std::vector<Chunk> chunks;
    size_t staged = 0;
    std::vector<bool> direct(segs.size(), false);
    for (size_t i = 0; i < segs.size(); ++i) {
      if (!segs[i].bytes) continue;
      cudaPointerAttributes attr{};
      direct[i] = cudaPointerGetAttributes(&attr, segs[i].dst) == cudaSuccess && attr.type == cudaMemoryTypeHost;
      (void)cudaGetLastError();  // some drivers report unregistered host memory as an error
      if (!direct[i]) staged += segs[i].bytes;
    }
    if (staged) h_out.ensure(staged);
    size_t at = 0;
    for (size_t i = 0; i < segs.size(); ++i) {
      if (!segs[i].bytes) continue;
      if (direct[i]) {
        CK(cudaMemcpyAsync(segs[i].dst, segs[i].src, segs[i].bytes, cudaMemcpyDeviceToHost, stream));
        continue;
      }
      for (size_t off = 0; off < segs[i].bytes; off += kChunk) {
        const size_t n = std::min(kChunk, segs[i].bytes - off);
        chunks.push_back({static_cast<char*>(segs[i].dst) + off, static_cast<const char*>(segs[i].src) + off,
                          static_cast<char*>(h_out.ptr) + at, n});
        at += n;
      }
    }
    events.ensure(from + 2 + chunks.size());
    for (size_t c = 0; c < chunks.size(); ++c) {
      CK(cudaMemcpyAsync(chunks[c].stage, chunks[c].src, chunks[c].bytes, cudaMemcpyDeviceToHost, stream));
      CK(cudaEventRecord(events.ev[from + 2 + c], stream));
    }
    CK(cudaEventRecord(events.ev[from + 1], stream));
    // Chunk c to worker c % workers: each chunk is copied on as soon as it has arrived.
    const size_t workers = std::min<size_t>(chunks.size(), (size_t)std::min(default_threads(), 16));
    std::atomic<int> failed{0};
    auto work = [&](size_t w) {
      for (size_t c = w; c < chunks.size(); c += workers) {
        if (failed.load() || cudaEventSynchronize(events.ev[from + 2 + c]) != cudaSuccess) {
          failed = 1;
          return;
        }
        std::memcpy(chunks[c].dst, chunks[c].stage, chunks[c].bytes);
      }
    };
    {
      struct Pool {
        std::vector<std::thread> threads;
        ~Pool() {
          for (auto& t : threads) t.join();
        }
      } pool;
      size_t started = 1;
      try {
        for (; started < workers; ++started) pool.threads.emplace_back(work, started);
      } catch (const std::system_error&) {  // no thread granted: this thread does their share
      }
      if (workers) work(0);
      for (size_t w = started; w < workers; ++w) work(w);
    }
    CK(cudaEventSynchronize(events.ev[from + 1]));
    if (failed) throw CudaError("copy back: a transfer failed");
    float ms = 0;
    CK(cudaEventElapsedTime(&ms, events.ev[from], events.ev[from + 1]));
    return ms;
  }

  StageTimes times_from(const std::vector<const char*>& names, size_t first) {
    StageTimes t;
    double total = 0;
    for (size_t i = 0; i < names.size(); ++i) {
      float ms = 0;
      CK(cudaEventElapsedTime(&ms, events.ev[first + i], events.ev[first + i + 1]));
      t.emplace_back(names[i], ms);
      total += ms;
    }
    return t;
  }
};

CudaEvaluator::CudaEvaluator(std::shared_ptr<const Plan> plan, const std::string& path,
                             int64_t shared_memory_limit)
    : plan_(std::move(plan)), impl_(new Impl) {
  if (shared_memory_limit != 0 && shared_memory_limit < 48 * 1024)
    throw std::invalid_argument("shared_memory_limit: expected 0 (the device's own limits) or at least 49152 bytes "
                                "(48 KiB, what every CUDA device gives a block), got " +
                                std::to_string(shared_memory_limit));
  init_device();
  Impl& m = *impl_;
  m.shared_memory_limit = shared_memory_limit;
  m.path = parse_path(path);
  m.max_terms = 1;
  for (const AxisPieceF& pc : plan_->pieces) m.max_terms = std::max(m.max_terms, std::max(pc.count, pc.degree + 1));
  const Plan& p = *plan_;
  CK(cudaStreamCreateWithFlags(&m.stream, cudaStreamNonBlocking));
  m.events.ensure(16);
  m.plan_limits();

  PlanView& v = m.pv;
  v = host_view(p);
  DeviceArena& a = m.arena;
  v.pieces = a.upload(p.pieces);
  v.sample_position = a.upload(p.sample_position);
  v.sample_piece = a.upload(p.sample_piece);
  v.sample_weight = a.upload(p.sample_weight);
  v.fit_matrix = a.upload(p.fit_matrix);
  v.column_bary = a.upload(p.column_bary);
  v.patch_samples = a.upload(p.patch_samples);
  v.patch_vertex = a.upload(p.patch_vertex);
  v.patch_edge = a.upload(p.patch_edge);
  v.patch_edge_reversed = a.upload(p.patch_edge_reversed);
  v.patch_render_normal = a.upload(p.patch_render_normal);
  v.patch_adjust_normal = a.upload(p.patch_adjust_normal);
  v.edge_vertex = a.upload(p.edge_vertex);
  v.edge_constraint = a.upload(p.edge_constraint);
  v.edge_patch = a.upload(p.edge_patch);
  v.edge_slot = a.upload(p.edge_slot);
  v.edge_flags = a.upload(p.edge_flags);
  v.grid_basis = a.upload(p.grid_basis);
  const TessellationTables tt = build_tessellation(p.level);
  v.local_triangles = a.upload(p.local_triangles);
  v.output_owner = a.upload(p.output_owner);
  // Render-vertex tables stay on the host (the per-corner copy back gathers there); the
  // kernels use the per-patch PatchRender below.
  v.render_owner = v.render_position = v.patch_grid_render = v.render_triangles = nullptr;

  // Which patch writes each edge's tessellation points, and the grid point table.
  std::vector<GridInfo> gi(tt.points.size());
  for (size_t g = 0; g < gi.size(); ++g) gi[g] = {tt.points[g].kind, tt.points[g].which, tt.points[g].step, -1};
  {
    const int IG = (p.level - 1) * (p.level - 2) / 2, NB = (int)gi.size() - IG;
    int nb = 0;
    for (size_t g = 0; g < gi.size(); ++g) {
      if (gi[g].kind == 2 && gi[g].which >= 0 && gi[g].which < IG)
        gi[NB + gi[g].which].order = (int)g;
      else if (gi[g].kind != 2 && nb < NB)
        gi[nb++].order = (int)g;
    }
    for (const GridInfo& q : gi)
      if (q.order < 0) throw std::logic_error("CudaEvaluator: unexpected tessellation grid");
  }
  std::vector<uint8_t> owns((size_t)p.patches, 0);
  const long long edge_points = (long long)p.edges * (p.level - 1);
  for (long long i = 0; i < edge_points; ++i) {
    int pp = p.output_owner[2 * i], g = p.output_owner[2 * i + 1];
    if (pp < 0 || g < 0 || gi[g].kind != 1) throw std::logic_error("CudaEvaluator: unexpected output owner table");
    owns[pp] |= uint8_t(1u << gi[g].which);
  }
  m.grid_info = a.upload(gi);
  m.owns = a.upload(owns);
  const std::vector<PatchRender> render = build_patch_render(p, tt);
  m.prender = a.upload(render);
  m.render_shift = (long long)p.render_vertices - p.output_vertices;
  m.build_inline_tables(p, tt, gi, owns, render);

  const long long S = p.samples, E = p.edges, P = p.patches, N = p.output_vertices, G = p.grid;
  m.nD = 3 * (size_t)p.dims[0] * p.dims[1] * p.dims[2];
  m.D = a.alloc<float>(m.nD);
  m.h_D.ensure(m.nD * sizeof(float));
  FrameView& f = m.fv;
  f.sample_value = a.alloc<float>(3 * S);
  f.sample_jacobian = a.alloc<float>(9 * S);
  f.edge_control = a.alloc<float>(6 * E);
  f.patch_control = a.alloc<float>(60 * P);
  f.patch_normal = f.patch_control + 30 * P;
  // The interior's first output vertex (and its render vertex) 16-byte aligned, so that every
  // run of interior points starts 16-byte aligned (wide stores): the buffers start 0-3 floats
  // into their allocations.
  const long long interior0 = p.sub_vertices + (long long)p.edges * (p.level - 1);
  auto lead = [](long long first) { return (int)((4 - (3 * first) % 4) % 4); };
  f.positions = a.alloc<float>(3 * N + 3) + lead(interior0);
  f.corner_normals = nullptr;
  (void)G;
  m.normals = a.alloc<float>(3 * (long long)p.render_vertices + 3) + lead(interior0 + m.render_shift);
  if (m.path == kCublas) {
    m.ensure_cublas();
  } else if (m.inline_mode < 0) {  // the fused path runs the reference kernels for this plan
    try {
      m.ensure_cublas();
    } catch (const CudaError& e) {
      throw CudaError("the inline kernel cannot run this plan (" + m.inline_why +
                      "), and the cuBLAS path that would serve it is unavailable: " + e.what());
    }
  }
  CK(cudaDeviceSynchronize());
}

CudaEvaluator::~CudaEvaluator() = default;

const char* CudaEvaluator::kernel() const {
  const Impl& m = *impl_;
  if (!m.inline_path()) return "cublas";
  return m.inline_mode == kInlineBoxes ? "inline (boxes)" : m.inline_mode == kInlineWeights ? "inline (weights)"
                                                                                          : "inline (global)";
}

sffd_cuda_limits CudaEvaluator::limits() const {
  sffd_cuda_limits l = impl_->lim;
  const Impl& m = *impl_;
  l.inline_dynamic = m.inline_path() && m.inline_mode != kInlineGlobal
                         ? (int64_t)m.inline_args.shared_bytes(plan_->columns, m.inline_terms)
                         : 0;
  return l;
}

std::string CudaEvaluator::path() const { return impl_->path == kFused ? "fused" : "cublas"; }

size_t CudaEvaluator::output_bytes() const {
  const Plan& p = *plan_;
  return 12 * ((size_t)p.output_vertices + (size_t)p.render_vertices);
}

size_t CudaEvaluator::device_bytes() const { return impl_->arena.bytes; }

void CudaEvaluator::poison() {
  Impl& m = *impl_;
  const Plan& p = *plan_;
  auto fill = [&](float* ptr, long long n) {
    if (!ptr || n <= 0) return;
    k_fill_nan<<<blocks_for(n, 256), 256, 0, m.stream>>>(ptr, n);
    CK_LAUNCH(k_fill_nan);
  };
  const long long S = p.samples, E = p.edges, P = p.patches;
  fill(m.fv.sample_value, 3 * S);
  fill(m.fv.sample_jacobian, 9 * S);
  fill(m.fv.edge_control, 6 * E);
  fill(m.fv.patch_control, 60 * P);
  fill(m.fv.positions, 3LL * p.output_vertices);
  fill(m.normals, 3LL * p.render_vertices);
  if (m.X) {
    fill(m.X, P * p.columns * 6);
    fill(m.F, 60 * P);
    fill(m.C, 60 * P);
    fill(m.Q, 6 * P * p.grid);
  }
  CK(cudaStreamSynchronize(m.stream));
}

StageTimes CudaEvaluator::evaluate_device(const float* D) {
  Impl& m = *impl_;
  std::vector<const char*> names;
  m.stage_D(D);
  m.run_stages(&names, true);
  CK(cudaEventSynchronize(m.events.ev[names.size()]));
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names, 0);
  double total = 0;
  for (auto& kv : t) total += kv.second;
  t.emplace_back("device_total", total);
  return t;
}

StageTimes CudaEvaluator::evaluate(const float* D, float* positions, float* corner_normals) {
  using Clock = std::chrono::steady_clock;
  Impl& m = *impl_;
  const Plan& p = *plan_;
  const size_t N = p.output_vertices, R = p.render_vertices, T = p.output_triangles;
  m.h_out.ensure(12 * (N + R));
  std::vector<const char*> names;
  m.stage_D(D);
  m.run_stages(&names, true);
  size_t e = names.size();  // event e marks the end of the device stages
  // Only the compact output crosses the bus (positions N x 3, render normals R x 3); the
  // per-corner normals are gathered on the host, straight into the caller's buffer.
  float* hp = static_cast<float*>(m.h_out.ptr);
  float* hn = hp + 3 * N;
  CK(cudaMemcpyAsync(hp, m.fv.positions, 12 * N, cudaMemcpyDeviceToHost, m.stream));
  if (corner_normals)  // null: positions only (the device still computed the normals)
    CK(cudaMemcpyAsync(hn, m.normals, 12 * R, cudaMemcpyDeviceToHost, m.stream));
  CK(cudaEventRecord(m.events.ev[e + 1], m.stream));
  CK(cudaEventSynchronize(m.events.ev[e + 1]));
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names, 0);
  float ms = 0;
  CK(cudaEventElapsedTime(&ms, m.events.ev[e], m.events.ev[e + 1]));
  t.emplace_back("copy_back", ms);
  // Host side, split across threads: the first touch of fresh (numpy) pages dominates, and
  // page faults run in parallel.
  auto t0 = Clock::now();
  const int* rt = p.render_triangles.data();
  const int threads = default_threads();
  parallel_for((long long)(3 * N), threads, [&](long long b, long long en) {
    std::memcpy(positions + b, hp + b, 4 * (size_t)(en - b));
  });
  if (corner_normals) parallel_for((long long)(3 * T), threads, [&](long long b, long long en) {
    for (long long i = b; i < en; ++i) {
      const float* s = hn + 3 * (size_t)rt[i];
      float* d = corner_normals + 3 * i;
      d[0] = s[0];
      d[1] = s[1];
      d[2] = s[2];
    }
  });
  t.emplace_back("host_expand", std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  return t;
}

StageTimes CudaEvaluator::evaluate_compact(const float* D, float* positions, float* normals) {
  Impl& m = *impl_;
  const Plan& p = *plan_;
  std::vector<const char*> names;
  m.stage_D(D);
  m.run_stages(&names, true);
  const size_t e = names.size();  // event e marks the end of the device stages
  const float ms = m.copy_to_host({{positions, m.fv.positions, 12 * (size_t)p.output_vertices},
                                   {normals, m.normals, normals ? 12 * (size_t)p.render_vertices : 0}},
                                  e);
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names, 0);
  t.emplace_back("copy_back", ms);
  return t;
}

StageTimes CudaEvaluator::benchmark(const float* D, int iters) {
  Impl& m = *impl_;
  iters = std::max(iters, 3);
  m.stage_D(D);
  for (int i = 0; i < 5; ++i) m.run_stages(nullptr, false);
  CK(cudaStreamSynchronize(m.stream));
  // Per-stage events, one frame at a time.
  std::vector<std::vector<double>> per;
  std::vector<double> totals;
  std::vector<const char*> names;
  for (int it = 0; it < iters; ++it) {
    names.clear();
    m.run_stages(&names, true);
    CK(cudaEventSynchronize(m.events.ev[names.size()]));
    if (per.empty()) per.resize(names.size());
    double total = 0;
    for (size_t i = 0; i < names.size(); ++i) {
      float ms = 0;
      CK(cudaEventElapsedTime(&ms, m.events.ev[i], m.events.ev[i + 1]));
      per[i].push_back(ms);
      total += ms;
    }
    float ms = 0;
    CK(cudaEventElapsedTime(&ms, m.events.ev[0], m.events.ev[names.size()]));
    totals.push_back(ms);
  }
  StageTimes t;
  for (size_t i = 0; i < names.size(); ++i) t.emplace_back(names[i], median(per[i]));
  t.emplace_back("total_events", median(totals));

  // The same frames with the device time alone between the events: each frame queued behind
  // a kernel that holds the stream for 50 us, so that its first event and its launches are
  // already waiting when the device reaches them (nvbench's blocking kernel does the same).
  // Above, the host enqueues the event and then the launch while the device idles: the
  // events time the launch's host latency too (about 5 us a frame on the H100 machine).
  {
    std::vector<double> queued;
    for (int it = 0; it < iters; ++it) {
      k_hold<<<1, 1, 0, m.stream>>>(50000);
      CK_LAUNCH(k_hold);
      m.run_stages(nullptr, true);
      CK(cudaEventSynchronize(m.events.ev[names.size()]));
      float ms = 0;
      CK(cudaEventElapsedTime(&ms, m.events.ev[0], m.events.ev[names.size()]));
      queued.push_back(ms);
    }
    t.emplace_back("total_events_queued", median(queued));
  }

  // The whole frame (D upload + stages) as a CUDA graph, replayed back to back.
  cudaGraph_t graph = nullptr;
  cudaGraphExec_t exec = nullptr;
  CK(cudaStreamBeginCapture(m.stream, cudaStreamCaptureModeThreadLocal));
  try {
    m.run_stages(nullptr, false);
  } catch (...) {
    cudaStreamEndCapture(m.stream, &graph);
    if (graph) cudaGraphDestroy(graph);
    throw;
  }
  CK(cudaStreamEndCapture(m.stream, &graph));
  CK(cudaGraphInstantiate(&exec, graph, 0));
  for (int i = 0; i < 3; ++i) CK(cudaGraphLaunch(exec, m.stream));
  std::vector<double> graph_ms;
  const int reps = 10, per_rep = std::max(iters / reps, 1);
  for (int r = 0; r < reps; ++r) {
    CK(cudaEventRecord(m.events.ev[0], m.stream));
    for (int i = 0; i < per_rep; ++i) CK(cudaGraphLaunch(exec, m.stream));
    CK(cudaEventRecord(m.events.ev[1], m.stream));
    CK(cudaEventSynchronize(m.events.ev[1]));
    float ms = 0;
    CK(cudaEventElapsedTime(&ms, m.events.ev[0], m.events.ev[1]));
    graph_ms.push_back(ms / per_rep);
  }
  cudaGraphExecDestroy(exec);
  cudaGraphDestroy(graph);
  t.emplace_back("total_graph", median(graph_ms));

  // Floor: output bytes at the device-to-device copy bandwidth measured now.
  const size_t bytes = output_bytes();
  void *src = nullptr, *dst = nullptr;
  CK(cudaMalloc(&src, bytes));
  cudaError_t err = cudaMalloc(&dst, bytes);
  if (err != cudaSuccess) {
    cudaFree(src);
    CK(err);
  }
  std::vector<double> copy_ms;
  for (int i = 0; i < iters + 3; ++i) {
    CK(cudaEventRecord(m.events.ev[0], m.stream));
    CK(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToDevice, m.stream));
    CK(cudaEventRecord(m.events.ev[1], m.stream));
    CK(cudaEventSynchronize(m.events.ev[1]));
    float ms = 0;
    CK(cudaEventElapsedTime(&ms, m.events.ev[0], m.events.ev[1]));
    if (i >= 3) copy_ms.push_back(ms);
  }
  cudaFree(src);
  cudaFree(dst);
  double cms = median(copy_ms);
  double bw = 2.0 * bytes / (cms * 1e-3);  // bytes read + written per second
  t.emplace_back("d2d_copy_ms", cms);
  t.emplace_back("d2d_bandwidth_GBps", bw * 1e-9);
  t.emplace_back("floor_ms", bytes / bw * 1e3);
  t.emplace_back("output_bytes", (double)bytes);
  CK(cudaGetLastError());
  return t;
}

// ================================================================= baseline

struct CudaUpsamplingBaseline::Impl {
  DeviceArena arena;
  PlanView pv{};
  float *D = nullptr, *rest_normal = nullptr, *pos = nullptr, *nrm = nullptr;
  size_t nD = 0;
  cudaStream_t stream = nullptr;
  Events events;
  ~Impl() {
    if (stream) cudaStreamDestroy(stream);
  }
  void launch() {
    if (pv.samples == 0) return;
    k_baseline<<<blocks_for(pv.samples, 256), 256, 0, stream>>>(pv, D, rest_normal, pos, nrm);
    CK_LAUNCH(k_baseline);
  }
};

CudaUpsamplingBaseline::CudaUpsamplingBaseline(std::shared_ptr<const Plan> plan, const std::vector<float>& points,
                                               const std::vector<float>& normals,
                                               const std::vector<uint32_t>& pieces)
    : plan_(std::move(plan)), impl_(new Impl) {
  init_device();
  const Plan& p = *plan_;
  const size_t M = pieces.size();
  if (points.size() != 3 * M || normals.size() != 3 * M)
    throw std::invalid_argument("baseline: points, normals (M x 3) and pieces (M) disagree");
  int axis_count[3];
  for (int a = 0; a < 3; ++a)
    axis_count[a] = (a < 2 ? p.axis_offset[a + 1] : (int)p.pieces.size()) - p.axis_offset[a];
  for (uint32_t pk : pieces)
    for (int a = 0; a < 3; ++a)
      if ((int)((pk >> (10 * a)) & 1023u) >= axis_count[a]) throw std::invalid_argument("baseline: piece index out of range");
  count_ = (int)M;
  Impl& m = *impl_;
  CK(cudaStreamCreateWithFlags(&m.stream, cudaStreamNonBlocking));
  m.events.ensure(4);
  PlanView& v = m.pv;
  v = PlanView{};
  v.samples = (int)M;
  for (int a = 0; a < 3; ++a) {
    v.axis_offset[a] = p.axis_offset[a];
    v.dims[a] = p.dims[a];
  }
  for (int i = 0; i < 12; ++i) v.param_map[i] = p.param_map[i];
  DeviceArena& a = m.arena;
  v.pieces = a.upload(p.pieces);
  v.sample_position = a.upload(points);
  v.sample_piece = a.upload(pieces);
  v.sample_weight = a.upload(std::vector<float>(M, 1.0f));
  m.rest_normal = a.upload(normals);
  m.nD = 3 * (size_t)p.dims[0] * p.dims[1] * p.dims[2];
  m.D = a.alloc<float>(m.nD);
  m.pos = a.alloc<float>(3 * M);
  m.nrm = a.alloc<float>(3 * M);
  CK(cudaDeviceSynchronize());
}

CudaUpsamplingBaseline::~CudaUpsamplingBaseline() = default;

size_t CudaUpsamplingBaseline::control_values() const { return impl_->nD; }

void CudaUpsamplingBaseline::evaluate(const float* D, float* positions, float* normals) {
  Impl& m = *impl_;
  CK(cudaMemcpy(m.D, D, m.nD * sizeof(float), cudaMemcpyHostToDevice));
  m.launch();
  CK(cudaStreamSynchronize(m.stream));
  CK(cudaMemcpy(positions, m.pos, 12 * (size_t)count_, cudaMemcpyDeviceToHost));
  CK(cudaMemcpy(normals, m.nrm, 12 * (size_t)count_, cudaMemcpyDeviceToHost));
}

StageTimes CudaUpsamplingBaseline::benchmark(const float* D, int iters) {
  Impl& m = *impl_;
  iters = std::max(iters, 3);
  CK(cudaMemcpy(m.D, D, m.nD * sizeof(float), cudaMemcpyHostToDevice));
  for (int i = 0; i < 5; ++i) m.launch();
  std::vector<double> ms_all;
  for (int i = 0; i < iters; ++i) {
    CK(cudaEventRecord(m.events.ev[0], m.stream));
    m.launch();
    CK(cudaEventRecord(m.events.ev[1], m.stream));
    CK(cudaEventSynchronize(m.events.ev[1]));
    float ms = 0;
    CK(cudaEventElapsedTime(&ms, m.events.ev[0], m.events.ev[1]));
    ms_all.push_back(ms);
  }
  StageTimes t;
  t.emplace_back("deform_samples", median(ms_all));
  t.emplace_back("output_bytes", (double)output_bytes());
  return t;
}

}  // namespace cuda_impl
}  // namespace sffd
