#include "smoothffd/eval/adaptive.hpp"

#include "smoothffd/eval/adaptive_stages.hpp"

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

using namespace adapt;

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

  // 2.-3. Decisions: each patch's uniform level, each edge's count, each patch's pattern.
  t0 = std::chrono::steady_clock::now();
  std::vector<int> level0(P), patch_m(P);
  out.edge_segments.resize(E);
  out.patch_uniform.resize(P);
  std::vector<double> edge_bounds(E), patch_bounds(P);
  AdaptiveView av{};
  av.value = value.data();
  av.edge_control = edge_control.data();
  av.patch_control = patch_control.data();
  av.patch_normal = patch_normal.data();
  av.level0 = level0.data();
  av.segments = out.edge_segments.data();
  av.patch_m = patch_m.data();
  av.patch_uniform = out.patch_uniform.data();
  av.edge_bound = edge_bounds.data();
  av.patch_bound = patch_bounds.data();
  av.min_edge_segments = o.min_edge_segments;
  av.min_patch_level = o.min_patch_level;
  av.tolerance = tol;
  av.max_level = o.max_level;
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) decide_level(av, (int)p);
  });
  parallel_for(E, threads, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) decide_edge(pv, av, (int)i);
  });
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) decide_pattern(pv, av, (int)p);
  });
  out.times.emplace_back("decisions", ms_since(t0));
  out.patch_level = patch_m;
  for (int p = 0; p < P; ++p) {
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
  for (int e = 0; e < E; ++e) edge_base[e + 1] = edge_base[e] + out.edge_segments[e] - 1;
  patch_base[0] = edge_base[E];
  tri_base[0] = 0;
  for (int p = 0; p < P; ++p) {
    const PatchShape sh = shape_of(pv, av, p);
    patch_base[p + 1] = patch_base[p] + interior_points(sh.m);
    tri_base[p + 1] = tri_base[p] + triangle_count(sh);
  }
  const long long N = patch_base[P], T = tri_base[P];
  if (N > 2000000000LL || 3 * T > 2000000000LL)
    throw std::invalid_argument("tolerance: output too large (" + std::to_string(T) + " triangles)");
  out.times.emplace_back("offsets", ms_since(t0));

  // 5. Emit.
  t0 = std::chrono::steady_clock::now();
  out.allocate(N, T, o, corner_uv != nullptr);
  av.edge_base = edge_base.data();
  av.patch_base = patch_base.data();
  av.tri_base = tri_base.data();
  av.positions = out.positions.data();
  av.rest_positions = out.rest_positions.data();
  av.triangles = out.triangles.data();
  av.face_index = out.face_index.data();
  av.triangle_patch = out.triangle_patch.data();
  av.corner_normals = o.normals ? out.corner_normals.data() : nullptr;
  av.uvs = corner_uv ? out.uvs.data() : nullptr;
  av.corner_bary = o.details ? out.corner_bary.data() : nullptr;
  av.rest = plan.rest_positions.data();
  av.patch_face = plan.patch_face.data();
  av.patch_triangle = plan.patch_triangle.data();
  av.patch_bary = plan.patch_bary.data();
  av.input_triangle_corner = plan.input_triangle_corner.data();
  av.corner_uv = corner_uv;
  for (int v = 0; v < SV; ++v)
    for (int r = 0; r < 3; ++r) {
      out.positions[3 * (size_t)v + r] = value[3 * (size_t)v + r];
      out.rest_positions[3 * (size_t)v + r] = av.rest[3 * (size_t)v + r];
    }
  parallel_for(E, threads, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) emit_edge(pv, av, (int)i);
  });
  parallel_for(P, threads, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) emit_patch(pv, av, (int)p);
  });
  out.sharp_edges = adaptive_sharp_edges(plan, out.edge_segments.data());
  out.times.emplace_back("emit", ms_since(t0));
  if (o.details) out.patch_control = std::move(patch_control);
  return out;
}

std::vector<int> adaptive_sharp_edges(const Plan& plan, const int* segments) {
  std::vector<int> out;
  long long base = plan.sub_vertices;  // first output vertex of edge e's inner points
  for (int e = 0; e < plan.edges; ++e) {
    const int n = segments[e];
    if (plan.edge_flags[e] & (kSharpAtA | kSharpAtB)) {
      long long prev = plan.edge_vertex[2 * e];
      for (int s = 1; s <= n; ++s) {
        const long long cur = s == n ? plan.edge_vertex[2 * e + 1] : base + s - 1;
        out.push_back((int)prev);
        out.push_back((int)cur);
        prev = cur;
      }
    }
    base += n - 1;
  }
  return out;
}

}  // namespace sffd
