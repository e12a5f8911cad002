// Render vertices of the plan (plan.hpp): an output vertex duplicated only where its normals
// split, the topology of the compact output layout.
#include "smoothffd/plan/render_vertices.hpp"

#include <algorithm>
#include <numeric>
#include <vector>

#include "smoothffd/core/cancel.hpp"

namespace sffd {

// Render vertices (see plan.hpp). Needs the patches, edges, output topology and owners.
void build_render_vertices(Plan& plan, int SV, const TessellationTables& tess, const std::vector<int>& face_count) {
  const int P = (int)(plan.patch_vertex.size() / 3), E = (int)plan.edge_flags.size();
  const int L = tess.level, G = tess.grid;
  const long long N = (long long)(plan.rest_positions.size() / 3);
  // Union-find over patch corners (3P): join the two corners at v of a manifold sub-edge that
  // is smooth at v's end.
  std::vector<int> parent(3 * (size_t)P);
  for (size_t i = 0; i < parent.size(); ++i) parent[i] = (int)i;
  auto find = [&](int x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (int e = 0; e < E; ++e) {
    if (face_count[e] != 2) continue;
    int p0 = plan.edge_patch[2 * e], p1 = plan.edge_patch[2 * e + 1];
    for (int end = 0; end < 2; ++end) {
      if ((plan.edge_flags[e] >> end) & 1) continue;  // kSharpAtA / kSharpAtB
      int a = find(3 * p0 + plan.edge_slot[4 * (size_t)e + end]);
      int b = find(3 * p1 + plan.edge_slot[4 * (size_t)e + 2 + end]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);  // root = lowest corner
    }
  }
  // Corners by sub-vertex and patches by edge (CSR, increasing patch order).
  std::vector<int> vstart(SV + 1, 0), estart(E + 1, 0);
  for (int p = 0; p < P; ++p)
    for (int k = 0; k < 3; ++k) {
      vstart[plan.patch_vertex[3 * p + k] + 1]++;
      estart[plan.patch_edge[3 * p + k] + 1]++;
    }
  for (int v = 0; v < SV; ++v) vstart[v + 1] += vstart[v];
  for (int e = 0; e < E; ++e) estart[e + 1] += estart[e];
  std::vector<int> vcorner(vstart[SV]), epatch(estart[E]);
  {
    std::vector<int> vf(vstart.begin(), vstart.end() - 1), ef(estart.begin(), estart.end() - 1);
    for (int p = 0; p < P; ++p)
      for (int k = 0; k < 3; ++k) {
        vcorner[vf[plan.patch_vertex[3 * p + k]]++] = 3 * p + k;
        epatch[ef[plan.patch_edge[3 * p + k]]++] = p;
      }
  }
  // Grid points of the corners and of the edge points, (k, step) -> g.
  int corner_g[3] = {0, 0, 0};
  std::vector<int> edge_g(3 * (size_t)(L + 1), -1);
  for (int g = 0; g < G; ++g) {
    const GridPoint& gp = tess.points[g];
    if (gp.kind == 0) corner_g[gp.which] = g;
    if (gp.kind == 1) edge_g[(size_t)gp.which * (L + 1) + gp.step] = g;
  }
  auto split = [&](int e) { return (plan.edge_flags[e] & (kSharpAtA | kSharpAtB | kNonManifold)) != 0; };
  plan.render_owner.clear();
  plan.render_position.clear();
  std::vector<int> corner_render(3 * (size_t)P, -1);  // by union-find root
  auto add = [&](long long o, int p, int g) {
    plan.render_position.push_back((int)o);
    plan.render_owner.push_back(p);
    plan.render_owner.push_back(g);
    return (int)(plan.render_position.size() - 1);
  };
  for (int v = 0; v < SV; ++v)
    for (int i = vstart[v]; i < vstart[v + 1]; ++i) {  // corners in increasing order
      int c = vcorner[i], root = find(c);
      if (corner_render[root] < 0) corner_render[root] = add(v, c / 3, corner_g[c % 3]);
    }
  std::vector<int> edge_base(E);
  CancelPoller poller(256);
  for (int e = 0; e < E; ++e) {
    poller.tick();
    edge_base[e] = (int)plan.render_position.size();
    for (int m = 1; m < L; ++m) {
      long long o = SV + (long long)e * (L - 1) + (m - 1);
      if (!split(e)) {
        add(o, plan.output_owner[2 * (o - SV)], plan.output_owner[2 * (o - SV) + 1]);
        continue;
      }
      for (int i = estart[e]; i < estart[e + 1]; ++i) {
        int p = epatch[i], k = 0;
        while (plan.patch_edge[3 * p + k] != e) ++k;
        int step = plan.patch_edge_reversed[3 * p + k] ? L - m : m;
        add(o, p, edge_g[(size_t)k * (L + 1) + step]);
      }
    }
  }
  const long long interior0 = SV + (long long)E * (L - 1);
  const long long shift = (long long)plan.render_position.size() - interior0;  // R - N
  for (long long o = interior0; o < N; ++o)
    add(o, plan.output_owner[2 * (o - SV)], plan.output_owner[2 * (o - SV) + 1]);
  plan.patch_grid_render.resize((size_t)P * G);
  for (int p = 0; p < P; ++p)
    for (int g = 0; g < G; ++g) {
      if (g == 0) poller.tick();
      const GridPoint& gp = tess.points[g];
      long long o = plan.patch_grid_vertex[(size_t)p * G + g];
      int r;
      if (gp.kind == 0) {
        r = corner_render[find(3 * p + gp.which)];
      } else if (gp.kind == 1) {
        int e = plan.patch_edge[3 * p + gp.which];
        int m = plan.patch_edge_reversed[3 * p + gp.which] ? L - gp.step : gp.step;
        int sides = split(e) ? estart[e + 1] - estart[e] : 1, s = 0;
        if (sides > 1)
          while (epatch[estart[e] + s] != p) ++s;
        r = edge_base[e] + (m - 1) * sides + s;
      } else {
        r = (int)(o + shift);
      }
      plan.patch_grid_render[(size_t)p * G + g] = r;
    }
  const int LL = L * L;
  plan.render_triangles.resize((size_t)P * LL * 3);
  for (int p = 0; p < P; ++p)
    for (int i = 0; i < 3 * LL; ++i)
      plan.render_triangles[(size_t)p * 3 * LL + i] = plan.patch_grid_render[(size_t)p * G + tess.triangles[i]];
  plan.render_vertices = (int)plan.render_position.size();
}

}  // namespace sffd
