// The sub-mesh adjacency stage (plan/adjacency.hpp) on hand-made triangle lists.
#include <gtest/gtest.h>

#include "smoothffd/plan/adjacency.hpp"

using namespace sffd;

namespace {

struct Built {
  Plan plan;
  EdgeTable sub;
};

// pv: P x 3 patches, one input triangle each (patch_tri = p); flat: which are a flat face's.
Built adjacency_of(const std::vector<int>& pv, std::vector<uint8_t> flat = {}, std::vector<uint8_t> sharp = {}) {
  Built b;
  const int P = (int)pv.size() / 3;
  b.sub = build_edges(pv);
  if (flat.empty()) flat.assign(P, 0);
  if (sharp.empty()) sharp.assign(b.sub.count(), 0);
  std::vector<int> patch_tri(P);
  for (int p = 0; p < P; ++p) patch_tri[p] = p;
  build_adjacency(b.plan, pv, b.sub, sharp, patch_tri, flat);
  return b;
}

// Index of edge (a, b), a < b, or -1.
int edge_of(const Plan& plan, int a, int b) {
  for (int e = 0; e < plan.edges; ++e)
    if (plan.edge_vertex[2 * e] == a && plan.edge_vertex[2 * e + 1] == b) return e;
  return -1;
}

}  // namespace

// Two triangles 0-1-2 and 2-1-3 sharing edge 1-2: five edges numbered by their ends.
TEST(Adjacency, TwoTrianglesByHand) {
  const Built b = adjacency_of({0, 1, 2, 2, 1, 3});
  const Plan& plan = b.plan;
  ASSERT_EQ(plan.edges, 5);
  EXPECT_EQ(plan.edge_vertex, (std::vector<int>{0, 1, 0, 2, 1, 2, 1, 3, 2, 3}));
  EXPECT_EQ(plan.patch_vertex, (std::vector<int>{0, 1, 2, 2, 1, 3}));
  // Patch 0: edges 0-1, 1-2, 2-0; patch 1: edges 2-1, 1-3, 3-2.
  EXPECT_EQ(plan.patch_edge, (std::vector<int>{0, 2, 1, 2, 3, 4}));
  // Corner k -> k + 1 against the edge's a -> b: 2 -> 0 and 2 -> 1 and 3 -> 2 run backwards.
  EXPECT_EQ(plan.patch_edge_reversed, (std::vector<uint8_t>{0, 0, 1, 1, 0, 1}));
  // Edge 1-2 (index 2): patch 0 with ends in slots 1, 2; patch 1 with ends in slots 1, 0.
  EXPECT_EQ(plan.edge_patch[4], 0);
  EXPECT_EQ(plan.edge_patch[5], 1);
  EXPECT_EQ(std::vector<uint8_t>(plan.edge_slot.begin() + 8, plan.edge_slot.begin() + 12),
            (std::vector<uint8_t>{1, 2, 1, 0}));
  // The outer four are boundary edges with one patch.
  for (int e : {0, 1, 3, 4}) {
    EXPECT_EQ(plan.edge_flags[e], kBoundary) << e;
    EXPECT_EQ(plan.edge_patch[2 * e + 1], -1) << e;
  }
  EXPECT_EQ(plan.edge_flags[2], 0);
  // With the second triangle a flat face's, its three edges follow it, the shared one too.
  const Plan flat = adjacency_of({0, 1, 2, 2, 1, 3}, {0, 1}).plan;
  EXPECT_EQ(flat.edge_flags, (std::vector<uint8_t>{kBoundary, kBoundary, kFlatFace, kBoundary | kFlatFace,
                                                   kBoundary | kFlatFace}));
}

// Every patch's edge slots name the edge's ends, and the reversal flag says which end its
// corner k is, on a closed tetrahedron.
TEST(Adjacency, SlotsAndReversalAgreeWithTheEnds) {
  const std::vector<int> pv = {0, 2, 1, 0, 1, 3, 1, 2, 3, 2, 0, 3};
  const Plan plan = adjacency_of(pv).plan;
  ASSERT_EQ(plan.edges, 6);
  for (int e = 0; e < 6; ++e) {
    EXPECT_EQ(plan.edge_flags[e], 0) << "closed manifold: no boundary";
    for (int s = 0; s < 2; ++s) {
      const int p = plan.edge_patch[2 * e + s];
      ASSERT_GE(p, 0);
      for (int end = 0; end < 2; ++end)
        EXPECT_EQ(pv[3 * p + plan.edge_slot[4 * e + 2 * s + end]], plan.edge_vertex[2 * e + end]);
    }
  }
  for (int p = 0; p < 4; ++p)
    for (int k = 0; k < 3; ++k) {
      const int e = plan.patch_edge[3 * p + k], from = pv[3 * p + k], to = pv[3 * p + (k + 1) % 3];
      EXPECT_EQ(e, edge_of(plan, std::min(from, to), std::max(from, to)));
      EXPECT_EQ(plan.patch_edge_reversed[3 * p + k], from > to);
    }
}

TEST(Adjacency, FlagsNonManifoldFlatAndSharp) {
  // Three triangles on edge 0-1 (non-manifold); triangle 2 is a flat face's; edge 0-2 is
  // given sharp at its end a (vertex 0).
  const std::vector<int> pv = {0, 1, 2, 1, 0, 3, 0, 1, 4};
  EdgeTable sub = build_edges(pv);
  std::vector<uint8_t> sharp(sub.count(), 0);
  Built ref = adjacency_of(pv);
  const int e02 = edge_of(ref.plan, 0, 2);
  ASSERT_GE(e02, 0);
  sharp[e02] = kSharpAtA;
  const Plan plan = adjacency_of(pv, {0, 0, 1}, sharp).plan;
  const int e01 = edge_of(plan, 0, 1), e04 = edge_of(plan, 0, 4), e14 = edge_of(plan, 1, 4), e13 = edge_of(plan, 1, 3);
  EXPECT_EQ(plan.edge_flags[e01], kNonManifold);  // its first two sides are triangles 0 and 1
  EXPECT_EQ(plan.edge_flags[e02], kSharpAtA | kBoundary);
  EXPECT_EQ(plan.edge_flags[e04], kBoundary | kFlatFace);
  EXPECT_EQ(plan.edge_flags[e14], kBoundary | kFlatFace);
  EXPECT_EQ(plan.edge_flags[e13], kBoundary);
}
