#include "smoothffd/eval/adaptive.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/eval/stages.hpp"
#include "smoothffd/plan/bezier.hpp"

namespace sffd {

namespace {

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
// over edges a, b, c of the triangle, and sum l_i (1 - l_i)^3 <= 0.3 on the simplex: the second
// term is at most 0.05 tau.

struct D3 {
  double x, y, z;
};
D3 operator+(D3 a, D3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
D3 operator*(double s, D3 a) { return {s * a.x, s * a.y, s * a.z}; }
double norm(D3 a) { return std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z); }

struct Power {
  D3 a[10];  // CubicPowerTerm order
};

Power power_of(const float* cp) {
  Power p;
  double b[3][10], a[3][10];
  for (int k = 0; k < 10; ++k)
    for (int r = 0; r < 3; ++r) b[r][k] = cp[3 * k + r];
  for (int r = 0; r < 3; ++r) cubic_power_form<double>(b[r], a[r]);
  for (int k = 0; k < 10; ++k) p.a[k] = {a[0][k], a[1][k], a[2][k]};
  return p;
}

// D2f at (s, t) applied to w twice.
D3 second(const Power& p, const double st[2], const double w[2]) {
  const double s = st[0], t = st[1];
  const D3 fss = 2.0 * p.a[kA20] + (6.0 * s) * p.a[kA30] + (2.0 * t) * p.a[kA21];
  const D3 fst = p.a[kA11] + (2.0 * s) * p.a[kA21] + (2.0 * t) * p.a[kA12];
  const D3 ftt = 2.0 * p.a[kA02] + (2.0 * s) * p.a[kA12] + (6.0 * t) * p.a[kA03];
  return (w[0] * w[0]) * fss + (2.0 * w[0] * w[1]) * fst + (w[1] * w[1]) * ftt;
}

// D3f[u, v, w] (constant for a cubic).
D3 third(const Power& p, const double u[2], const double v[2], const double w[2]) {
  const D3 sss = 6.0 * p.a[kA30], sst = 2.0 * p.a[kA21], stt = 2.0 * p.a[kA12], ttt = 6.0 * p.a[kA03];
  return (u[0] * v[0] * w[0]) * sss + (u[0] * v[0] * w[1] + u[0] * v[1] * w[0] + u[1] * v[0] * w[0]) * sst +
         (u[0] * v[1] * w[1] + u[1] * v[0] * w[1] + u[1] * v[1] * w[0]) * stt + (u[1] * v[1] * w[1]) * ttt;
}

// max over the simplex of q01 l0 l1 + q02 l0 l2 + q12 l1 l2 (q >= 0): an edge's midpoint or the
// stationary point inside (where it exists: for squared edge lengths, the circumcentre).
double simplex_max(double q01, double q02, double q12) {
  double best = 0.25 * std::max(q01, std::max(q02, q12));
  const double l0 = q12 * (q01 + q02 - q12), l1 = q02 * (q01 + q12 - q02), l2 = q01 * (q02 + q12 - q01);
  const double sum = l0 + l1 + l2;
  if (l0 > 0 && l1 > 0 && l2 > 0 && sum > 0) {
    const double a = l0 / sum, b = l1 / sum, c = l2 / sum;
    best = std::max(best, q01 * a * b + q02 * a * c + q12 * b * c);
  }
  return best;
}

// The bound for a triangle with edges e[0] = v1 - v0, e[1] = v2 - v0, e[2] = v2 - v1, the
// second derivatives bounded over the parameter points region[0..n).
double bound_core(const Power& p, const double e[3][2], const double (*region)[2], int n) {
  double q[3];
  for (int k = 0; k < 3; ++k) {
    q[k] = 0;
    for (int r = 0; r < n; ++r) q[k] = std::max(q[k], norm(second(p, region[r], e[k])));
  }
  double tau = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b)
      for (int c = b; c < 3; ++c) tau = std::max(tau, norm(third(p, e[a], e[b], e[c])));
  return 0.5 * simplex_max(q[0], q[1], q[2]) + 0.05 * tau;
}

// For a triangle the second derivative along edge ij is bounded where it is used: at x,
// |D2f(x)[e_ij]| <= sum_k l_k |D2f(v_k)[e_ij]| <= A_ij + l_k B_ij, A_ij the larger value at the
// edge's own ends, B_ij what the third corner k adds. So the first term is at most
// 1/2 (simplex_max(A) + l0 l1 l2 sum B) <= 1/2 (simplex_max(A) + sum B / 27): a long edge of a
// thin triangle is charged its own ends' curvature, not the far corner's (the strips' triangles
// on a long, straight edge segment next to a curved interior).
double triangle_bound_p(const Power& p, const double st[3][2]) {
  const int ends[3][3] = {{0, 1, 2}, {0, 2, 1}, {1, 2, 0}};  // i, j, k of edges e[0..2]
  double e[3][2], A[3], B = 0;
  for (int q = 0; q < 3; ++q) {
    const int i = ends[q][0], j = ends[q][1], k = ends[q][2];
    e[q][0] = st[j][0] - st[i][0];
    e[q][1] = st[j][1] - st[i][1];
    A[q] = std::max(norm(second(p, st[i], e[q])), norm(second(p, st[j], e[q])));
    B += std::max(0.0, norm(second(p, st[k], e[q])) - A[q]);
  }
  double tau = 0;
  for (int a = 0; a < 3; ++a)
    for (int b = a; b < 3; ++b)
      for (int c = b; c < 3; ++c) tau = std::max(tau, norm(third(p, e[a], e[b], e[c])));
  return 0.5 * (simplex_max(A[0], A[1], A[2]) + B / 27.0) + 0.05 * tau;
}

const double kPatchCorners[3][2] = {{0, 0}, {1, 0}, {0, 1}};

double uniform_bound_p(const Power& p, int m) {
  const double h = 1.0 / m;
  const double e[3][2] = {{h, 0}, {0, h}, {-h, h}};
  return bound_core(p, e, kPatchCorners, 3);
}

// Edge bound with the same constants as a strip triangle's that shrinks onto the edge: the
// chord error is at most h^2/8 max|c''| + 0.05 max|D3 on edge vectors|, h = 1/n, c'' at most 6
// times the larger second difference, c''' = 6 times the third difference.
double edge_bound_d(const D3 b[4], int n) {
  const D3 d2a = b[0] + (-2.0) * b[1] + b[2], d2b = b[1] + (-2.0) * b[2] + b[3];
  const D3 d3 = b[3] + (-3.0) * b[2] + 3.0 * b[1] + (-1.0) * b[0];
  const double h = 1.0 / n;
  return 0.75 * h * h * std::max(norm(d2a), norm(d2b)) + 0.3 * h * h * h * norm(d3);
}

// Edges aim below the tolerance so that a strip triangle on a long edge segment, whose bound
// tends to the edge's as the interior level grows, meets it at a moderate level.
constexpr double kEdgeShare = 0.5;

int edge_count(const D3 b[4], int at_least, double tol, int max_level, double& bound) {
  int n = std::min(at_least, max_level);
  while (n < max_level && edge_bound_d(b, n) > kEdgeShare * tol) {
    // Jump close to the answer from the second-difference term, then step.
    const double d = edge_bound_d(b, n) / (kEdgeShare * tol);
    n = std::max(n + 1, (int)std::min<double>(max_level, std::floor(n * std::sqrt(d) * 0.9)));
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

void barycentric(const PatchShape& sh, const LocalPoint& q, double b[3]) {
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
LocalPoint outer_point(const PatchShape& sh, int k, int i) {
  if (i == 0) return {0, (unsigned char)k, 0, 0};
  if (i == sh.n[k]) return {0, (unsigned char)((k + 1) % 3), 0, 0};
  return {1, (unsigned char)k, i, 0};
}
LocalPoint inner_point(const PatchShape& sh, int k, int r) {
  const int m = sh.m;
  if (k == 0) return {2, 0, r + 1, 1};
  if (k == 1) return {2, 0, m - 2 - r, r + 1};
  return {2, 0, 1, m - 2 - r};
}

// Grid point (i, j) of the uniform level-m pattern as a local point.
LocalPoint grid_point(int m, int i, int j) {
  if (i == 0 && j == 0) return {0, 0, 0, 0};
  if (i == m) return {0, 1, 0, 0};
  if (j == m) return {0, 2, 0, 0};
  if (j == 0) return {1, 0, i, 0};
  if (i + j == m) return {1, 1, j, 0};
  if (i == 0) return {1, 2, m - j, 0};
  return {2, 0, i, j};
}

long long interior_points(int m) { return m >= 3 ? (long long)(m - 1) * (m - 2) / 2 : 0; }

long long triangle_count(const PatchShape& sh) {
  if (sh.uniform) return (long long)sh.m * sh.m;
  const long long r = sh.m - 3;
  return r * r + sh.n[0] + sh.n[1] + sh.n[2] + 3 * r;
}

// Whether corner k of a non-uniform pattern is cut off by the triangle of its two nearest edge
// points (as in the uniform grid) instead of joined to the inner corner: when both edges have
// inner points and that triangle leaves the inner corner (1/m from both edges) outside, which
// holds when n_k + n_(k-1) > m.
bool cut_corner(const PatchShape& sh, int k) {
  const int a = sh.n[k], b = sh.n[(k + 2) % 3];
  return a >= 2 && b >= 2 && a + b > sh.m;
}

// The strips of a non-uniform pattern, one a side, and its corners. Side k zips its outer
// points (at i/n along it; without a corner that is cut off) with its inner points (at
// (r + 1)/m) in order of that parameter (an integer comparison: the same on every machine).
template <class Emit>
void for_each_strip_triangle(const PatchShape& sh, Emit&& emit) {
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
void for_each_triangle(const PatchShape& sh, Emit&& emit) {
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

// The largest strip triangle bound of the pattern (its inner grid is within uniform_bound).
double strip_bound(const Power& p, const PatchShape& sh) {
  double worst = 0;
  for_each_strip_triangle(sh, [&](const LocalPoint& a, const LocalPoint& b, const LocalPoint& c) {
    const LocalPoint t[3] = {a, b, c};
    double st[3][2];
    for (int k = 0; k < 3; ++k) {
      double w[3];
      barycentric(sh, t[k], w);
      st[k][0] = w[1];
      st[k][1] = w[2];
    }
    worst = std::max(worst, triangle_bound_p(p, st));
  });
  return worst;
}

// The smallest level m (at most max_level) whose uniform grid is within tol of the patch.
int uniform_level(const Power& p, double tol, int max_level) {
  int m = 1;
  while (m < max_level && uniform_bound_p(p, m) > tol) {
    const double d = uniform_bound_p(p, m) / tol;
    m = std::max(m + 1, (int)std::min<double>(max_level, std::floor(m * std::sqrt(d) * 0.9)));
    while (m > 1 && uniform_bound_p(p, m - 1) <= tol) --m;
  }
  return m;
}

// The pattern of a patch of uniform level m0 whose edges have n[0..2] segments: the uniform grid
// when they all have m0, else strips around the level-m grid's interior, m from max(m0, 3) up
// until every strip triangle is within tol (or m reaches max_level).
PatchShape patch_shape(const Power& p, int m0, const int n[3], double tol, int max_level, bool held,
                       double& bound) {
  PatchShape sh;
  for (int k = 0; k < 3; ++k) sh.n[k] = n[k];
  sh.uniform = false;
  if (held) max_level = std::min(max_level, m0);  // exactly m0 (or 3, the least strip level)
  for (sh.m = n[0] == m0 && n[1] == m0 && n[2] == m0 ? m0 : std::max(m0, 3);; ++sh.m) {
    if (n[0] == sh.m && n[1] == sh.m && n[2] == sh.m) {
      sh.uniform = true;
      bound = uniform_bound_p(p, sh.m);
      return sh;
    }
    const double b = std::max(strip_bound(p, sh), uniform_bound_p(p, sh.m));
    if (b <= tol || sh.m >= std::max(max_level, 3)) {
      bound = b;
      return sh;
    }
  }
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

std::vector<double> adaptive_pattern(const int n[3], int m) {
  PatchShape sh;
  for (int k = 0; k < 3; ++k) sh.n[k] = n[k];
  sh.m = m;
  sh.uniform = n[0] == m && n[1] == m && n[2] == m;
  if (!sh.uniform && m < 3) throw std::invalid_argument("adaptive_pattern: m >= 3 unless every n is m");
  std::vector<double> out;
  for_each_triangle(sh, [&](const LocalPoint& a, const LocalPoint& b, const LocalPoint& c) {
    for (const LocalPoint* q : {&a, &b, &c}) {
      double w[3];
      barycentric(sh, *q, w);
      out.insert(out.end(), w, w + 3);
    }
  });
  return out;
}

double triangle_bound(const float* cp, const double st[3][2]) { return triangle_bound_p(power_of(cp), st); }
double uniform_bound(const float* cp, int m) { return uniform_bound_p(power_of(cp), m); }
double edge_bound(const float* b0, const float* b1, const float* b2, const float* b3, int n) {
  const float* b[4] = {b0, b1, b2, b3};
  D3 d[4];
  for (int k = 0; k < 4; ++k) d[k] = {b[k][0], b[k][1], b[k][2]};
  return edge_bound_d(d, n);
}

AdaptiveMesh adaptive_frame(const Plan& plan, const float* D, const float* corner_uv, const AdaptiveOptions& o) {
  if (!(o.tolerance > 0) || !std::isfinite(o.tolerance))
    throw std::invalid_argument("tolerance: expected a positive finite distance, got " + std::to_string(o.tolerance));
  if (o.max_level < 1 || o.max_level > kMaxLevel)
    throw std::invalid_argument("max_level: expected 1.." + std::to_string(kMaxLevel) + ", got " +
                                std::to_string(o.max_level));
  const int threads = o.threads > 0 ? o.threads : default_threads();
  const PlanView pv = host_view(plan);
  const int S = plan.samples, E = plan.edges, P = plan.patches, SV = plan.sub_vertices;
  const double tol = o.tolerance;
  AdaptiveMesh out;

  // 1. Reference patches: the shared scalar stages, one element at a time.
  auto t0 = std::chrono::steady_clock::now();
  std::vector<float> value(3 * (size_t)S), jacobian(9 * (size_t)S), edge_control(6 * (size_t)E),
      patch_control(30 * (size_t)P), patch_normal(30 * (size_t)P);
  FrameView fv{};
  fv.sample_value = value.data();
  fv.sample_jacobian = jacobian.data();
  fv.edge_control = edge_control.data();
  fv.patch_control = patch_control.data();
  fv.patch_normal = patch_normal.data();
  parallel_for(S, threads, [&](long long b, long long e) {
    for (long long s = b; s < e; ++s) sample_point(pv, D, (int)s, &value[3 * s], &jacobian[9 * s]);
  });
  parallel_for(E, threads, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) adjust_edge(pv, fv, (int)i);
  });
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) fit_patch_into(pv, fv, (int)p, &patch_control[30 * p], &patch_normal[30 * p]);
  });
  out.times.emplace_back("reference patches", ms_since(t0));

  // 2. Each patch's uniform level, then each edge's count: enough for its own cubic and at
  // least the uniform level of each patch on it (so that no strip triangle along a straight
  // edge reaches into a curved interior with a long side).
  t0 = std::chrono::steady_clock::now();
  std::vector<int> level0(P);
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) {
      level0[p] = uniform_level(power_of(&patch_control[30 * p]), tol, o.max_level);
      if (o.min_patch_level) level0[p] = std::max(level0[p], std::min(o.min_patch_level[p], o.max_level));
    }
  });
  auto edge_curve = [&](int e, D3 b[4]) {
    const float* pa = &value[3 * (size_t)plan.edge_vertex[2 * e]];
    const float* pb = &value[3 * (size_t)plan.edge_vertex[2 * e + 1]];
    const float* c = &edge_control[6 * (size_t)e];
    b[0] = {pa[0], pa[1], pa[2]};
    b[1] = {c[0], c[1], c[2]};
    b[2] = {c[3], c[4], c[5]};
    b[3] = {pb[0], pb[1], pb[2]};
  };
  out.edge_segments.resize(E);
  std::vector<double> edge_bounds(E);
  parallel_for(E, threads, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) {
      D3 c[4];
      edge_curve((int)i, c);
      int at_least = level0[plan.edge_patch[2 * i]];
      if (plan.edge_patch[2 * i + 1] >= 0) at_least = std::max(at_least, level0[plan.edge_patch[2 * i + 1]]);
      if (o.min_edge_segments) at_least = std::max(at_least, o.min_edge_segments[i]);
      out.edge_segments[i] = edge_count(c, at_least, tol, o.max_level, edge_bounds[i]);
    }
  });
  out.times.emplace_back("levels and edge counts", ms_since(t0));

  // 3. Patch patterns.
  t0 = std::chrono::steady_clock::now();
  std::vector<PatchShape> shape(P);
  std::vector<double> patch_bounds(P);
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) {
      int n[3];
      for (int k = 0; k < 3; ++k) n[k] = out.edge_segments[plan.patch_edge[3 * p + k]];
      shape[p] = patch_shape(power_of(&patch_control[30 * p]), level0[p], n, tol, o.max_level,
                             o.min_patch_level != nullptr, patch_bounds[p]);
    }
  });
  out.times.emplace_back("patch patterns", ms_since(t0));

  out.patch_level.resize(P);
  out.patch_uniform.resize(P);
  for (int p = 0; p < P; ++p) {
    out.patch_level[p] = shape[p].m;
    out.patch_uniform[p] = shape[p].uniform;
    if (patch_bounds[p] > tol) ++out.capped;
    out.max_bound = std::max(out.max_bound, patch_bounds[p]);
  }
  for (int e = 0; e < E; ++e) {
    if (edge_bounds[e] > kEdgeShare * tol) ++out.capped;
    out.max_bound = std::max(out.max_bound, edge_bounds[e]);
  }
  if (o.counts_only) return out;

  // 4. Offsets.
  t0 = std::chrono::steady_clock::now();
  std::vector<long long> edge_base(E + 1), patch_base(P + 1), tri_base(P + 1);
  edge_base[0] = SV;
  for (int e = 0; e < E; ++e) {
    edge_base[e + 1] = edge_base[e] + out.edge_segments[e] - 1;
  }
  patch_base[0] = edge_base[E];
  tri_base[0] = 0;
  for (int p = 0; p < P; ++p) {
    patch_base[p + 1] = patch_base[p] + interior_points(shape[p].m);
    tri_base[p + 1] = tri_base[p] + triangle_count(shape[p]);
  }
  const long long N = patch_base[P], T = tri_base[P];
  if (N > 2000000000LL || 3 * T > 2000000000LL)
    throw std::invalid_argument("tolerance: output too large (" + std::to_string(T) + " triangles)");
  out.times.emplace_back("offsets", ms_since(t0));

  // 5. Emit.
  t0 = std::chrono::steady_clock::now();
  out.positions.resize(3 * (size_t)N);
  out.rest_positions.resize(3 * (size_t)N);
  const float* rest = plan.rest_positions.data();  // [0, SV): the sub-vertices at rest
  for (int v = 0; v < SV; ++v)
    for (int r = 0; r < 3; ++r) {
      out.positions[3 * (size_t)v + r] = value[3 * (size_t)v + r];
      out.rest_positions[3 * (size_t)v + r] = rest[3 * (size_t)v + r];
    }
  parallel_for(E, threads, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) {
      D3 c[4];
      edge_curve((int)i, c);
      const int n = out.edge_segments[i];
      const float* ra = rest + 3 * (size_t)plan.edge_vertex[2 * i];
      const float* rb = rest + 3 * (size_t)plan.edge_vertex[2 * i + 1];
      for (int s = 1; s < n; ++s) {
        const float u = (float)s / (float)n, w = 1.0f - u;
        const float B[4] = {w * w * w, 3.0f * u * w * w, 3.0f * u * u * w, u * u * u};
        float* x = &out.positions[3 * (size_t)(edge_base[i] + s - 1)];
        float* y = &out.rest_positions[3 * (size_t)(edge_base[i] + s - 1)];
        const double* cc[4] = {&c[0].x, &c[1].x, &c[2].x, &c[3].x};
        for (int r = 0; r < 3; ++r) {
          float acc = 0.0f;
          for (int k = 0; k < 4; ++k) acc += B[k] * (float)cc[k][r];
          x[r] = acc;
          y[r] = w * ra[r] + u * rb[r];
        }
      }
    }
  });
  out.triangles.resize(3 * (size_t)T);
  out.face_index.resize(T);
  out.triangle_patch.resize(T);
  if (o.normals) out.corner_normals.resize(9 * (size_t)T);
  if (corner_uv) out.uvs.resize(6 * (size_t)T);
  if (o.details) out.corner_bary.resize(9 * (size_t)T);
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) {
      const PatchShape& sh = shape[p];
      const float* cp = &patch_control[30 * p];
      const float* np = &patch_normal[30 * p];
      const int* cv = &plan.patch_vertex[3 * p];
      // Interior points.
      for (int j = 1; j <= sh.m - 2; ++j)
        for (int i = 1; i + j <= sh.m - 1; ++i) {
          const long long o2 = patch_base[p] + (long long)(j - 1) * (sh.m - 1) - (long long)(j - 1) * j / 2 + (i - 1);
          const float bb[3] = {(float)(sh.m - i - j) / sh.m, (float)i / sh.m, (float)j / sh.m};
          float B[10];
          cubic_basis<float>(bb, B);
          const V3 x = eval_cubic(B, cp);
          out.positions[3 * o2] = x.x;
          out.positions[3 * o2 + 1] = x.y;
          out.positions[3 * o2 + 2] = x.z;
          for (int r = 0; r < 3; ++r)
            out.rest_positions[3 * o2 + r] =
                bb[0] * rest[3 * (size_t)cv[0] + r] + bb[1] * rest[3 * (size_t)cv[1] + r] + bb[2] * rest[3 * (size_t)cv[2] + r];
        }
      auto global = [&](const LocalPoint& q) -> long long {
        if (q.kind == 0) return cv[q.k];
        if (q.kind == 1) {
          const int e = plan.patch_edge[3 * p + q.k];
          const int s = plan.patch_edge_reversed[3 * p + q.k] ? sh.n[q.k] - q.i : q.i;
          return edge_base[e] + s - 1;
        }
        return patch_base[p] + (long long)(q.j - 1) * (sh.m - 1) - (long long)(q.j - 1) * q.j / 2 + (q.i - 1);
      };
      long long t = tri_base[p];
      const int tri = plan.patch_triangle[p];
      const double* pb = &plan.patch_bary[9 * (size_t)p];
      for_each_triangle(sh, [&](const LocalPoint& a, const LocalPoint& b2, const LocalPoint& c) {
        const LocalPoint q[3] = {a, b2, c};
        for (int k = 0; k < 3; ++k) {
          out.triangles[3 * t + k] = (int)global(q[k]);
          if (!o.normals && !corner_uv && !o.details) continue;
          double bd[3];
          barycentric(sh, q[k], bd);
          if (o.details)
            for (int r = 0; r < 3; ++r) out.corner_bary[9 * t + 3 * k + r] = (float)bd[r];
          if (o.normals) {
            const float bf[3] = {(float)bd[0], (float)bd[1], (float)bd[2]};
            float B[10];
            cubic_basis<float>(bf, B);
            const V3 nn = unit_patch_normal(eval_cubic(B, np), np);
            out.corner_normals[9 * t + 3 * k] = nn.x;
            out.corner_normals[9 * t + 3 * k + 1] = nn.y;
            out.corner_normals[9 * t + 3 * k + 2] = nn.z;
          }
          if (corner_uv) {
            double ib[3] = {0, 0, 0};  // barycentric point on the input triangle
            for (int c2 = 0; c2 < 3; ++c2)
              for (int r = 0; r < 3; ++r) ib[r] += bd[c2] * pb[3 * c2 + r];
            for (int r = 0; r < 2; ++r) {
              double u = 0;
              for (int c2 = 0; c2 < 3; ++c2) u += ib[c2] * corner_uv[2 * (size_t)plan.input_triangle_corner[3 * tri + c2] + r];
              out.uvs[6 * t + 2 * k + r] = (float)u;
            }
          }
        }
        out.face_index[t] = plan.patch_face[p];
        out.triangle_patch[t] = (int)p;
        ++t;
      });
    }
  });
  for (int e = 0; e < E; ++e) {
    if (!(plan.edge_flags[e] & (kSharpAtA | kSharpAtB))) continue;
    const int n = out.edge_segments[e];
    long long prev = plan.edge_vertex[2 * e];
    for (int s = 1; s <= n; ++s) {
      const long long cur = s == n ? plan.edge_vertex[2 * e + 1] : edge_base[e] + s - 1;
      out.sharp_edges.push_back((int)prev);
      out.sharp_edges.push_back((int)cur);
      prev = cur;
    }
  }
  out.times.emplace_back("emit", ms_since(t0));
  if (o.details) out.patch_control = std::move(patch_control);
  return out;
}

}  // namespace sffd
