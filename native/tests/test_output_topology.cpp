// The output topology stage (plan/output_topology.hpp) on a hand-made closed tetrahedron: the
// vertex and triangle counts, a watertight consistently wound output, rest positions on the
// patches, sharp edges and UVs.
#include <gtest/gtest.h>

#include <set>

#include "smoothffd/plan/adjacency.hpp"
#include "smoothffd/plan/output_topology.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

const std::vector<int> kTetra = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};      // wound consistently
const std::vector<double> kCorners = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};  // vertex positions

// The plan up to the output topology: adjacency, faces 7, 7, 8, 9, each patch a whole input
// triangle of corners 3p .. 3p + 2 (for the UVs).
Plan tetra_plan() {
  Plan plan;
  EdgeTable e = build_edges(kTetra);
  build_adjacency(plan, kTetra, e, std::vector<uint8_t>(e.count(), 0), {0, 1, 2, 3}, {0, 0, 0, 0});
  plan.sub_vertices = 4;
  plan.patch_face = {7, 7, 8, 9};
  plan.input_corners = 12;
  for (int c = 0; c < 12; ++c) plan.input_triangle_corner.push_back(c);
  plan.input_triangle_face = {7, 7, 8, 9};
  plan.patch_triangle = {0, 1, 2, 3};
  for (int p = 0; p < 4; ++p)
    for (int c = 0; c < 3; ++c)
      for (int k = 0; k < 3; ++k) plan.patch_bary.push_back(c == k ? 1.0 : 0.0);
  return plan;
}

int edge_of(const Plan& plan, int a, int b) {
  for (int e = 0; e < plan.edges; ++e)
    if (plan.edge_vertex[2 * e] == a && plan.edge_vertex[2 * e + 1] == b) return e;
  return -1;
}

}  // namespace

TEST(OutputTopology, CountsAndWatertightness) {
  for (int L : {1, 2, 3, 5}) {
    Plan plan = tetra_plan();
    build_output_topology(plan, build_tessellation(L), kCorners, {});
    const int N = 4 + 6 * (L - 1) + 4 * (L - 1) * (L - 2) / 2, T = 4 * L * L;
    EXPECT_EQ(plan.output_vertices, N) << L;
    EXPECT_EQ(plan.output_triangles, T) << L;
    EXPECT_EQ(plan.level, L);
    EXPECT_EQ(plan.grid, (L + 1) * (L + 2) / 2);
    ASSERT_EQ(plan.triangles.size(), 3u * T);
    ASSERT_EQ(plan.output_owner.size(), 2u * (N - 4));
    EXPECT_TRUE(plan.uvs.empty());
    EXPECT_TRUE(plan.sharp_edges.empty());
    // Closed and consistently wound: every edge on two triangles, once in each direction;
    // Euler characteristic 2; every output vertex used.
    const EdgeCounts c = count_edges(plan.triangles);
    for (const auto& kv : c.undirected) EXPECT_EQ(kv.second, 2) << L;
    for (const auto& kv : c.directed) EXPECT_EQ(kv.second, 1) << L;
    EXPECT_EQ(N - (int)c.undirected.size() + T, 2) << L;
    EXPECT_EQ(std::set<int>(plan.triangles.begin(), plan.triangles.end()).size(), (size_t)N);
    for (int t = 0; t < T; ++t) EXPECT_EQ(plan.face_index[t], plan.patch_face[t / (L * L)]);
    for (size_t i = 0; i < plan.output_owner.size(); i += 2) {
      EXPECT_GE(plan.output_owner[i], 0);
      EXPECT_LT(plan.output_owner[i], 4);
    }
  }
}

TEST(OutputTopology, RestPositionsLieOnTheFlatPatches) {
  const int L = 3;
  Plan plan = tetra_plan();
  build_output_topology(plan, build_tessellation(L), kCorners, {});
  for (int v = 0; v < 4; ++v)
    for (int i = 0; i < 3; ++i) EXPECT_EQ(plan.rest_positions[3 * v + i], (float)kCorners[3 * v + i]);
  // Step m along edge e from its end a: a + m / L (b - a).
  for (int e = 0; e < plan.edges; ++e) {
    const double* a = &kCorners[3 * plan.edge_vertex[2 * e]];
    const double* b = &kCorners[3 * plan.edge_vertex[2 * e + 1]];
    for (int m = 1; m < L; ++m) {
      const int o = 4 + e * (L - 1) + m - 1;
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(plan.rest_positions[3 * o + i], a[i] + m / double(L) * (b[i] - a[i]), 1e-7);
    }
  }
  // The one point inside each patch at level 3: its centroid.
  for (int p = 0; p < 4; ++p) {
    const int o = 4 + 6 * (L - 1) + p;
    for (int i = 0; i < 3; ++i) {
      double c = 0;
      for (int k = 0; k < 3; ++k) c += kCorners[3 * kTetra[3 * p + k] + i] / 3;
      EXPECT_NEAR(plan.rest_positions[3 * o + i], c, 1e-7);
    }
  }
}

TEST(OutputTopology, SharpEdgesRunAlongTheirSubEdge) {
  const int L = 4;
  Plan plan = tetra_plan();
  const int e01 = edge_of(plan, 0, 1), e23 = edge_of(plan, 2, 3);
  plan.edge_flags[e01] |= kSharpAtA;
  plan.edge_flags[e23] |= kSharpAtB;
  build_output_topology(plan, build_tessellation(L), kCorners, {});
  auto inner = [&](int e, int m) { return 4 + e * (L - 1) + m - 1; };
  std::vector<int> want;
  for (int e : {std::min(e01, e23), std::max(e01, e23)}) {
    std::vector<int> chain = {plan.edge_vertex[2 * e], inner(e, 1), inner(e, 2), inner(e, 3), plan.edge_vertex[2 * e + 1]};
    for (int m = 0; m < L; ++m) want.insert(want.end(), {chain[m], chain[m + 1]});
  }
  EXPECT_EQ(plan.sharp_edges, want);
  // Each of them an edge of the output triangles.
  const EdgeCounts c = count_edges(plan.triangles);
  for (size_t i = 0; i < want.size(); i += 2)
    EXPECT_EQ(c.undirected.count({std::min(want[i], want[i + 1]), std::max(want[i], want[i + 1])}), 1u);
}

TEST(OutputTopology, UVsFollowTheRestPositions) {
  // UV = (x, y) of each input corner's vertex: every output corner's UV is then the (x, y) of
  // its rest position.
  const int L = 3;
  Plan plan = tetra_plan();
  std::vector<float> uv;
  for (int c = 0; c < 12; ++c) uv.insert(uv.end(), {(float)kCorners[3 * kTetra[c]], (float)kCorners[3 * kTetra[c] + 1]});
  build_output_topology(plan, build_tessellation(L), kCorners, uv);
  ASSERT_EQ(plan.uvs.size(), 6u * plan.output_triangles);
  for (int t = 0; t < plan.output_triangles; ++t)
    for (int c = 0; c < 3; ++c) {
      const int o = plan.triangles[3 * t + c];
      EXPECT_NEAR(plan.uvs[6 * t + 2 * c], plan.rest_positions[3 * o], 1e-6);
      EXPECT_NEAR(plan.uvs[6 * t + 2 * c + 1], plan.rest_positions[3 * o + 1], 1e-6);
    }
}
