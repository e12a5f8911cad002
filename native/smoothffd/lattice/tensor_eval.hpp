// The tensor-product contraction shared by every lattice evaluation (double API, CPU and CUDA
// evaluators): given the active terms of the three axes at a point, sum their products with
// the control values D and the derivatives along s.
#pragma once

#include "smoothffd/core/hd.hpp"
#include "smoothffd/lattice/axis_basis.hpp"

namespace sffd {

SFFD_ISA_BEGIN

// Control values as the contraction reads them: D is (nu, nv, nw, NC) C-order (NC = 3: the
// displacements; 4: the displacement and the point's weight, Blender's lattice vertex group),
// a term's offset is its control point's index along the axis times the axis's stride (nv nw,
// nw, 1); D.row(ou + ov) is the row of the u and v terms' offsets, and row(ow, d) gives the NC
// values of that row's point at w offset ow (the row's address once for its CW terms). The
// CUDA inline kernel passes its own readers (the values staged in shared memory, or read
// through the cache), the same contraction. kComponents: the values a point (NC).
template <class TD, int NC = 3>
struct PackedControls {
  static constexpr int kComponents = NC;
  const TD* D;
  struct Row {
    const TD* p;
    SFFD_HD void operator()(int ow, TD d[NC]) const {
      const TD* q = p + NC * ow;
SFFD_UNROLL
      for (int r = 0; r < NC; ++r) d[r] = q[r];
    }
  };
  SFFD_HD Row row(int o) const { return Row{D + NC * (long long)o}; }
};

// Factored contraction with term counts known at compile time: contract w first, then v,
// then u (about 40% fewer multiply-adds than the plain triple loop, and fully unrolled).
// ou, ov, ow: the terms' offsets (PackedControls); D: the controls' reader, NC =
// Controls::kComponents values a point; value[NC], grad[3 NC] (grad[3 r + axis] = dvalue_r/ds).
template <class T, class TD, int CU, int CV, int CW, class Controls>
SFFD_HD void tensor_contract(const int* ou, const T* wu, const T* du, const int* ov, const T* wv, const T* dv,
                             const int* ow, const T* ww, const T* dw, const Controls& D, T* value, T* grad) {
  constexpr int NC = Controls::kComponents;
  T val[NC], gu[NC], gv[NC], gw[NC];
SFFD_UNROLL
  for (int r = 0; r < NC; ++r) val[r] = gu[r] = gv[r] = gw[r] = T(0.0f);
SFFD_UNROLL
  for (int a = 0; a < CU; ++a) {
    T av[NC], avd[NC], awd[NC];  // over b: value, d/dv, d/dw
SFFD_UNROLL
    for (int r = 0; r < NC; ++r) av[r] = avd[r] = awd[r] = T(0.0f);
SFFD_UNROLL
    for (int b = 0; b < CV; ++b) {
      const auto row = D.row(ou[a] + ov[b]);
      T bw[NC], bwd[NC];  // over c: value, d/dw
SFFD_UNROLL
      for (int r = 0; r < NC; ++r) bw[r] = bwd[r] = T(0.0f);
SFFD_UNROLL
      for (int c = 0; c < CW; ++c) {
        TD d[NC];
        row(ow[c], d);
SFFD_UNROLL
        for (int r = 0; r < NC; ++r) {
          bw[r] += ww[c] * (T)d[r];
          bwd[r] += dw[c] * (T)d[r];
        }
      }
SFFD_UNROLL
      for (int r = 0; r < NC; ++r) {
        av[r] += wv[b] * bw[r];
        avd[r] += dv[b] * bw[r];
        awd[r] += wv[b] * bwd[r];
      }
    }
SFFD_UNROLL
    for (int r = 0; r < NC; ++r) {
      val[r] += wu[a] * av[r];
      gu[r] += du[a] * av[r];
      gv[r] += wu[a] * avd[r];
      gw[r] += wu[a] * awd[r];
    }
  }
SFFD_UNROLL
  for (int r = 0; r < NC; ++r) {
    value[r] = val[r];
    grad[3 * r] = gu[r];
    grad[3 * r + 1] = gv[r];
    grad[3 * r + 2] = gw[r];
  }
}

// tensor_contract over D (nu, nv, nw, NC) from the terms' control indices iu, iv, iw.
template <class T, class TD, int CU, int CV, int CW, int NC = 3>
SFFD_HD void tensor_eval_fixed(const int* iu, const T* wu, const T* du, const int* iv,
                               const T* wv, const T* dv, const int* iw, const T* ww,
                               const T* dw, const TD* D, int nv, int nw, T* value, T* grad) {
  int ou[CU], ov[CV];
SFFD_UNROLL
  for (int a = 0; a < CU; ++a) ou[a] = iu[a] * nv * nw;
SFFD_UNROLL
  for (int b = 0; b < CV; ++b) ov[b] = iv[b] * nw;
  tensor_contract<T, TD, CU, CV, CW>(ou, wu, du, ov, wv, dv, iw, ww, dw, PackedControls<TD, NC>{D}, value, grad);
}

// Value v and derivative d in t of one term's polynomial sum_q c(q) t^q, q = 0 .. top (its
// degree; N > top at compile time): Horner from the highest power. Every evaluator's per-axis
// weights (sample_weights, the CUDA inline kernel).
template <int N, class T, class Coef>
SFFD_HD void horner(const Coef& c, int top, T t, T& v, T& d) {
  v = T(0.0f);
  d = T(0.0f);
SFFD_UNROLL
  for (int q = N - 1; q >= 0; --q) {
    if (q > top) continue;
    if (q == top) {
      v = T(c(q));
      continue;
    }
    d = d * t + v;
    v = v * t + c(q);
  }
}

// D is (nu, nv, nw, NC) C-order. value[NC] = sum w_a w_b w_c D_abc; grad[3*r + axis] =
// dvalue_r/ds_axis. Every axis passes kMaxTerms terms, zero weights (and any valid index)
// beyond its own count; `count` is the largest count of the three. The contraction runs with a
// compile-time size (1, 2, 3, 4 or 6 terms an axis), so on the GPU every array stays in
// registers (a loop over a run-time count would put them in local memory).
template <class T, class TD, int NC = 3>
SFFD_HD void tensor_eval(const int* iu, const T* wu, const T* du, const int* iv, const T* wv,
                         const T* dv, const int* iw, const T* ww, const T* dw, int count,
                         const TD* D, int nv, int nw, T* value, T* grad) {
  if (count <= 1)
    tensor_eval_fixed<T, TD, 1, 1, 1, NC>(iu, wu, du, iv, wv, dv, iw, ww, dw, D, nv, nw, value, grad);
  else if (count == 2)
    tensor_eval_fixed<T, TD, 2, 2, 2, NC>(iu, wu, du, iv, wv, dv, iw, ww, dw, D, nv, nw, value, grad);
  else if (count == 3)
    tensor_eval_fixed<T, TD, 3, 3, 3, NC>(iu, wu, du, iv, wv, dv, iw, ww, dw, D, nv, nw, value, grad);
  else if (count == 4)
    tensor_eval_fixed<T, TD, 4, 4, 4, NC>(iu, wu, du, iv, wv, dv, iw, ww, dw, D, nv, nw, value, grad);
  else
    tensor_eval_fixed<T, TD, kMaxTerms, kMaxTerms, kMaxTerms, NC>(iu, wu, du, iv, wv, dv, iw, ww, dw,
                                                                 D, nv, nw, value, grad);
}

// F = p + weight * value; J = I + weight * grad * A, A = ds/dp (row-major 3x3 part of the
// affine map object -> parameter space).
template <class T>
SFFD_HD void compose_deformation(const T p[3], T weight, const T value[3], const T grad[9],
                                 const T A[9], T F[3], T J[9]) {
  for (int r = 0; r < 3; ++r) {
    F[r] = p[r] + weight * value[r];
    for (int c = 0; c < 3; ++c) {
      T g = grad[3 * r] * A[c] + grad[3 * r + 1] * A[3 + c] + grad[3 * r + 2] * A[6 + c];
      J[3 * r + c] = (r == c ? T(1) : T(0)) + weight * g;
    }
  }
}

// Blender's lattice vertex group (Lattice.vertex_group; BKE_lattice_deform_data_eval_co):
// value[0..2] = d, the displacement, value[3] = s, the points' weights interpolated with the
// same basis; grad (3 x 4 rows, as tensor_contract writes them) their derivatives in s. Blender
// blends p toward p + weight d by weight s, its per-point factor `weight` entering both sums:
//   F = p + weight^2 s d,   J = I + weight^2 (s dd/dp + d (ds/dp)^T),  d/dp = d/ds A.
template <class T>
SFFD_HD void compose_weighted_deformation(const T p[3], T weight, const T value[4], const T grad[12],
                                          const T A[9], T F[3], T J[9]) {
  const T w2 = weight * weight;
  const T ws = w2 * value[3];
  T gs[3];
  for (int c = 0; c < 3; ++c) gs[c] = grad[9] * A[c] + grad[10] * A[3 + c] + grad[11] * A[6 + c];
  for (int r = 0; r < 3; ++r) {
    F[r] = p[r] + ws * value[r];
    const T wd = w2 * value[r];
    for (int c = 0; c < 3; ++c) {
      T g = grad[3 * r] * A[c] + grad[3 * r + 1] * A[3 + c] + grad[3 * r + 2] * A[6 + c];
      J[3 * r + c] = (r == c ? T(1) : T(0)) + (ws * g + wd * gs[c]);
    }
  }
}

SFFD_ISA_END

}  // namespace sffd
