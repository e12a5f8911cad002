// The render vertices stage (plan/render_vertices.hpp) on a hand-made tetrahedron: how many
// copies of each output vertex sharp and non-manifold edges make, and their numbering.
#include <gtest/gtest.h>

#include <algorithm>
#include <set>

#include "smoothffd/plan/adjacency.hpp"
#include "smoothffd/plan/output_topology.hpp"
#include "smoothffd/plan/render_vertices.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

const std::vector<double> kCorners = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};

int edge_of(const Plan& plan, int a, int b) {
  for (int e = 0; e < plan.edges; ++e)
    if (plan.edge_vertex[2 * e] == a && plan.edge_vertex[2 * e + 1] == b) return e;
  return -1;
}

// Patches pv (one input triangle each) at level L, with `flags` or'ed onto edges (a, b).
Plan rendered(const std::vector<int>& pv, int SV, int L, const std::vector<std::pair<std::pair<int, int>, uint8_t>>& flags) {
  Plan plan;
  const int P = (int)pv.size() / 3;
  EdgeTable e = build_edges(pv);
  std::vector<int> tri(P);
  for (int p = 0; p < P; ++p) tri[p] = p;
  build_adjacency(plan, pv, e, std::vector<uint8_t>(e.count(), 0), tri, std::vector<uint8_t>(P, 0));
  for (const auto& f : flags) plan.edge_flags[edge_of(plan, f.first.first, f.first.second)] |= f.second;
  plan.sub_vertices = SV;
  plan.patch_face.assign(P, 0);
  std::vector<double> X(3 * SV, 0.0);
  std::copy(kCorners.begin(), kCorners.begin() + std::min<size_t>(X.size(), kCorners.size()), X.begin());
  const TessellationTables tess = build_tessellation(L);
  build_output_topology(plan, tess, X, {});
  build_render_vertices(plan, SV, tess, e.face_count);
  return plan;
}

// render_triangles name the same output vertices as triangles, render vertices are numbered by
// output vertex, every one is used, and each grid point's render vertex is at its output vertex.
void expect_consistent(const Plan& plan) {
  const int R = plan.render_vertices;
  ASSERT_EQ(plan.render_position.size(), (size_t)R);
  ASSERT_EQ(plan.render_owner.size(), 2u * R);
  ASSERT_EQ(plan.render_triangles.size(), plan.triangles.size());
  for (size_t i = 0; i < plan.triangles.size(); ++i)
    EXPECT_EQ(plan.render_position[plan.render_triangles[i]], plan.triangles[i]);
  EXPECT_TRUE(std::is_sorted(plan.render_position.begin(), plan.render_position.end()));
  EXPECT_EQ(std::set<int>(plan.render_triangles.begin(), plan.render_triangles.end()).size(), (size_t)R);
  for (size_t i = 0; i < plan.patch_grid_render.size(); ++i)
    EXPECT_EQ(plan.render_position[plan.patch_grid_render[i]], plan.patch_grid_vertex[i]);
  // Each render vertex's owner is a (patch, grid point) at it.
  const int G = plan.grid;
  for (int r = 0; r < R; ++r)
    EXPECT_EQ(plan.patch_grid_render[(size_t)plan.render_owner[2 * r] * G + plan.render_owner[2 * r + 1]], r);
}

const std::vector<int> kTetra = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};

}  // namespace

TEST(RenderVertices, NoSplitIsTheOutputVertices) {
  const Plan plan = rendered(kTetra, 4, 3, {});
  expect_consistent(plan);
  EXPECT_EQ(plan.render_vertices, plan.output_vertices);
  for (int r = 0; r < plan.render_vertices; ++r) EXPECT_EQ(plan.render_position[r], r);
  EXPECT_EQ(plan.render_triangles, plan.triangles);
}

TEST(RenderVertices, OneSharpEdgeSplitsItsInsideOnly) {
  // Sharp edge 0-1: its L - 1 inner points get a copy for each of its two patches; its ends
  // stay one vertex each (the patches around 0 still meet across the smooth edges 0-2, 0-3).
  const int L = 4;
  const Plan plan = rendered(kTetra, 4, L, {{{0, 1}, kSharpAtA | kSharpAtB}});
  expect_consistent(plan);
  EXPECT_EQ(plan.render_vertices, plan.output_vertices + (L - 1));
  // Step m (1..L-1 from end a) on side s: base + (m - 1) * 2 + s; sides in increasing patch order.
  const int e = edge_of(plan, 0, 1), base = 4 + 0;  // edge 0-1 is the first edge: right after the 4 corners
  ASSERT_EQ(e, 0);
  const int sides[2] = {plan.edge_patch[0], plan.edge_patch[1]};
  ASSERT_LT(sides[0], sides[1]);
  for (int m = 1; m < L; ++m)
    for (int s = 0; s < 2; ++s) {
      const int r = base + (m - 1) * 2 + s;
      EXPECT_EQ(plan.render_position[r], 4 + m - 1);
      EXPECT_EQ(plan.render_owner[2 * r], sides[s]);
    }
}

TEST(RenderVertices, AVertexCutAllRoundSplitsPerPatch) {
  // All three edges at vertex 0 sharp there: its three patches meet across none of them, three
  // copies of vertex 0; the edges' inner points split; vertices 1, 2, 3 stay whole.
  const int L = 3;
  const Plan plan = rendered(kTetra, 4, L, {{{0, 1}, kSharpAtA}, {{0, 2}, kSharpAtA}, {{0, 3}, kSharpAtA}});
  expect_consistent(plan);
  EXPECT_EQ(plan.render_vertices, plan.output_vertices + 2 + 3 * (L - 1));
  EXPECT_EQ(std::count(plan.render_position.begin(), plan.render_position.end(), 0), 3);
  for (int v = 1; v < 4; ++v) EXPECT_EQ(std::count(plan.render_position.begin(), plan.render_position.end(), v), 1);
}

TEST(RenderVertices, NonManifoldEdgeSplitsPerPatch) {
  // Three triangles on edge 0-1: its inner points get three copies; the flag kNonManifold alone
  // splits (no sharp bit). Its ends: each triangle's corner at 0 is joined to no other (the
  // edges 0-2, 0-3, 0-4 have one patch each, 0-1 is not manifold): three copies each.
  const int L = 3;
  const std::vector<int> pv = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  const Plan plan = rendered(pv, 5, L, {});
  expect_consistent(plan);
  const int e = edge_of(plan, 0, 1);
  ASSERT_NE(plan.edge_flags[e] & kNonManifold, 0);
  EXPECT_EQ(plan.render_vertices, plan.output_vertices + 2 * (L - 1) + 2 + 2);
  for (int m = 1; m < L; ++m) {
    const int o = 5 + e * (L - 1) + m - 1;
    EXPECT_EQ(std::count(plan.render_position.begin(), plan.render_position.end(), o), 3) << m;
  }
}
