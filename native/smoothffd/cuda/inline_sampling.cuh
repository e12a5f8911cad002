// Device helpers of the inline kernel's sampling (inline_kernel.cu): F and its Jacobian at a
// sample from the axis pieces' weights and the tensor contraction (sample_inline: the weights
// and global modes), or from the lattice boxes in power form (convert_boxes once a block,
// then sample_box: three nested Horner schemes, about half the multiply-adds; the boxes
// mode). The same F and J as sample_point (eval/stages.hpp) up to rounding.
#pragma once

#include <cuda_runtime.h>

#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/cuda/inline_tessellation.cuh"
#include "smoothffd/eval/stages.hpp"

namespace sffd {
namespace cuda_impl {

// A piece's coefficients of term k and its terms' offsets, C terms (C <= 4 for InlinePiece).
template <int C>
__device__ __forceinline__ void piece_coefficients(const InlinePiece& pc, int k, float c[C]) {
  const float4 c4 = ld(pc.coef[k]);
  const float v[4] = {c4.x, c4.y, c4.z, c4.w};
#pragma unroll
  for (int q = 0; q < C; ++q) c[q] = v[q];
}
template <int C>
__device__ __forceinline__ void piece_coefficients(const InlinePieceWide& pc, int k, float c[C]) {
#pragma unroll
  for (int q = 0; q < C; ++q) c[q] = pc.coef[k][q];
}
template <int C>
__device__ __forceinline__ void piece_offsets(const InlinePiece& pc, int o[C]) {
  const int4 q = ld(pc.off);
  const int v[4] = {q.x, q.y, q.z, q.w};
#pragma unroll
  for (int k = 0; k < C; ++k) o[k] = v[k];
}
template <int C>
__device__ __forceinline__ void piece_offsets(const InlinePieceWide& pc, int o[C]) {
#pragma unroll
  for (int k = 0; k < C; ++k) o[k] = pc.off[k];
}

// F = p + w value and J = I + w (dF/dt) A' (compose_deformation, lattice/tensor_eval.hpp)
// with the derivatives in the pieces' own t and A' = the pieces' maps (rows m[a] = dt_a/dp).
__device__ __forceinline__ void compose_inline(float4 pw, const float m[3][3], const float val[3], const float grad[9],
                                               float F[3], float J[9]) {
  const float p[3] = {pw.x, pw.y, pw.z};
  compose_deformation<float>(p, pw.w, val, grad, &m[0][0], F, J);
}

// Where sample_inline reads the control values (tensor_contract's readers, lattice/
// tensor_eval.hpp, with offsets in points: InlinePiece::off). SharedControls: the block's
// float4 copy in shared memory (the weights mode); GlobalControls: the frame's upload, 3
// floats a point, through the read-only cache (the global mode).
struct SharedControls {
  static constexpr int kComponents = 3;
  const float4* v;
  struct Row {
    const float4* p;
    __device__ __forceinline__ void operator()(int ow, float d[3]) const {
      const float4 q = p[ow];
      d[0] = q.x, d[1] = q.y, d[2] = q.z;
    }
  };
  __device__ __forceinline__ Row row(int o) const { return Row{v + o}; }
};
struct GlobalControls {
  static constexpr int kComponents = 3;
  const float* __restrict__ v;
  struct Row {
    const float* __restrict__ p;
    __device__ __forceinline__ void operator()(int ow, float d[3]) const {
      const float* q = p + 3 * ow;
      d[0] = __ldg(q), d[1] = __ldg(q + 1), d[2] = __ldg(q + 2);
    }
  };
  __device__ __forceinline__ Row row(int o) const { return Row{v + 3 * (long long)o}; }
};

// F and J at one sample from the inline tables: sample_point (stages.hpp) with the axis
// pieces in power form and t from the folded map (one affine map a piece instead of the
// lattice's map, the origin and the scale), the per-axis Horner scheme (horner) and the
// contraction (tensor_contract) of lattice/tensor_eval.hpp with the kernel's reader of the
// control values, and J = I + w (dF/dt) A' with A' = the pieces' maps (dt/dp). piece: the
// sample's piece of each axis (indices into pcs); local: the sample's t of each axis where the
// plan has them (Plan::sample_local: spans too small for float positions), else null.
template <int C, class Piece, class Controls>
__device__ __forceinline__ void sample_inline(const Controls& D, const Piece* __restrict__ pcs, float4 pw,
                                              const int piece[3], float F[3], float J[9],
                                              const float* __restrict__ local = nullptr) {
  float w[3][C], dw[3][C], m[3][3];
  int off[3][C];
#pragma unroll
  for (int a = 0; a < 3; ++a) {
    const Piece& pc = pcs[piece[a]];
    const float4 mp = ld(pc.map);
    piece_offsets<C>(pc, off[a]);
    m[a][0] = mp.x, m[a][1] = mp.y, m[a][2] = mp.z;
    const float t = local ? __ldg(local + a) : fmaf(mp.x, pw.x, fmaf(mp.y, pw.y, fmaf(mp.z, pw.z, mp.w)));
#pragma unroll
    for (int k = 0; k < C; ++k) {
      float c[C];
      piece_coefficients<C>(pc, k, c);
      horner<C>([&](int q) { return c[q]; }, C - 1, t, w[a][k], dw[a][k]);
    }
  }
  float val[3], grad[9];
  tensor_contract<float, float, C, C, C>(off[0], w[0], dw[0], off[1], w[1], dw[1], off[2], w[2], dw[2], D, val, grad);
  compose_inline(pw, m, val, grad, F, J);
}

// The lattice boxes of box_list (`boxes` of them) in power form: the C^3 coefficient vectors
// A[i][j][k] of F's polynomial part sum A t_u^i t_v^j t_w^k, each the tensor product of the
// three pieces' weight coefficients with the control values. Computed once a block a frame,
// so that a sample is three nested Horner schemes (about half the multiply-adds of the basis
// weights and their contraction).
template <int C>
__device__ __forceinline__ void convert_boxes(int n_boxes, const I4* box_list, const float4* __restrict__ D4,
                                              const InlinePiece* __restrict__ pcs, float4* __restrict__ boxes) {
  // One thread a (box, i, j): T[c] = sum over a, b of the u and v coefficients times the
  // control values, then A[i][j][k] = sum over c of the w coefficients times T[c] (about a
  // third of the multiply-adds and loads of one full sum a coefficient).
  constexpr int C2 = C * C;
  for (int item = threadIdx.x; item < n_boxes * C2; item += blockDim.x) {
    const int box = item / C2, ij = item - box * C2;
    const int i = ij / C, j = ij - i * C;
    const int4 b = ld(box_list[box]);
    const InlinePiece& pu = pcs[b.x];
    const InlinePiece& pv = pcs[b.y];
    const InlinePiece& pw = pcs[b.z];
    const int4 qu = ld(pu.off), qv = ld(pv.off), qw = ld(pw.off);
    const int ou[4] = {qu.x, qu.y, qu.z, qu.w}, ov[4] = {qv.x, qv.y, qv.z, qv.w}, ow[4] = {qw.x, qw.y, qw.z, qw.w};
    float T[C][3];
#pragma unroll
    for (int c = 0; c < C; ++c) T[c][0] = T[c][1] = T[c][2] = 0.0f;
#pragma unroll
    for (int a = 0; a < C; ++a) {
      const float4 cu4 = ld(pu.coef[a]);
      const float cu = i == 0 ? cu4.x : i == 1 ? cu4.y : i == 2 ? cu4.z : cu4.w;
#pragma unroll
      for (int bb = 0; bb < C; ++bb) {
        const float4 cv4 = ld(pv.coef[bb]);
        const float cuv = cu * (j == 0 ? cv4.x : j == 1 ? cv4.y : j == 2 ? cv4.z : cv4.w);
        const float4* row = D4 + ou[a] + ov[bb];
#pragma unroll
        for (int c = 0; c < C; ++c) {
          const float4 d = row[ow[c]];
          T[c][0] += cuv * d.x;
          T[c][1] += cuv * d.y;
          T[c][2] += cuv * d.z;
        }
      }
    }
    float4* out = boxes + (size_t)box * (C * C2) + ij * C;
#pragma unroll
    for (int k = 0; k < C; ++k) {
      float acc[3] = {0, 0, 0};
#pragma unroll
      for (int c = 0; c < C; ++c) {
        const float4 cw4 = ld(pw.coef[c]);
        const float cw = k == 0 ? cw4.x : k == 1 ? cw4.y : k == 2 ? cw4.z : cw4.w;
#pragma unroll
        for (int r = 0; r < 3; ++r) acc[r] += cw * T[c][r];
      }
      out[k] = make_float4(acc[0], acc[1], acc[2], 0.0f);
    }
  }
}

// One Horner step of a polynomial and its derivative in t, from the highest power down: step
// `from_top` 0 starts the value at c, step 1 starts the derivative at the value (what
// d * t + v gives from d = 0, without the multiply by zero), later steps are both updates.
__device__ __forceinline__ void horner_step(float& v, float& d, float c, float t, int from_top) {
  if (from_top == 0) {
    v = c;
  } else {
    d = from_top == 1 ? v : fmaf(d, t, v);
    v = fmaf(v, t, c);
  }
}

// Value and the three derivatives (in the pieces' own t) of a box polynomial (convert_boxes):
// Horner over k (w), then j (v), then i (u), each carrying its derivative along; the
// derivatives along the inner axes are Horner schemes of their own in the outer variable.
template <int C>
__device__ __forceinline__ void eval_box(const float4* __restrict__ A, float tu, float tv, float tw, float val[3],
                                         float gu[3], float gv[3], float gw[3]) {
  float qv[3], qdv[3], qdw[3], v[3], d[3];
#pragma unroll
  for (int r = 0; r < 3; ++r) gu[r] = qdv[r] = d[r] = 0.0f;  // C = 1: no derivative steps
#pragma unroll
  for (int i = C - 1; i >= 0; --i) {
#pragma unroll
    for (int j = C - 1; j >= 0; --j) {
      const float4* a = A + (i * C + j) * C;
#pragma unroll
      for (int k = C - 1; k >= 0; --k) {
        const float4 ak = a[k];
        const float c[3] = {ak.x, ak.y, ak.z};
#pragma unroll
        for (int r = 0; r < 3; ++r) horner_step(v[r], d[r], c[r], tw, C - 1 - k);
      }
#pragma unroll
      for (int r = 0; r < 3; ++r) {
        horner_step(qv[r], qdv[r], v[r], tv, C - 1 - j);
        if (j == C - 1) qdw[r] = d[r];
        else qdw[r] = fmaf(qdw[r], tv, d[r]);
      }
    }
#pragma unroll
    for (int r = 0; r < 3; ++r) {
      horner_step(val[r], gu[r], qv[r], tu, C - 1 - i);
      if (i == C - 1) {
        gv[r] = qdv[r];
        gw[r] = qdw[r];
      } else {
        gv[r] = fmaf(gv[r], tu, qdv[r]);
        gw[r] = fmaf(gw[r], tu, qdw[r]);
      }
    }
  }
}

// F and J at one sample from the box polynomials: sample_inline's result up to rounding.
template <int C>
__device__ __forceinline__ void sample_box(const float4* __restrict__ boxes, const InlinePiece* __restrict__ pcs,
                                           float4 pw, uint2 box, float F[3], float J[9]) {
  float t[3], m[3][3];
#pragma unroll
  for (int a = 0; a < 3; ++a) {
    const float4 mp = ld(pcs[(box.x >> (10 * a)) & 1023u].map);
    m[a][0] = mp.x, m[a][1] = mp.y, m[a][2] = mp.z;
    t[a] = fmaf(mp.x, pw.x, fmaf(mp.y, pw.y, fmaf(mp.z, pw.z, mp.w)));
  }
  float val[3], gu[3], gv[3], gw[3];
  eval_box<C>(boxes + (size_t)box.y * (C * C * C), t[0], t[1], t[2], val, gu, gv, gw);
  const float grad[9] = {gu[0], gv[0], gw[0], gu[1], gv[1], gw[1], gu[2], gv[2], gw[2]};
  compose_inline(pw, m, val, grad, F, J);
}

}  // namespace cuda_impl
}  // namespace sffd
