// Unit tests of the adjustment normals and their bound (plan/rest_surface.hpp): flat
// triangles follow their own plane, normals that fold a patch are blended toward the
// triangles' own, normals that fold nothing are kept.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "smoothffd/plan/bezier.hpp"
#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/rest_surface.hpp"

using namespace sffd;

namespace {

struct Case {
  std::vector<double> X;
  std::vector<int> tv;
  std::vector<double> normals;  // #T x 3 x 3
};

std::vector<double> unit(double x, double y, double z) {
  double l = std::sqrt(x * x + y * y + z * z);
  return {x / l, y / l, z / l};
}

// Every corner's normal: f(vertex position).
template <class F>
std::vector<double> corner_normals(const Case& c, F f) {
  std::vector<double> n;
  for (int v : c.tv) {
    std::vector<double> x = f(&c.X[3 * (size_t)v]);
    n.insert(n.end(), x.begin(), x.end());
  }
  return n;
}

// A fan of 6 triangles around vertex 0 on the sphere of radius 1 (a cap), outward.
Case sphere_cap() {
  Case c;
  c.X = {0, 0, 1};
  for (int k = 0; k < 6; ++k) {
    double a = k * M_PI / 3, r = std::sin(0.5);
    c.X.insert(c.X.end(), {r * std::cos(a), r * std::sin(a), std::cos(0.5)});
  }
  for (int k = 0; k < 6; ++k) c.tv.insert(c.tv.end(), {0, 1 + k, 1 + (k + 1) % 6});
  return c;
}

bool any_folds(const Case& c, const EdgeTable& e, const RestSurface& rs) {
  for (size_t t = 0; t < c.tv.size() / 3; ++t) {
    double cp[10][3];
    rest_patch(rs, c.X, c.tv, e, (int)t, cp);
    if (rest_patch_folds(cp, &c.normals[9 * t])) return true;
  }
  return false;
}

}  // namespace

TEST(AdjustNormals, GoodNormalsAreKept) {
  Case c = sphere_cap();
  c.normals = corner_normals(c, [](const double* p) { return unit(p[0], p[1], p[2]); });
  EdgeTable e = build_edges(c.tv);
  std::vector<uint8_t> sharp = classify_sharp_ends(e, c.tv, c.normals, std::cos(M_PI / 180));
  AdjustNormals an(c.X, c.tv, c.normals, std::vector<uint8_t>(6, 0));
  RestSurface rs;
  EXPECT_EQ(bound_adjust_normals(c.X, c.tv, e, sharp, c.normals, an, rs), 0);
  EXPECT_EQ(an.corner, c.normals);
}

TEST(AdjustNormals, FoldingNormalsAreBlendedTowardTheTriangles) {
  // The cap's normals all tilted about 65 degrees toward +x: the PN patches fold.
  Case c = sphere_cap();
  c.normals = corner_normals(c, [](const double* p) { return unit(2.14 + p[0], p[1], p[2]); });
  EdgeTable e = build_edges(c.tv);
  std::vector<uint8_t> sharp = classify_sharp_ends(e, c.tv, c.normals, std::cos(M_PI / 180));
  AdjustNormals an(c.X, c.tv, c.normals, std::vector<uint8_t>(6, 0));
  ASSERT_TRUE(any_folds(c, e, build_rest_surface(c.X, c.tv, e, sharp, an.corner)));
  RestSurface rs;
  EXPECT_GT(bound_adjust_normals(c.X, c.tv, e, sharp, c.normals, an, rs), 0);
  for (double t : an.trust) EXPECT_TRUE(t >= 0.0 && t <= 1.0);
  // What still folds is a flat triangle (its vertices' trust 0) whose own normals lie more than
  // the margin from its flat triangle: those cannot do better.
  int unfolded = 0;
  for (size_t t = 0; t < 6; ++t) {
    double cp[10][3];
    rest_patch(rs, c.X, c.tv, e, (int)t, cp);
    if (!rest_patch_folds(cp, &c.normals[9 * t])) {
      ++unfolded;
      continue;
    }
    double flat[10][3];
    for (int k = 0; k < 10; ++k) {
      int ex[3];
      cubic_exponents(k, ex);
      for (int i = 0; i < 3; ++i) {
        flat[k][i] = 0;
        for (int q = 0; q < 3; ++q) flat[k][i] += ex[q] / 3.0 * c.X[3 * (size_t)c.tv[3 * t + q] + i];
      }
    }
    EXPECT_TRUE(rest_patch_folds(flat, &c.normals[9 * t])) << t;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(an.trust[c.tv[3 * t + k]], 0.0) << t;
  }
  EXPECT_GE(unfolded, 3);
}

TEST(AdjustNormals, FlatNonPlanarQuadStaysItsTwoTriangles) {
  // A quad with one corner lifted, both triangles carrying the quad's (Newell) normal, as
  // Blender's flat shading gives them: each triangle follows its own plane, every rest
  // surface point is the point of the flat triangle.
  Case c;
  c.X = {0, 0, 0, 1, 0, 0.15, 1, 1, 0, 0, 1, 0};
  c.tv = {0, 1, 2, 0, 2, 3};
  std::vector<double> quad = unit(-0.15, 0.15, 1.0);  // (x2 - x0) x (x3 - x1), normalised
  for (int i = 0; i < 6; ++i) c.normals.insert(c.normals.end(), quad.begin(), quad.end());
  EdgeTable e = build_edges(c.tv);
  std::vector<uint8_t> sharp = classify_sharp_ends(e, c.tv, c.normals, std::cos(M_PI / 180));
  AdjustNormals an(c.X, c.tv, c.normals, std::vector<uint8_t>(2, 1));
  RestSurface rs;
  EXPECT_EQ(bound_adjust_normals(c.X, c.tv, e, sharp, c.normals, an, rs), 0);
  for (int t = 0; t < 2; ++t) {
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) EXPECT_EQ(an.corner[9 * t + 3 * k + i], an.own[3 * t + i]);
    for (double b0 : {0.0, 0.2, 0.5, 0.9})
      for (double b1 : {0.0, 0.1, 0.5}) {
        if (b0 + b1 > 1) continue;
        const double b[3] = {b0, b1, 1 - b0 - b1};
        double x[3];
        rest_surface_point(rs, c.X, c.tv, e, t, b, x);
        for (int i = 0; i < 3; ++i) {
          double flat = 0;
          for (int k = 0; k < 3; ++k) flat += b[k] * c.X[3 * (size_t)c.tv[3 * t + k] + i];
          EXPECT_NEAR(x[i], flat, 1e-15);
        }
      }
  }
}
