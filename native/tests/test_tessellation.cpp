// Unit tests of the uniform tessellation tables (plan/tessellation.hpp, paper sec. 5.5).
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>

#include "smoothffd/plan/tessellation.hpp"
#include "test_util.hpp"

using namespace sffd;

TEST(Tessellation, Counts) {
  for (int L = 1; L <= 20; ++L) {
    TessellationTables tt = build_tessellation(L);
    const int G = (L + 1) * (L + 2) / 2;
    EXPECT_EQ(tt.level, L);
    ASSERT_EQ(tt.grid, G);
    ASSERT_EQ((int)tt.points.size(), G);
    ASSERT_EQ(tt.bary.size(), 3u * G);
    ASSERT_EQ(tt.basis.size(), 10u * G);
    ASSERT_EQ((int)tt.triangles.size(), 3 * L * L);
    int kinds[3] = {0, 0, 0};
    std::set<std::pair<int, int>> edge_points;
    std::set<int> corners, interior;
    for (const GridPoint& p : tt.points) {
      kinds[p.kind]++;
      if (p.kind == 0) corners.insert(p.which);
      if (p.kind == 1) {
        EXPECT_GE(p.step, 1);
        EXPECT_LE(p.step, L - 1);
        edge_points.insert({p.which, p.step});
      }
      if (p.kind == 2) interior.insert(p.which);
    }
    EXPECT_EQ(kinds[0], 3);
    EXPECT_EQ(kinds[1], 3 * (L - 1));
    EXPECT_EQ(kinds[2], (L - 1) * (L - 2) / 2);
    EXPECT_EQ(corners.size(), 3u);
    EXPECT_EQ((int)edge_points.size(), 3 * (L - 1));  // each (edge, step) exactly once
    EXPECT_EQ((int)interior.size(), kinds[2]);
    if (!interior.empty()) EXPECT_EQ(*interior.rbegin(), kinds[2] - 1);
  }
}

TEST(Tessellation, GridPointsAndBasis) {
  for (int L : {1, 2, 3, 7, 10}) {
    TessellationTables tt = build_tessellation(L);
    for (int g = 0; g < tt.grid; ++g) {
      const double* b = &tt.bary[3 * g];
      EXPECT_NEAR(b[0] + b[1] + b[2], 1.0, 1e-15);
      float sum = 0;
      for (int k = 0; k < 10; ++k) sum += tt.basis[10 * g + k];
      EXPECT_NEAR(sum, 1.0f, 1e-6f);
      const GridPoint& p = tt.points[g];
      if (p.kind == 0) EXPECT_EQ(b[p.which], 1.0);
      if (p.kind == 1) {  // on edge which (corner which -> which+1), step/L from its start
        EXPECT_EQ(b[(p.which + 2) % 3], 0.0);
        EXPECT_NEAR(b[(p.which + 1) % 3], double(p.step) / L, 1e-15);
      }
      if (p.kind == 2) EXPECT_TRUE(b[0] > 0 && b[1] > 0 && b[2] > 0);
    }
  }
}

// The L^2 triangles tile the patch once, with the patch's winding, and form a disk whose open
// boundary is the 3L grid edges along the patch sides.
TEST(Tessellation, TrianglesTileThePatch) {
  for (int L : {1, 2, 5, 10}) {
    TessellationTables tt = build_tessellation(L);
    double area = 0;
    for (int t = 0; t < L * L; ++t) {
      const double *a = &tt.bary[3 * tt.triangles[3 * t]], *b = &tt.bary[3 * tt.triangles[3 * t + 1]],
                   *c = &tt.bary[3 * tt.triangles[3 * t + 2]];
      // Signed area in the (b1, b2) plane: positive = same winding as corners 0, 1, 2.
      double s = 0.5 * ((b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]));
      EXPECT_NEAR(s, 0.5 / (L * L), 1e-12);
      area += s;
    }
    EXPECT_NEAR(area, 0.5, 1e-12);
    sffd_test::EdgeCounts e = sffd_test::count_edges(tt.triangles);
    int open = 0;
    for (auto& kv : e.undirected) {
      EXPECT_LE(kv.second, 2);
      open += kv.second == 1;
    }
    for (auto& kv : e.directed) EXPECT_EQ(kv.second, 1);
    EXPECT_EQ(open, 3 * L);
  }
}
