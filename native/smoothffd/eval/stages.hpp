// The per-frame stages of smooth FFD, one function per element, shared by the CPU evaluator
// (loops) and the CUDA kernels (one thread per element; the inline kernel calls the pieces
// with its own data access: docs/algorithm.md lists where each stage lives):
//   1. sample_point      (sec. 5.1)  F and its Jacobian at one sample point
//   2. adjust_edge       (sec. 4.2)  fitted edge control points, moved to the tangent plane
//                                     (smooth end) or the crease line (sharp end)
//   3. fit_column, finish_patch (Eqs. 11-13, 4.2)  geometry + normal patch of one
//                                     sub-triangle (fit_patch_into: the whole fit of one patch)
//   4. tessellate_*      (Eq. 14)    output positions and normals
#pragma once

#include "smoothffd/core/hd.hpp"
#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/lattice/tensor_eval.hpp"
#include "smoothffd/plan/bezier.hpp"

namespace sffd {

SFFD_ISA_BEGIN

// Per-axis weights of sample s with C terms an axis (C a compile-time size, so on the GPU the
// arrays stay in registers; a loop over the run-time term count would put them in local
// memory). Terms beyond a piece's count get weight 0: its coefficients are 0 there, and the
// evaluators only use C >= every count of the plan. Returns the largest count of the three.
// T = float, or Lanes (eval/lanes.hpp) for several samples of one lattice box at once.
// local: the sample's local coordinate in each piece from the plan (Plan::sample_local), used
// instead of t from the position where the plan has them (spans too small for float).
template <int C, class T = float>
SFFD_HD int sample_weights(const PlanView& pv, const T p[3], uint32_t packed, int idx[3][C],
                           T w[3][C], T dw[3][C], const T* local = nullptr) {
  int count = 0;
SFFD_UNROLL
  for (int a = 0; a < 3; ++a) {
    const AxisPieceF& pc = pv.pieces[pv.axis_offset[a] + ((packed >> (10 * a)) & 1023u)];
    const float* m = pv.param_map + 4 * a;
    T t;
    if (local) {
      t = local[a];
    } else {
      t = ((m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3]) - pc.origin) * pc.inv_scale;
    }
    if (pc.degree == 0) t = 0.0f;
    count = pc.count > count ? pc.count : count;
SFFD_UNROLL
    for (int k = 0; k < C; ++k) {
      T v, d;
      horner<C>([&](int q) { return pc.coef[k][q]; }, pc.degree, t, v, d);
      idx[a][k] = pc.index[k];
      w[a][k] = v;
      dw[a][k] = d * pc.inv_scale;
    }
  }
  return count;
}

// F and J at sample s from the contraction's value and grad (NC values a point; lattice/
// tensor_eval.hpp): F = p + w value, J = I + w grad A (NC = 3), or Blender's lattice vertex
// group blend F = p + w^2 s d (NC = 4: compose_weighted_deformation).
template <int NC>
SFFD_HD void finish_sample(const PlanView& pv, const float p[3], int s, const float* value,
                           const float* grad, float* F, float* J) {
  float A[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A[3 * r + c] = pv.param_map[4 * r + c];
  if constexpr (NC == 4)
    compose_weighted_deformation<float>(p, pv.sample_weight[s], value, grad, A, F, J);
  else
    compose_deformation<float>(p, pv.sample_weight[s], value, grad, A, F, J);
}

// sample_point with NC values a control point (pv.components).
template <int NC>
SFFD_HD void sample_point_nc(const PlanView& pv, const float* D, int s, float* F, float* J) {
  float p[3] = {pv.sample_position[3 * s], pv.sample_position[3 * s + 1], pv.sample_position[3 * s + 2]};
  int idx[3][kMaxTerms];
  float w[3][kMaxTerms], dw[3][kMaxTerms], value[NC], grad[3 * NC];
  const float* local = pv.sample_local ? pv.sample_local + 3 * (long long)s : nullptr;
  int count = sample_weights<kMaxTerms>(pv, p, pv.sample_piece[s], idx, w, dw, local);
  tensor_eval<float, float, NC>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2], dw[2], count, D,
                                pv.dims[1], pv.dims[2], value, grad);
  finish_sample<NC>(pv, p, s, value, grad, F, J);
}

// 1. F(p) = p + w sum W(s(p)) D and J = dF/dp at sample s (with point weights: p + w^2 s d).
SFFD_HD void sample_point(const PlanView& pv, const float* D, int s, float* F, float* J) {
  if (pv.components == 4)
    sample_point_nc<4>(pv, D, s, F, J);
  else
    sample_point_nc<3>(pv, D, s, F, J);
}

// sample_point with C terms an axis at compile time instead of the run-time dispatch on the
// largest count (C at least every count and degree + 1 of the plan's pieces: the padded terms
// are exact zeros, fma(0, d, x) = x, so the result is sample_point's), NC values a control
// point (pv.components). The CUDA kernels' form.
template <int C, int NC = 3>
SFFD_HD void sample_point_fixed(const PlanView& pv, const float* D, int s, float* F, float* J) {
  float p[3] = {pv.sample_position[3 * s], pv.sample_position[3 * s + 1], pv.sample_position[3 * s + 2]};
  int idx[3][C];
  float w[3][C], dw[3][C], value[NC], grad[3 * NC];
  const float* local = pv.sample_local ? pv.sample_local + 3 * (long long)s : nullptr;
  sample_weights<C>(pv, p, pv.sample_piece[s], idx, w, dw, local);
  tensor_eval_fixed<float, float, C, C, C, NC>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2], dw[2], D,
                                               pv.dims[1], pv.dims[2], value, grad);
  finish_sample<NC>(pv, p, s, value, grad, F, J);
}

// Moves control point c next to corner P: onto the tangent plane of the (averaged) normal at
// a smooth end, onto the line through P along n0 x n1 at a sharp end (paper Fig. 4).
SFFD_HD V3 adjust_control_point(V3 c, V3 P, V3 n0, V3 n1, bool has_n1, bool sharp) {
  if (sharp && has_n1) {
    V3 t = cross(n0, n1);
    if (dot(t, t) > 1e-12f) {
      t = (1.0f / sqrtf(dot(t, t))) * t;
      return P + dot(c - P, t) * t;
    }
  }
  V3 n = has_n1 ? normalized_or(n0 + n1, n0) : n0;
  return c - dot(c - P, n) * n;
}

// 2. Edge control points of an edge from its end samples Pa, Pb and the two constraint
// samples Q1, Q2 (cubic interpolation at 0, 1/3, 2/3, 1), then adjusted at both ends: c[0]
// next to a, c[1] next to b. sharp: bit 0 sharp at a, bit 1 at b; has1: a second patch
// (side 1); normal(end, side): the deformed adjustment normal of side `side`'s patch at that
// end (deformed_end_normal). keep: the edge keeps the fitted points (kKeepFitted: non-manifold
// edges and flat faces' edges).
template <class EndNormal>
SFFD_HD void edge_control_points_with(V3 Pa, V3 Pb, V3 Q1, V3 Q2, unsigned sharp, bool keep, bool has1,
                                      const EndNormal& normal, V3 c[2]) {
  const float s6 = 1.0f / 6.0f;
  c[0] = s6 * (-5.0f * Pa + 18.0f * Q1 - 9.0f * Q2 + 2.0f * Pb);
  c[1] = s6 * (2.0f * Pa - 9.0f * Q1 + 18.0f * Q2 - 5.0f * Pb);
  if (keep) return;
  for (int end = 0; end < 2; ++end) {
    const V3 n0 = normal(end, 0);
    const V3 n1 = has1 ? normal(end, 1) : n0;
    c[end] = adjust_control_point(c[end], end ? Pb : Pa, n0, n1, has1, (sharp >> end) & 1u);
  }
}

// The rest adjustment normal m at an edge end deformed by the Jacobian J there (Eq. 3).
SFFD_HD V3 deformed_end_normal(const float* J, V3 m) { return normalized_or(cofactor_apply(J, m), m); }

// edge_control_points_with the end normals deformed here from the Jacobians Ja, Jb at the ends
// and rest(end, side), the rest adjustment normals (the plan's tables for adjust_edge, the
// patch record for the CUDA inline kernel, whose two patches of an edge so compute bitwise the
// same points).
template <class RestNormal>
SFFD_HD void edge_control_points(V3 Pa, V3 Pb, V3 Q1, V3 Q2, const float* Ja, const float* Jb, unsigned sharp,
                                 bool keep, bool has1, const RestNormal& rest, V3 c[2]) {
  edge_control_points_with(Pa, Pb, Q1, Q2, sharp, keep, has1,
                           [&](int end, int side) { return deformed_end_normal(end ? Jb : Ja, rest(end, side)); }, c);
}

// The adjusted control points of edge e from the frame's sample buffers and the plan's edge
// tables (once per edge, so both patches on it share the result), the end normals from
// normal(end, side) (the CPU reads its per-frame table of them: eval/cpu_frame.hpp).
template <class EndNormal>
SFFD_HD void adjust_edge_with(const PlanView& pv, const FrameView& fv, int e, const EndNormal& normal) {
  const int a = pv.edge_vertex[2 * e], b = pv.edge_vertex[2 * e + 1];
  const V3 Pa = load3(fv.sample_value + 3 * (long long)a), Pb = load3(fv.sample_value + 3 * (long long)b);
  const V3 Q1 = load3(fv.sample_value + 3 * (long long)pv.edge_constraint[2 * e]);
  const V3 Q2 = load3(fv.sample_value + 3 * (long long)pv.edge_constraint[2 * e + 1]);
  const uint8_t flags = pv.edge_flags[e];
  V3 c[2];
  edge_control_points_with(Pa, Pb, Q1, Q2, flags & (kSharpAtA | kSharpAtB), (flags & kKeepFitted) != 0,
                           pv.edge_patch[2 * e + 1] >= 0, normal, c);
  store3(fv.edge_control + 6 * (long long)e, c[0]);
  store3(fv.edge_control + 6 * (long long)e + 3, c[1]);
}

// adjust_edge_with the end normals deformed here from the end samples' Jacobians.
SFFD_HD void adjust_edge(const PlanView& pv, const FrameView& fv, int e) {
  const int ends[2] = {pv.edge_vertex[2 * e], pv.edge_vertex[2 * e + 1]};
  adjust_edge_with(pv, fv, e, [&](int end, int side) {
    const V3 m = load3(pv.patch_adjust_normal + 9 * (long long)pv.edge_patch[2 * e + side] +
                       3 * pv.edge_slot[4 * e + 2 * side + end]);
    return deformed_end_normal(fv.sample_jacobian + 9 * (long long)ends[end], m);
  });
}

// 3. Constrained fit of the geometry and normal patches of patch p together (Eq. 13), then
// the adjusted edge control points replace the fitted ones and the centre moves with them.
//
// Deformed, interpolated render normal at barycentric point (b0, b1, b2) from the sample's
// Jacobian J: the patch's rest corner normals rn interpolated there, cofactor-deformed (Eq. 3).
SFFD_HD V3 deformed_normal_at(float b0, float b1, float b2, const V3 rn[3], const float* J) {
  V3 n0 = b0 * rn[0] + b1 * rn[1] + b2 * rn[2];
  V3 n = normalized_or(cofactor_apply(J, n0), n0);
  return normalized_or(n, rn[0]);
}

// deformed_normal_at column k's point.
SFFD_HD V3 deformed_column_normal(const PlanView& pv, int k, const V3 rn[3], const float* J) {
  const float* b = pv.column_bary + 3 * k;
  return deformed_normal_at(b[0], b[1], b[2], rn, J);
}

// The paper leaves the centre b111 where the fit put it. We move it by 3/2 of the mean motion
// of the six edge control points: PN triangles' b111 = E + (E - V)/2 written as an update, so
// a rest-pose patch with exact normals reproduces the PN centre (a rest-pose icosphere comes
// out far closer to its sphere than with the fitted centre; tests/test_sphere_and_sharp.py).
// fitted, adjusted: the sums of the six edge control points before and after the adjustment.
SFFD_HD V3 moved_centre(V3 centre, V3 fitted, V3 adjusted) {
  return centre + 0.25f * (adjusted - fitted);  // 3/2 * (mean of 6 differences)
}

// One column k of patch p: the deformed sample x and its deformed, interpolated render normal n.
SFFD_HD void fit_column(const PlanView& pv, const FrameView& fv, int p, int k, const V3 rn[3], V3& x, V3& n) {
  int s = pv.patch_samples[(long long)p * pv.columns + k];
  x = load3(fv.sample_value + 3 * (long long)s);
  n = deformed_column_normal(pv, k, rn, fv.sample_jacobian + 9 * (long long)s);
}

// Replaces the corners of fitted geometry patch g with the exact corners and the edge control
// points with the adjusted ones (edge_cp[k]: next to corner k, next to corner k + 1), and
// moves the centre with them.
SFFD_HD void finish_patch_from(const V3 corner[3], const V3 edge_cp[3][2], V3 g[10]) {
  V3 fitted_mean = v3(0, 0, 0), adjusted_mean = v3(0, 0, 0);
  for (int k = 0; k < 3; ++k) {
    g[k] = corner[k];
    int i0 = edge_control_index(k, false), i1 = edge_control_index(k, true);
    fitted_mean += g[i0] + g[i1];
    g[i0] = edge_cp[k][0];
    g[i1] = edge_cp[k][1];
    adjusted_mean += g[i0] + g[i1];
  }
  g[kCentre] = moved_centre(g[kCentre], fitted_mean, adjusted_mean);
}

// The corners and adjusted edge control points of patch p from the frame's buffers
// (cp[k]: next to corner k, next to corner k + 1).
SFFD_HD void patch_boundary(const PlanView& pv, const FrameView& fv, int p, V3 corner[3], V3 cp[3][2]) {
  for (int k = 0; k < 3; ++k) {
    corner[k] = load3(fv.sample_value + 3 * (long long)pv.patch_vertex[3 * p + k]);
    int e = pv.patch_edge[3 * p + k];
    bool rev = pv.patch_edge_reversed[3 * p + k];
    V3 near_a = load3(fv.edge_control + 6 * (long long)e), near_b = load3(fv.edge_control + 6 * (long long)e + 3);
    cp[k][0] = rev ? near_b : near_a;
    cp[k][1] = rev ? near_a : near_b;
  }
}

// finish_patch_from with the corners and edge control points from the frame's buffers.
SFFD_HD void finish_patch(const PlanView& pv, const FrameView& fv, int p, V3 g[10]) {
  V3 corner[3], cp[3][2];
  patch_boundary(pv, fv, p, corner, cp);
  finish_patch_from(corner, cp, g);
}

// The geometry patch from its boundary and its centre row's value c_p + sum_j a_pj D_j
// (plan/centre_rows.hpp): finish_patch_from's patch, the fitted edge points' share of the
// moved centre already in the row.
SFFD_HD void patch_from_centre_row(const V3 corner[3], const V3 edge_cp[3][2], V3 row_value, V3 g[10]) {
  V3 adjusted = v3(0, 0, 0);
  for (int k = 0; k < 3; ++k) {
    g[k] = corner[k];
    g[edge_control_index(k, false)] = edge_cp[k][0];
    g[edge_control_index(k, true)] = edge_cp[k][1];
    adjusted += edge_cp[k][0] + edge_cp[k][1];
  }
  g[kCentre] = row_value + 0.25f * adjusted;
}

// A centre row's block (Plan::centre_box): control indices lo[a] + [0, ext[a]) along axis a.
SFFD_HD void unpack_centre_box(uint64_t box, int lo[3], int ext[3]) {
  for (int a = 0; a < 3; ++a) {
    lo[a] = (int)((box >> (16 * a)) & 0xffffu);
    ext[a] = (int)((box >> (48 + 5 * a)) & 31u);
  }
}

// The reference value of patch p's centre row (the CPU evaluator's is on lanes: same terms,
// another order): c_p + sum_j a_pj D_j over the patch's block.
SFFD_HD V3 centre_row_value(const PlanView& pv, const float* D, int p) {
  int lo[3], ext[3];
  unpack_centre_box(pv.centre_box[p], lo, ext);
  const float* row = pv.centre_row + pv.centre_start[p];
  V3 x = load3(pv.centre_constant + 3 * (long long)p);
  for (int u = 0, i = 0; u < ext[0]; ++u)
    for (int v = 0; v < ext[1]; ++v)
      for (int w = 0; w < ext[2]; ++w, ++i) {
        const long long o = ((long long)(lo[0] + u) * pv.dims[1] + lo[1] + v) * pv.dims[2] + lo[2] + w;
        x += row[i] * load3(D + 3 * o);
      }
  return x;
}

// The whole fit of patch p: fit_column over its columns, the product with M_r, finish_patch;
// the 10 + 10 control points to out_g and out_n (30 floats each). The evaluators split it for
// speed (cpu_fitting.cpp, the CUDA kernels); tests hold their fits to this one.
SFFD_HD void fit_patch_into(const PlanView& pv, const FrameView& fv, int p, float* out_g, float* out_n) {
  const int K = pv.columns;
  V3 rn[3];
  for (int k = 0; k < 3; ++k) rn[k] = load3(pv.patch_render_normal + 9 * (long long)p + 3 * k);
  V3 g[10], nn[10];
  for (int r = 0; r < 10; ++r) g[r] = nn[r] = v3(0, 0, 0);
  // M_r's boundary rows (corners, edge points) are exactly zero outside the 9 constraint
  // columns (the constraints fix the boundary; see plan/fit_matrix.hpp), so only the centre
  // row runs over every column: 6x fewer multiply-adds, bitwise the same sums.
  for (int k = 0; k < K; ++k) {
    V3 x, n;
    fit_column(pv, fv, p, k, rn, x, n);
    int r0 = k < K - 9 ? kCentre : 0;
    for (int r = r0; r < 10; ++r) {
      float m = pv.fit_matrix[r * K + k];
      g[r] += m * x;
      nn[r] += m * n;
    }
  }
  finish_patch(pv, fv, p, g);
  for (int r = 0; r < 10; ++r) {
    store3(out_g + 3 * r, g[r]);
    store3(out_n + 3 * r, nn[r]);
  }
}

// Cubic patch with control points cp (10 x 3) at the grid point with basis B (10 values).
SFFD_HD V3 eval_cubic(const float* B, const float* cp) {
  V3 x = v3(0, 0, 0);
  for (int k = 0; k < 10; ++k) x += B[k] * load3(cp + 3 * k);
  return x;
}

// unit_patch_normal's fallback direction from the sum of the normal patch's corner points.
SFFD_HD V3 patch_normal_fallback(V3 corner_sum) { return normalized_or(corner_sum, v3(0, 0, 1)); }

// Unit normal from the normal patch value n (fallback: the mean of the corner normals).
SFFD_HD V3 unit_patch_normal(V3 n, const float* cp) {
  return normalized_or(n, patch_normal_fallback(load3(cp) + load3(cp + 3) + load3(cp + 6)));
}

// 4a. Output vertex o: input and clip vertices are the deformed samples themselves; edge and
// interior points are evaluated on their owner patch (Eq. 14 row).
SFFD_HD void tessellate_position(const PlanView& pv, const FrameView& fv, int o) {
  V3 x;
  if (o < pv.sub_vertices) {
    x = load3(fv.sample_value + 3 * (long long)o);
  } else {
    long long i = o - pv.sub_vertices;
    int p = pv.output_owner[2 * i], g = pv.output_owner[2 * i + 1];
    x = eval_cubic(pv.grid_basis + 10 * g, fv.patch_control + 30 * (long long)p);
  }
  store3(fv.positions + 3 * (long long)o, x);
}

// 4b. Unit normal of patch p at grid point g.
SFFD_HD V3 tessellate_normal(const PlanView& pv, const FrameView& fv, int p, int g) {
  const float* cp = fv.patch_normal + 30 * (long long)p;
  return unit_patch_normal(eval_cubic(pv.grid_basis + 10 * g, cp), cp);
}

SFFD_ISA_END

}  // namespace sffd
