// The adaptive tessellation's per-element decisions (eval/adaptive.hpp), written once for the
// CPU driver (adaptive.cpp) and the CUDA kernels (cuda/adaptive_kernels.cu): the bounds, each
// edge's count, each patch's level and pattern, and the pattern's triangles. Both compile them
// without floating-point contraction (and the CUDA file without fast math), from patches the
// shared scalar stages computed the same way: the same counts on either backend.
#pragma once

#include <cmath>

#include "smoothffd/core/hd.hpp"
#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/eval/stages.hpp"
#include "smoothffd/plan/bezier.hpp"

namespace sffd {
namespace adapt {

template <class T>
SFFD_HD T amax(T a, T b) { return a < b ? b : a; }
template <class T>
SFFD_HD T amin(T a, T b) { return b < a ? b : a; }

// ---------------------------------------------------------------------------------------------
// Bounds (docs/algorithm.md, "Adaptive tessellation"). A cubic patch f(s, t), s = b1, t = b2,
// in power form (bezier.hpp) has second derivatives linear in (s, t) and constant third ones.
// For a triangle v0 v1 v2 of parameter points and x = sum l_i v_i in it, Taylor's formula at x
// (exact for a cubic) gives
//   sum l_i f(v_i) - f(x) = 1/2 sum_{i<j} l_i l_j D2f(x)[v_i - v_j] + 1/6 sum_i l_i D3f[v_i - x]
// (the first sum by the identity sum l_i q(v_i - x) = sum_{i<j} l_i l_j q(v_i - v_j) for a
// quadratic form q). |D2f(x)[w]| is at most its largest value at the triangle's corners (a
// norm of a function linear in x), so the first term is at most 1/2 max_l sum l_i l_j Q_ij
// (simplex_max) with Q_ij that largest value for the edge v_i - v_j. With v_i - x =
// sum_j l_j (v_i - v_j), |D3f[v_i - x]| <= (1 - l_i)^3 tau, tau the largest |D3f[a, b, c]|
// over edges a, b, c of the triangle (third_bound), and sum l_i (1 - l_i)^3 <= 0.3 on the
// simplex: the second term is at most 0.05 tau.

struct D3 {
  double x, y, z;
};
SFFD_HD D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
SFFD_HD D3 operator*(double s, D3 a) { return {s * a.x, s * a.y, s * a.z}; }
SFFD_HD double norm(D3 a) { return sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

struct Power {
  D3 a[10];  // CubicPowerTerm order
  D3 t[4];   // D3f along s s s, s s t, s t t, t t t (6 a30, 2 a21, 2 a12, 6 a03): constant
};

SFFD_HD Power power_of(const float* cp) {
  Power p;
  double b[3][10], a[3][10];
  for (int k = 0; k < 10; ++k)
    for (int r = 0; r < 3; ++r) b[r][k] = cp[3 * k + r];
  for (int r = 0; r < 3; ++r) cubic_power_form<double>(b[r], a[r]);
  for (int k = 0; k < 10; ++k) p.a[k] = {a[0][k], a[1][k], a[2][k]};
  p.t[0] = 6.0 * p.a[kA30];
  p.t[1] = 2.0 * p.a[kA21];
  p.t[2] = 2.0 * p.a[kA12];
  p.t[3] = 6.0 * p.a[kA03];
  return p;
}

// D2f at (s, t) applied to w twice.
SFFD_HD D3 second(const Power& p, const double st[2], const double w[2]) {
  const double s = st[0], t = st[1];
  const D3 fss = 2.0 * p.a[kA20] + (6.0 * s) * p.a[kA30] + (2.0 * t) * p.a[kA21];
  const D3 fst = p.a[kA11] + (2.0 * s) * p.a[kA21] + (2.0 * t) * p.a[kA12];
  const D3 ftt = 2.0 * p.a[kA02] + (2.0 * s) * p.a[kA12] + (6.0 * t) * p.a[kA03];
  return (w[0] * w[0]) * fss + (2.0 * w[0] * w[1]) * fst + (w[1] * w[1]) * ftt;
}

SFFD_HD double norm2(D3 a) { return a.x * a.x + a.y * a.y + a.z * a.z; }

// tau: the largest |D3f[a, b, c]| over edges a, b, c of e[0..2] (D3f is constant for a cubic).
SFFD_HD double third_bound(const Power& p, const double e[3][2]) {
  double worst = 0;
  for (int i = 0; i < 3; ++i)
    for (int j = i; j < 3; ++j)
      for (int k = j; k < 3; ++k) {
        const double *u = e[i], *v = e[j], *w = e[k];
        const D3 d = (u[0] * v[0] * w[0]) * p.t[0] + (u[0] * v[0] * w[1] + u[0] * v[1] * w[0] + u[1] * v[0] * w[0]) * p.t[1] +
                     (u[0] * v[1] * w[1] + u[1] * v[0] * w[1] + u[1] * v[1] * w[0]) * p.t[2] +
                     (u[1] * v[1] * w[1]) * p.t[3];
        worst = amax(worst, norm2(d));
      }
  return sqrt(worst);
}

// max over the simplex of q01 l0 l1 + q02 l0 l2 + q12 l1 l2 (q >= 0): an edge's midpoint or the
// stationary point inside (where it exists: for squared edge lengths, the circumcentre).
SFFD_HD double simplex_max(double q01, double q02, double q12) {
  double best = 0.25 * amax(q01, amax(q02, q12));
  const double l0 = q12 * (q01 + q02 - q12), l1 = q02 * (q01 + q12 - q02), l2 = q01 * (q02 + q12 - q01);
  const double sum = l0 + l1 + l2;
  if (l0 > 0 && l1 > 0 && l2 > 0 && sum > 0) {
    const double a = l0 / sum, b = l1 / sum, c = l2 / sum;
    best = amax(best, q01 * a * b + q02 * a * c + q12 * b * c);
  }
  return best;
}

// The bound for a triangle with edges e[0] = v1 - v0, e[1] = v2 - v0, e[2] = v2 - v1, the
// second derivatives bounded over the parameter points region[0..n).
SFFD_HD double bound_core(const Power& p, const double e[3][2], const double (*region)[2], int n) {
  double q[3];
  for (int k = 0; k < 3; ++k) {
    q[k] = 0;
    for (int r = 0; r < n; ++r) q[k] = amax(q[k], norm(second(p, region[r], e[k])));
  }
  return 0.5 * simplex_max(q[0], q[1], q[2]) + 0.05 * third_bound(p, e);
}

// For a triangle the second derivative along edge ij is bounded where it is used: at x,
// |D2f(x)[e_ij]| <= sum_k l_k |D2f(v_k)[e_ij]| <= A_ij + l_k B_ij, A_ij the larger value at the
// edge's own ends, B_ij what the third corner k adds. So the first term is at most
// 1/2 (simplex_max(A) + l0 l1 l2 sum B) <= 1/2 (simplex_max(A) + sum B / 27): a long edge of a
// thin triangle is charged its own ends' curvature, not the far corner's (the strips' triangles
// on a long, straight edge segment next to a curved interior).
SFFD_HD double triangle_bound_p(const Power& p, const double st[3][2]) {
  const int ends[3][3] = {{0, 1, 2}, {0, 2, 1}, {1, 2, 0}};  // i, j, k of edges e[0..2]
  double e[3][2], A[3], B = 0;
  for (int q = 0; q < 3; ++q) {
    const int i = ends[q][0], j = ends[q][1], k = ends[q][2];
    e[q][0] = st[j][0] - st[i][0];
    e[q][1] = st[j][1] - st[i][1];
    A[q] = amax(norm(second(p, st[i], e[q])), norm(second(p, st[j], e[q])));
    B += fmax(0.0, norm(second(p, st[k], e[q])) - A[q]);
  }
  return 0.5 * (simplex_max(A[0], A[1], A[2]) + B / 27.0) + 0.05 * third_bound(p, e);
}

SFFD_HD double uniform_bound_p(const Power& p, int m) {
  const double h = 1.0 / m;
  const double e[3][2] = {{h, 0}, {0, h}, {-h, h}};
  const double corners[3][2] = {{0, 0}, {1, 0}, {0, 1}};
  return bound_core(p, e, corners, 3);
}

// Edge bound with the same constants as a strip triangle's that shrinks onto the edge: the
// chord error is at most h^2/8 max|c''| + 0.05 max|D3 on edge vectors|, h = 1/n, c'' at most 6
// times the larger second difference, c''' = 6 times the third difference.
SFFD_HD double edge_bound_d(const D3 b[4], int n) {
  const D3 d2a = b[0] + (-2.0) * b[1] + b[2], d2b = b[1] + (-2.0) * b[2] + b[3];
  const D3 d3 = b[3] + (-3.0) * b[2] + 3.0 * b[1] + (-1.0) * b[0];
  const double h = 1.0 / n;
  return 0.75 * h * h * amax(norm(d2a), norm(d2b)) + 0.3 * h * h * h * norm(d3);
}

// Edges aim below the tolerance so that a strip triangle on a long edge segment, whose bound
// tends to the edge's as the interior level grows, meets it at a moderate level.
constexpr double kEdgeShare = 0.5;

SFFD_HD int edge_count(const D3 b[4], int at_least, double tol, int max_level, double& bound) {
  int n = amin(at_least, max_level);
  while (n < max_level && edge_bound_d(b, n) > kEdgeShare * tol) {
    // Jump close to the answer from the second-difference term, then step.
    const double d = edge_bound_d(b, n) / (kEdgeShare * tol);
    n = amax(n + 1, (int)fmin((double)max_level, floor(n * sqrt(d) * 0.9)));
    while (n > at_least && edge_bound_d(b, n - 1) <= kEdgeShare * tol) --n;
  }
  bound = edge_bound_d(b, n);
  return n;
}

// ---------------------------------------------------------------------------------------------
// Patterns. A local point of a patch: a corner, an inner point of one of its edges (step along
// the patch edge k from corner k), or an interior point (i, j) of the level-m grid (barycentric
// ((m - i - j)/m, i/m, j/m), all three at least 1/m).
struct LocalPoint {
  unsigned char kind;  // 0 corner, 1 edge, 2 interior
  unsigned char k;     // corner or patch edge
  int i, j;            // edge: step i of n; interior: (i, j)
};

struct PatchShape {
  int n[3];  // segments of patch edge k (corner k -> k+1)
  int m;     // interior level
  bool uniform;
};

SFFD_HD void barycentric(const PatchShape& sh, const LocalPoint& q, double b[3]) {
  b[0] = b[1] = b[2] = 0;
  if (q.kind == 0) {
    b[q.k] = 1;
  } else if (q.kind == 1) {
    const double u = (double)q.i / sh.n[q.k];
    b[q.k] = 1 - u;
    b[(q.k + 1) % 3] = u;
  } else {
    b[1] = (double)q.i / sh.m;
    b[2] = (double)q.j / sh.m;
    b[0] = (double)(sh.m - q.i - q.j) / sh.m;
  }
}

// Outer point i (0..n) of side k, inner point r (0..m-3) of side k.
SFFD_HD LocalPoint outer_point(const PatchShape& sh, int k, int i) {
  if (i == 0) return {0, (unsigned char)k, 0, 0};
  if (i == sh.n[k]) return {0, (unsigned char)((k + 1) % 3), 0, 0};
  return {1, (unsigned char)k, i, 0};
}
SFFD_HD LocalPoint inner_point(const PatchShape& sh, int k, int r) {
  const int m = sh.m;
  if (k == 0) return {2, 0, r + 1, 1};
  if (k == 1) return {2, 0, m - 2 - r, r + 1};
  return {2, 0, 1, m - 2 - r};
}

// Grid point (i, j) of the uniform level-m pattern as a local point.
SFFD_HD LocalPoint grid_point(int m, int i, int j) {
  if (i == 0 && j == 0) return {0, 0, 0, 0};
  if (i == m) return {0, 1, 0, 0};
  if (j == m) return {0, 2, 0, 0};
  if (j == 0) return {1, 0, i, 0};
  if (i + j == m) return {1, 1, j, 0};
  if (i == 0) return {1, 2, m - j, 0};
  return {2, 0, i, j};
}

SFFD_HD long long interior_points(int m) { return m >= 3 ? (long long)(m - 1) * (m - 2) / 2 : 0; }

SFFD_HD long long triangle_count(const PatchShape& sh) {
  if (sh.uniform) return (long long)sh.m * sh.m;
  const long long r = sh.m - 3;
  return r * r + sh.n[0] + sh.n[1] + sh.n[2] + 3 * r;
}

// Whether corner k of a non-uniform pattern is cut off by the triangle of its two nearest edge
// points (as in the uniform grid) instead of joined to the inner corner: when both edges have
// inner points and that triangle leaves the inner corner (1/m from both edges) outside, which
// holds when n_k + n_(k-1) > m.
SFFD_HD bool cut_corner(const PatchShape& sh, int k) {
  const int a = sh.n[k], b = sh.n[(k + 2) % 3];
  return a >= 2 && b >= 2 && a + b > sh.m;
}

// The strips of a non-uniform pattern, one a side, and its corners. Side k zips its outer
// points (at i/n along it; without a corner that is cut off) with its inner points (at
// (r + 1)/m) in order of that parameter (an integer comparison: the same on every machine).
template <class Emit>
SFFD_HD void for_each_strip_triangle(const PatchShape& sh, Emit&& emit) {
  const int m = sh.m, last = m - 3;
  for (int k = 0; k < 3; ++k) {
    const int n = sh.n[k];
    if (cut_corner(sh, k)) {
      const int prev = (k + 2) % 3;
      const LocalPoint a = outer_point(sh, prev, sh.n[prev] - 1), b = outer_point(sh, k, 1);
      emit(outer_point(sh, k, 0), b, a);
      emit(b, inner_point(sh, k, 0), a);
    }
    int i = cut_corner(sh, k) ? 1 : 0, r = 0;
    const int end = cut_corner(sh, (k + 1) % 3) ? n - 1 : n;
    while (i < end || r < last) {
      if (r == last || (i < end && (long long)(i + 1) * m <= (long long)(r + 2) * n)) {
        emit(outer_point(sh, k, i), outer_point(sh, k, i + 1), inner_point(sh, k, r));
        ++i;
      } else {
        emit(outer_point(sh, k, i), inner_point(sh, k, r + 1), inner_point(sh, k, r));
        ++r;
      }
    }
  }
}

// Every triangle of the pattern, in order, to emit(a, b, c) (counter-clockwise as the
// uniform tessellation's).
template <class Emit>
SFFD_HD void for_each_triangle(const PatchShape& sh, Emit&& emit) {
  const int m = sh.m;
  if (sh.uniform) {
    for (int j = 0; j < m; ++j)
      for (int i = 0; i < m - j; ++i) {
        emit(grid_point(m, i, j), grid_point(m, i + 1, j), grid_point(m, i, j + 1));
        if (i + j < m - 1) emit(grid_point(m, i + 1, j), grid_point(m, i + 1, j + 1), grid_point(m, i, j + 1));
      }
    return;
  }
  // The inner grid: the level-m triangles whose corners are all interior points.
  for (int j = 1; j <= m - 3; ++j)
    for (int i = 1; i + j <= m - 2; ++i) {
      emit(LocalPoint{2, 0, i, j}, LocalPoint{2, 0, i + 1, j}, LocalPoint{2, 0, i, j + 1});
      if (i + j <= m - 3)
        emit(LocalPoint{2, 0, i + 1, j}, LocalPoint{2, 0, i + 1, j + 1}, LocalPoint{2, 0, i, j + 1});
    }
  for_each_strip_triangle(sh, emit);
}

// The largest strip triangle bound of the pattern, or the first one above `stop` (its inner
// grid is within uniform_bound).
SFFD_HD double strip_bound(const Power& p, const PatchShape& sh, double stop) {
  double worst = 0;
  for_each_strip_triangle(sh, [&](const LocalPoint& a, const LocalPoint& b, const LocalPoint& c) {
    if (worst > stop) return;
    const LocalPoint t[3] = {a, b, c};
    double st[3][2];
    for (int k = 0; k < 3; ++k) {
      double w[3];
      barycentric(sh, t[k], w);
      st[k][0] = w[1];
      st[k][1] = w[2];
    }
    worst = amax(worst, triangle_bound_p(p, st));
  });
  return worst;
}

// The smallest level m (at most max_level) whose uniform grid is within tol of the patch.
SFFD_HD int uniform_level(const Power& p, double tol, int max_level) {
  int m = 1;
  while (m < max_level && uniform_bound_p(p, m) > tol) {
    const double d = uniform_bound_p(p, m) / tol;
    m = amax(m + 1, (int)fmin((double)max_level, floor(m * sqrt(d) * 0.9)));
    while (m > 1 && uniform_bound_p(p, m - 1) <= tol) --m;
  }
  return m;
}

// The pattern of a patch of uniform level m0 whose edges have n[0..2] segments: the uniform grid
// when they all have m0, else strips around the level-m grid's interior, m from max(m0, 3) up
// until every strip triangle is within tol (or m reaches max_level).
SFFD_HD PatchShape patch_shape(const Power& p, int m0, const int n[3], double tol, int max_level, bool held,
                       double& bound) {
  PatchShape sh;
  for (int k = 0; k < 3; ++k) sh.n[k] = n[k];
  sh.uniform = false;
  if (held) max_level = amin(max_level, m0);  // exactly m0 (or 3, the least strip level)
  for (sh.m = n[0] == m0 && n[1] == m0 && n[2] == m0 ? m0 : amax(m0, 3);; ++sh.m) {
    if (n[0] == sh.m && n[1] == sh.m && n[2] == sh.m) {
      sh.uniform = true;
      bound = uniform_bound_p(p, sh.m);
      return sh;
    }
    const bool last = sh.m >= amax(max_level, 3);
    const double b = amax(strip_bound(p, sh, last ? HUGE_VAL : tol), uniform_bound_p(p, sh.m));
    if (b <= tol || last) {
      bound = b;
      return sh;
    }
  }
}


// ---------------------------------------------------------------------------------------------
// Per element, for both drivers: the frame's reference buffers and the decisions' arrays.
struct AdaptiveView {
  // reference patches (the shared scalar stages, stages.hpp)
  const float* value;          // S x 3 (the sub-vertices first)
  const float* edge_control;   // E x 6
  const float* patch_control;  // P x 30
  const float* patch_normal;   // P x 30
  // decisions
  int* level0;                 // P: uniform level
  int* segments;               // E
  int* patch_m;                // P
  unsigned char* patch_uniform;  // P
  double* edge_bound;          // E
  double* patch_bound;         // P
  const int* min_edge_segments;  // E or null (held counts)
  const int* min_patch_level;    // P or null
  double tolerance;
  int max_level;
  // offsets (exclusive scans): edge points, interior points (both from the first output
  // vertex after the sub-vertices... absolute output vertex numbers), triangles
  const long long* edge_base;   // E: first output vertex of edge e's inner points
  const long long* patch_base;  // P: first output vertex of patch p's interior points
  const long long* tri_base;    // P: first triangle of patch p
  // emitted
  float* positions;       // N x 3
  float* rest_positions;  // N x 3
  int* triangles;         // T x 3
  int* face_index;        // T
  int* triangle_patch;    // T
  float* corner_normals;  // T x 9 or null
  float* uvs;             // T x 6 or null
  float* corner_bary;     // T x 9 or null (tests)
  // plan tables the emission reads beyond the PlanView
  const float* rest;                 // rest positions, the sub-vertices first
  const int* patch_face;             // P
  const int* patch_triangle;         // P
  const double* patch_bary;          // P x 9
  const int* input_triangle_corner;  // Tin x 3
  const float* corner_uv;            // C x 2 or null
};

SFFD_HD void edge_curve(const PlanView& pv, const AdaptiveView& av, int e, D3 b[4]) {
  const float* pa = av.value + 3 * (long long)pv.edge_vertex[2 * e];
  const float* pb = av.value + 3 * (long long)pv.edge_vertex[2 * e + 1];
  const float* c = av.edge_control + 6 * (long long)e;
  b[0] = D3{pa[0], pa[1], pa[2]};
  b[1] = D3{c[0], c[1], c[2]};
  b[2] = D3{c[3], c[4], c[5]};
  b[3] = D3{pb[0], pb[1], pb[2]};
}

// Patch p's uniform level (its own: a held level raises its pattern, not its edges).
SFFD_HD void decide_level(const AdaptiveView& av, int p) {
  av.level0[p] = uniform_level(power_of(av.patch_control + 30 * (long long)p), av.tolerance, av.max_level);
}

// Edge e's count: enough for its own cubic and at least the uniform level of each patch on it
// (so that no strip triangle along a straight edge reaches into a curved interior with a long
// side), and at least its held count.
SFFD_HD void decide_edge(const PlanView& pv, const AdaptiveView& av, int e) {
  D3 c[4];
  edge_curve(pv, av, e, c);
  int at_least = av.level0[pv.edge_patch[2 * e]];
  if (pv.edge_patch[2 * e + 1] >= 0) at_least = amax(at_least, av.level0[pv.edge_patch[2 * e + 1]]);
  if (av.min_edge_segments) at_least = amax(at_least, av.min_edge_segments[e]);
  av.segments[e] = edge_count(c, at_least, av.tolerance, av.max_level, av.edge_bound[e]);
}

SFFD_HD PatchShape shape_of(const PlanView& pv, const AdaptiveView& av, int p) {
  PatchShape sh;
  for (int k = 0; k < 3; ++k) sh.n[k] = av.segments[pv.patch_edge[3 * p + k]];
  sh.m = av.patch_m[p];
  sh.uniform = av.patch_uniform[p] != 0;
  return sh;
}

SFFD_HD void decide_pattern(const PlanView& pv, const AdaptiveView& av, int p) {
  int n[3];
  for (int k = 0; k < 3; ++k) n[k] = av.segments[pv.patch_edge[3 * p + k]];
  int m0 = av.level0[p];
  if (av.min_patch_level) m0 = amax(m0, amin(av.min_patch_level[p], av.max_level));
  const PatchShape sh = patch_shape(power_of(av.patch_control + 30 * (long long)p), m0, n, av.tolerance, av.max_level,
                                    av.min_patch_level != nullptr, av.patch_bound[p]);
  av.patch_m[p] = sh.m;
  av.patch_uniform[p] = sh.uniform ? 1 : 0;
}

// Edge e's inner points, from its own cubic, and their rest positions.
SFFD_HD void emit_edge(const PlanView& pv, const AdaptiveView& av, int e) {
  D3 c[4];
  edge_curve(pv, av, e, c);
  const int n = av.segments[e];
  const float* ra = av.rest + 3 * (long long)pv.edge_vertex[2 * e];
  const float* rb = av.rest + 3 * (long long)pv.edge_vertex[2 * e + 1];
  for (int s = 1; s < n; ++s) {
    const float u = (float)s / (float)n, w = 1.0f - u;
    const float B[4] = {w * w * w, 3.0f * u * w * w, 3.0f * u * u * w, u * u * u};
    const long long o = av.edge_base[e] + s - 1;
    const double* cc[4] = {&c[0].x, &c[1].x, &c[2].x, &c[3].x};
    for (int r = 0; r < 3; ++r) {
      float acc = 0.0f;
      for (int k = 0; k < 4; ++k) acc += B[k] * (float)cc[k][r];
      av.positions[3 * o + r] = acc;
      av.rest_positions[3 * o + r] = w * ra[r] + u * rb[r];
    }
  }
}

// Patch p's interior points, then its triangles with their corners' normals, UVs, input face.
SFFD_HD void emit_patch(const PlanView& pv, const AdaptiveView& av, int p) {
  const PatchShape sh = shape_of(pv, av, p);
  const float* cp = av.patch_control + 30 * (long long)p;
  const float* np = av.patch_normal + 30 * (long long)p;
  const int* cv = pv.patch_vertex + 3 * (long long)p;
  const long long base = av.patch_base[p];
  for (int j = 1; j <= sh.m - 2; ++j)
    for (int i = 1; i + j <= sh.m - 1; ++i) {
      const long long o = base + (long long)(j - 1) * (sh.m - 1) - (long long)(j - 1) * j / 2 + (i - 1);
      const float bb[3] = {(float)(sh.m - i - j) / sh.m, (float)i / sh.m, (float)j / sh.m};
      float B[10];
      cubic_basis<float>(bb, B);
      store3(av.positions + 3 * o, eval_cubic(B, cp));
      for (int r = 0; r < 3; ++r)
        av.rest_positions[3 * o + r] = bb[0] * av.rest[3 * (long long)cv[0] + r] + bb[1] * av.rest[3 * (long long)cv[1] + r] +
                                       bb[2] * av.rest[3 * (long long)cv[2] + r];
    }
  long long t = av.tri_base[p];
  const int tri = av.patch_triangle[p];
  const double* pb = av.patch_bary + 9 * (long long)p;
  for_each_triangle(sh, [&](const LocalPoint& a, const LocalPoint& b, const LocalPoint& c) {
    const LocalPoint q[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
      long long g;
      if (q[k].kind == 0) {
        g = cv[q[k].k];
      } else if (q[k].kind == 1) {
        const int e = pv.patch_edge[3 * p + q[k].k];
        const int s = pv.patch_edge_reversed[3 * p + q[k].k] ? sh.n[q[k].k] - q[k].i : q[k].i;
        g = av.edge_base[e] + s - 1;
      } else {
        g = base + (long long)(q[k].j - 1) * (sh.m - 1) - (long long)(q[k].j - 1) * q[k].j / 2 + (q[k].i - 1);
      }
      av.triangles[3 * t + k] = (int)g;
      if (!av.corner_normals && !av.uvs && !av.corner_bary) continue;
      double bd[3];
      barycentric(sh, q[k], bd);
      if (av.corner_bary)
        for (int r = 0; r < 3; ++r) av.corner_bary[9 * t + 3 * k + r] = (float)bd[r];
      if (av.corner_normals) {
        const float bf[3] = {(float)bd[0], (float)bd[1], (float)bd[2]};
        float B[10];
        cubic_basis<float>(bf, B);
        store3(av.corner_normals + 9 * t + 3 * k, unit_patch_normal(eval_cubic(B, np), np));
      }
      if (av.uvs) {
        double ib[3] = {0, 0, 0};  // the barycentric point on the input triangle
        for (int c2 = 0; c2 < 3; ++c2)
          for (int r = 0; r < 3; ++r) ib[r] += bd[c2] * pb[3 * c2 + r];
        for (int r = 0; r < 2; ++r) {
          double u = 0;
          for (int c2 = 0; c2 < 3; ++c2)
            u += ib[c2] * av.corner_uv[2 * (long long)av.input_triangle_corner[3 * tri + c2] + r];
          av.uvs[6 * t + 2 * k + r] = (float)u;
        }
      }
    }
    av.face_index[t] = av.patch_face[p];
    av.triangle_patch[t] = p;
    ++t;
  });
}

}  // namespace adapt
}  // namespace sffd
