#include "smoothffd/plan/output_topology.hpp"

#include <stdexcept>
#include <string>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/sources.hpp"

namespace sffd {

void build_output_topology(Plan& plan, const TessellationTables& tess, const std::vector<double>& rest,
                           const std::vector<float>& corner_uv) {
  const int L = tess.level, SV = plan.sub_vertices;
  const int P = (int)(plan.patch_vertex.size() / 3), E = (int)(plan.edge_vertex.size() / 2);
  const int G = tess.grid, IG = (L - 1) * (L - 2) / 2;
  const long long N = (long long)SV + (long long)E * (L - 1) + (long long)P * IG;
  const long long T = (long long)P * L * L;
  if (N > 2000000000LL || 3 * T > 2000000000LL)
    throw std::invalid_argument("level: output too large (" + std::to_string(T) + " triangles)");
  plan.grid_basis = tess.basis;
  plan.local_triangles = tess.triangles;
  plan.patch_grid_vertex.resize((size_t)P * G);
  plan.output_owner.assign(2 * (size_t)(N - SV), -1);
  CancelPoller poller(256);
  for (int p = 0; p < P; ++p) {
    poller.tick();
    const int* cv = &plan.patch_vertex[3 * p];
    for (int g = 0; g < G; ++g) {
      const GridPoint& gp = tess.points[g];
      long long o;
      if (gp.kind == 0) {
        o = cv[gp.which];
      } else if (gp.kind == 1) {
        int m = plan.patch_edge_reversed[3 * p + gp.which] ? L - gp.step : gp.step;
        o = SV + (long long)plan.patch_edge[3 * p + gp.which] * (L - 1) + (m - 1);
      } else {
        o = SV + (long long)E * (L - 1) + (long long)p * IG + gp.which;
      }
      plan.patch_grid_vertex[(size_t)p * G + g] = (int)o;
      if (o >= SV && plan.output_owner[2 * (o - SV)] < 0) {
        plan.output_owner[2 * (o - SV)] = p;
        plan.output_owner[2 * (o - SV) + 1] = g;
      }
    }
  }
  plan.output_vertices = (int)N;
  output_rest_positions(plan, tess, rest, plan.rest_positions);
  plan.triangles.resize(3 * (size_t)T);
  plan.face_index.resize(T);
  const int LL = L * L;
  for (int p = 0; p < P; ++p)
    for (int t = 0; t < LL; ++t) {
      if (t == 0) poller.tick();
      size_t ot = (size_t)p * LL + t;
      plan.face_index[ot] = plan.patch_face[p];
      for (int c = 0; c < 3; ++c)
        plan.triangles[3 * ot + c] = plan.patch_grid_vertex[(size_t)p * G + tess.triangles[3 * t + c]];
    }
  plan.level = L;  // interpolate_corners reads it
  output_uvs(plan, corner_uv, plan.uvs);
  for (int e = 0; e < E; ++e) {
    if (!(plan.edge_flags[e] & (kSharpAtA | kSharpAtB))) continue;
    int prev = plan.edge_vertex[2 * e];
    for (int m = 1; m <= L; ++m) {
      int cur = m == L ? plan.edge_vertex[2 * e + 1] : SV + e * (L - 1) + (m - 1);
      plan.sharp_edges.push_back(prev);
      plan.sharp_edges.push_back(cur);
      prev = cur;
    }
  }
  plan.grid = G;
  plan.output_triangles = (int)T;
}

void output_rest_positions(const Plan& plan, const TessellationTables& tess, const std::vector<double>& rest,
                           std::vector<float>& out) {
  const long long SV = plan.sub_vertices, N = plan.output_vertices;
  out.resize(3 * (size_t)N);
  for (long long v = 0; v < SV; ++v)
    for (int i = 0; i < 3; ++i) out[3 * v + i] = (float)rest[3 * v + i];
  parallel_for(N - SV, default_threads(), [&](long long b, long long e) {
    for (long long j = b; j < e; ++j) {
      const int p = plan.output_owner[2 * j], g = plan.output_owner[2 * j + 1];
      const int* cv = &plan.patch_vertex[3 * (size_t)p];
      const double* w = &tess.bary[3 * (size_t)g];
      for (int i = 0; i < 3; ++i) {
        double x = 0;
        for (int c = 0; c < 3; ++c) x += w[c] * rest[3 * (size_t)cv[c] + i];
        out[3 * (SV + j) + i] = (float)x;
      }
    }
  });
}

void output_uvs(const Plan& plan, const std::vector<float>& corner_uv, std::vector<float>& uvs) {
  if (corner_uv.empty()) {
    uvs.clear();
    return;
  }
  uvs.resize(6 * (size_t)plan.patch_triangle.size() * plan.level * plan.level);
  interpolate_corners(plan, corner_uv.data(), 2, uvs.data());
}

}  // namespace sffd
