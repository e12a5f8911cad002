// Device helpers of the inline kernel's tessellation (inline_kernel.cu): a group's patches in
// shared memory (PatchCtrl) in power form, evaluated at the grid's walk, boundary points one a
// thread, interior points two a thread stored straight from registers.
#pragma once

#include <cuda_runtime.h>

#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {
namespace cuda_impl {

// The tables' plain vector structs (device_tables.hpp) as CUDA's vector types of the same
// layout: one vector load each.
__device__ __forceinline__ float4 ld(const F4& v) { return *reinterpret_cast<const float4*>(&v); }
__device__ __forceinline__ int4 ld(const I4& v) { return *reinterpret_cast<const int4*>(&v); }
__device__ __forceinline__ float2 ld(const F2& v) { return *reinterpret_cast<const float2*>(&v); }

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
// 16-byte stores, measured 6% slower on W1.)
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

// Control points of a patch in the inline kernel's shared memory: 30 floats padded to 32, so
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

// Positions x and unit normals n of a patch at N grid points (s[i], t[i]): cg and cn its
// geometry and normal patches in power form (cubic_power_form, plan/bezier.hpp), fallback its
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

// Where tessellate_interior finds an interior point's (s, t) (its PTS points' at once): k_inline's
// table of (s, t) in walk order, whose interior starts at an even index so that a thread's
// two points are one 16-byte load (as one float4 a point with scalar loads of s and t, the
// loads of a warp were 5-way bank conflicts: the shared-memory pipe is k_inline's busiest unit).
struct WalkST {
  const F2* st;
  int interior;  // index of the first interior point (even)
  template <int PTS>
  __device__ __forceinline__ void operator()(int jj, float s[PTS], float t[PTS]) const {
    if constexpr (PTS == 2) {
      const float4 q = *reinterpret_cast<const float4*>(st + interior + jj);
      s[0] = q.x, t[0] = q.y, s[1] = q.z, t[1] = q.w;
    } else {
      const float2 q = ld(st[interior + jj]);
      s[0] = q.x, t[0] = q.y;
    }
  }
};

// The interior points of k_inline's group of patches (tessellate_group), PTS consecutive
// ones a thread (1, or 2 when no pair straddles two patches): each warp takes 32 PTS
// consecutive points of the group's run, the block's last warp the first run (when the runs
// do not divide evenly, the warps at the end take one more: the boundary list gives its extra
// points to the first warps). The thread's (patch q, interior point jj) advances by a
// constant step instead of a division a point. Each thread stores its points straight from
// registers (PTS = 2: three 8-byte stores a field; the evaluator's buffers put the interior's
// first output and render vertex on a 128-byte line, so each warp's run fills whole lines and
// sectors, CudaEvaluator's constructor): no shared-memory round trip
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

// The group's boundary points (corners and edge points) for tessellate_group: from the
// group's list (shared-memory modes) or all of them, one after the other (kInlineGlobal;
// the points no patch of the group writes are skipped).
struct ListedBoundary {
  const uint16_t* list;
  int items;
  __device__ __forceinline__ int count() const { return items; }
  __device__ __forceinline__ void item(int i, int& q, int& w) const {
    const uint32_t e = list[i];
    q = e & 31u, w = e >> 5;
  }
  static constexpr bool kAll = false;
};
struct AllBoundary {
  int patches, points;  // points: the walk's boundary points
  float inv_points;
  __device__ __forceinline__ int count() const { return patches * points; }
  __device__ __forceinline__ void item(int i, int& q, int& w) const {
    q = div_small(i, points, inv_points), w = i - q * points;
  }
  static constexpr bool kAll = true;
};

// The tessellation of k_inline's group of patches (ctrl, already with their fallback normals
// and in power form), in the walk order of the grid (gi: the boundary points' GridInfo, st:
// every point's (s, t)): first the boundary points the group writes (BL: ListedBoundary or
// AllBoundary; sbound: the patches' PatchBoundary tables), one thread a point, so that no
// thread idles beside the others on a point another patch owns; then the interior points,
// which every patch writes, two a thread where no pair straddles two patches, stored straight
// from registers.
template <int kThreads, class BL>
__device__ __forceinline__ void tessellate_group(const PlanView& pv, const FrameView& fv, const GridInfo* __restrict__ gi,
                                                 const WalkST& st, const PatchCtrl* ctrl, const PatchBoundary* sbound,
                                                 const BL& boundary, int base, long long render_shift,
                                                 float* __restrict__ normals) {
  const int L = pv.level;
  const int np = min(kThreads / 4, pv.patches - base);
  const int IG = (L - 1) * (L - 2) / 2;
  const int items = boundary.count();
  for (int i = threadIdx.x; i < items; i += kThreads) {
    int q, w;
    boundary.item(i, q, w);
    const GridInfo t = gi[w];
    int o = -1, r;
    if (t.kind == 0) {
      r = sbound[q].corner[t.which];
    } else {
      const int4 b = ld(sbound[q].edge[t.which]);
      o = b.x + t.step * b.y;
      r = b.z + t.step * b.w;
    }
    if (BL::kAll && r < 0 && o < 0) continue;
    V3 x, n;
    const float2 p = ld(st.st[w]);
    eval_point(p.x, p.y, ctrl[q][0], ctrl[q][1], load3(ctrl[q].fallback), x, n);
    if (r >= 0) store3(normals + 3 * (long long)r, n);
    if (o >= 0) store3(fv.positions + 3 * (long long)o, x);
  }
  if (IG == 0) return;
  const long long o0 = pv.sub_vertices + (long long)pv.edges * (L - 1) + (long long)base * IG;
  // The warps whose threads took one boundary point more take their interior runs last.
  if (IG % 2 == 0)
    tessellate_interior<2, kThreads>(fv, st, ctrl, np * IG, IG, o0, render_shift, normals);
  else
    tessellate_interior<1, kThreads>(fv, st, ctrl, np * IG, IG, o0, render_shift, normals);
}

}  // namespace cuda_impl
}  // namespace sffd
