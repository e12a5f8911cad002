// The adaptive tessellation's patterns (eval/adaptive.hpp): for every combination of edge
// counts and interior level, the triangles tile the parameter triangle exactly once, each
// counter-clockwise, their boundary is each edge's n equal segments, and their count is the
// one the frame's offsets assume.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

#include "smoothffd/eval/adaptive.hpp"

namespace {

using Key = std::pair<long long, long long>;
// A parameter point as exact integers: (b1, b2) scaled by a common multiple of every count.
constexpr long long kScale = 720720;  // lcm(1..16)
Key key(const double* w) { return {std::llround(w[1] * kScale), std::llround(w[2] * kScale)}; }

void check_pattern(const int n[3], int m) {
  const std::vector<double> t = sffd::adaptive_pattern(n, m);
  const long long T = (long long)t.size() / 9;
  const bool uniform = n[0] == m && n[1] == m && n[2] == m;
  const long long r = m - 3;
  const long long want = uniform ? (long long)m * m : r * r + n[0] + n[1] + n[2] + 3 * r;
  ASSERT_EQ(T, want) << n[0] << " " << n[1] << " " << n[2] << " m " << m;
  double area = 0;
  std::map<std::pair<Key, Key>, int> edges;  // directed edge -> uses
  for (long long i = 0; i < T; ++i) {
    const double* a = &t[9 * i];
    const double *b = a + 3, *c = a + 6;
    const double twice = (b[1] - a[1]) * (c[2] - a[2]) - (c[1] - a[1]) * (b[2] - a[2]);
    ASSERT_GT(twice, 1e-12) << "triangle " << i << " is not counter-clockwise (n " << n[0] << " " << n[1] << " "
                            << n[2] << " m " << m << ")";
    area += twice / 2;
    const double* v[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) edges[{key(v[k]), key(v[(k + 1) % 3])}]++;
  }
  EXPECT_NEAR(area, 0.5, 1e-9);
  // Each directed edge once; an inner edge also the other way; the rest are the boundary.
  std::map<std::pair<Key, Key>, int> boundary;
  for (const auto& [e, uses] : edges) {
    ASSERT_EQ(uses, 1);
    if (!edges.count({e.second, e.first})) boundary[e] = 1;
  }
  // The boundary: side k's n[k] equal segments from corner k to corner k + 1.
  const double corner[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  size_t sides = 0;
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < n[k]; ++i) {
      double p[3], q[3];
      for (int c = 0; c < 3; ++c) {
        p[c] = corner[k][c] + (corner[(k + 1) % 3][c] - corner[k][c]) * i / n[k];
        q[c] = corner[k][c] + (corner[(k + 1) % 3][c] - corner[k][c]) * (i + 1) / n[k];
      }
      EXPECT_TRUE(boundary.count({key(p), key(q)})) << "side " << k << " segment " << i;
    }
    sides += n[k];
  }
  EXPECT_EQ(boundary.size(), sides);
}

TEST(AdaptivePattern, EveryCountAndLevelTilesTheTriangle) {
  for (int m = 1; m <= 10; ++m)
    for (int a = 1; a <= 9; ++a)
      for (int b = 1; b <= 9; ++b)
        for (int c = 1; c <= 9; ++c) {
          const int n[3] = {a, b, c};
          if (m < 3 && !(a == m && b == m && c == m)) continue;
          check_pattern(n, m);
          if (HasFatalFailure()) return;
        }
}

TEST(AdaptivePattern, UniformIsTheLevelGrid) {
  // All three counts equal to m: the uniform level-m grid, m^2 triangles of area 1/(2 m^2).
  for (int m = 1; m <= 12; ++m) {
    const int n[3] = {m, m, m};
    const std::vector<double> t = sffd::adaptive_pattern(n, m);
    for (size_t i = 0; i < t.size() / 9; ++i) {
      const double* a = &t[9 * i];
      const double twice = (a[4] - a[1]) * (a[8] - a[2]) - (a[7] - a[1]) * (a[5] - a[2]);
      EXPECT_NEAR(twice, 1.0 / (m * m), 1e-12);
    }
  }
}

TEST(AdaptiveBounds, FlatPatchAndStraightEdgeAreZero) {
  // A planar patch with linear parametrisation: every bound is 0 (up to rounding).
  float cp[30];
  const float P0[3] = {0, 0, 0}, P1[3] = {3, 0, 0}, P2[3] = {0, 3, 1};
  const int e[10][3] = {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 1, 0}, {1, 2, 0},
                        {0, 2, 1}, {0, 1, 2}, {1, 0, 2}, {2, 0, 1}, {1, 1, 1}};
  for (int k = 0; k < 10; ++k)
    for (int r = 0; r < 3; ++r) cp[3 * k + r] = (e[k][0] * P0[r] + e[k][1] * P1[r] + e[k][2] * P2[r]) / 3.0f;
  const double st[3][2] = {{0.1, 0.1}, {0.6, 0.2}, {0.2, 0.7}};
  EXPECT_LT(sffd::triangle_bound(cp, st), 1e-6);
  EXPECT_LT(sffd::uniform_bound(cp, 1), 1e-6);
  EXPECT_LT(sffd::edge_bound(cp, cp + 9, cp + 12, cp + 3, 1), 1e-6);
}

TEST(AdaptiveBounds, QuadraticCurveMatchesTheChordError) {
  // c(u) = (u, u^2, 0) as a cubic (control points of y: 0, 0, 1/3, 1): its chord error over n
  // equal steps is the parabola's sagitta h^2 / 4, h = 1/n; second differences 1/3 (c'' = 2),
  // third difference 0, so the bound 0.75 * (1/3) h^2 is exact.
  const float b[4][3] = {{0, 0, 0}, {1.0f / 3, 0, 0}, {2.0f / 3, 1.0f / 3, 0}, {1, 1, 0}};
  for (int n = 1; n <= 8; ++n) {
    const double exact = 0.25 / (n * n);  // max of u(h - u) with h = 1/n, times c''/2 = 1
    const double bound = sffd::edge_bound(b[0], b[1], b[2], b[3], n);
    EXPECT_GE(bound, exact * (1 - 1e-6));
    EXPECT_LE(bound, exact * 1.0001);  // c''' = 0: the bound is the exact sagitta
  }
}

}  // namespace
