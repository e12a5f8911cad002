// The cuBLAS reference path's kernels and their launchers (kernels.hpp): the paper's
// formulation, one thread an element, each calling the stage functions of eval/stages.hpp.
//   k_sample   sample_point_fixed: F and J of every sample (and the sub-vertices' positions)
//   k_edge     adjust_edge: the adjusted edge control points of every edge
//   k_gather   fit_column: X (K x 6P), the deformed samples and normals of every patch
//   (SGEMM)    F = M_r X (Eq. 13), in cuda_evaluator.cpp
//   k_finish   finish_patch: exact corners, adjusted edges, centre
//   (SGEMM)    Q = B_q C (Eq. 14)
//   k_scatter  the welded positions and the render vertices' unit normals
#include <cuda_runtime.h>

#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/cuda/kernels.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

// Output vertex of (patch p, grid point g) when p writes it, else -1 (corners are written by
// the sampling kernel; an edge point by the patch that owns it in the plan).
__device__ __forceinline__ long long owned_vertex(const PlanView& pv, const GridInfo* gi, const uint8_t* owns, int p,
                                                  int g) {
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

// F and J of every sample, and the positions of the sub-vertices (input and clip vertices),
// which are samples themselves. C terms an axis (the plan's largest, kernel_terms), registers
// capped by MINB blocks of 256 an SM (C = 3: 4 blocks, 64 registers, measured fastest); NC
// values a control point (pv.components: 4 with point weights).
template <int C, int MINB, int NC>
__global__ void __launch_bounds__(256, MINB) k_sample(PlanView pv, FrameView fv, const float* __restrict__ D) {
  int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= pv.samples) return;
  sample_point_fixed<C, NC>(pv, D, s, fv.sample_value + 3 * (long long)s, fv.sample_jacobian + 9 * (long long)s);
  if (s < pv.sub_vertices) tessellate_position(pv, fv, s);  // input and clip vertices
}

__global__ void k_edge(PlanView pv, FrameView fv) {
  int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e < pv.edges) adjust_edge(pv, fv, e);
}

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

// F (10 x 6P) = M X; finishes the geometry patches and writes C (10 x 6P, same layout).
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

__global__ void k_fill_nan(float* p, long long n) {
  long long i = blockIdx.x * (long long)blockDim.x + threadIdx.x;
  if (i < n) p[i] = __int_as_float(0x7fffffff);
}

constexpr int kThreads = 256;

}  // namespace

namespace {

template <int NC>
void launch_sample_nc(int terms, const PlanView& pv, const FrameView& fv, const float* D, cudaStream_t stream) {
  const unsigned grid = blocks_for(pv.samples, kThreads);
  // Register caps: 4 blocks of 256 an SM up to 3 terms, then 3, then 2.
  switch (terms) {
    case 2: k_sample<2, 4, NC><<<grid, kThreads, 0, stream>>>(pv, fv, D); break;
    case 3: k_sample<3, 4, NC><<<grid, kThreads, 0, stream>>>(pv, fv, D); break;
    case 4: k_sample<4, 3, NC><<<grid, kThreads, 0, stream>>>(pv, fv, D); break;
    case 5: k_sample<5, 2, NC><<<grid, kThreads, 0, stream>>>(pv, fv, D); break;
    default: k_sample<kMaxTerms, 2, NC><<<grid, kThreads, 0, stream>>>(pv, fv, D); break;
  }
}

}  // namespace

void launch_sample(int terms, const PlanView& pv, const FrameView& fv, const float* D, cudaStream_t stream) {
  if (pv.samples <= 0) return;
  if (pv.components == 4)
    launch_sample_nc<4>(terms, pv, fv, D, stream);
  else
    launch_sample_nc<3>(terms, pv, fv, D, stream);
  CK_LAUNCH(k_sample);
}

void launch_edges(const PlanView& pv, const FrameView& fv, cudaStream_t stream) {
  if (pv.edges <= 0) return;
  k_edge<<<blocks_for(pv.edges, kThreads), kThreads, 0, stream>>>(pv, fv);
  CK_LAUNCH(k_edge);
}

void launch_gather(const PlanView& pv, const FrameView& fv, float* X, cudaStream_t stream) {
  k_gather<<<blocks_for((long long)pv.patches * pv.columns, kThreads), kThreads, 0, stream>>>(pv, fv, X);
  CK_LAUNCH(k_gather);
}

void launch_finish(const PlanView& pv, const FrameView& fv, const float* F, float* C, cudaStream_t stream) {
  k_finish<<<blocks_for(pv.patches, kThreads), kThreads, 0, stream>>>(pv, fv, F, C);
  CK_LAUNCH(k_finish);
}

void launch_scatter(const PlanView& pv, const FrameView& fv, const float* Q, const float* C, const GridInfo* gi,
                    const uint8_t* owns, const PatchRender* render, long long render_shift, float* normals,
                    cudaStream_t stream) {
  k_scatter<<<blocks_for((long long)pv.patches * pv.grid, kThreads), kThreads, 0, stream>>>(
      pv, fv, Q, C, gi, owns, render, render_shift, normals);
  CK_LAUNCH(k_scatter);
}

void launch_fill_nan(float* p, long long n, cudaStream_t stream) {
  if (!p || n <= 0) return;
  k_fill_nan<<<blocks_for(n, kThreads), kThreads, 0, stream>>>(p, n);
  CK_LAUNCH(k_fill_nan);
}

cudaError_t kernel_image_status() {
  cudaFuncAttributes fa;
  return cudaFuncGetAttributes(&fa, k_fill_nan);
}

}  // namespace cuda_impl
}  // namespace sffd
