// Unit tests of the adjustment normals and their bound (plan/rest_surface.hpp): flat
// triangles follow their own plane, normals that fold a patch are blended toward the
// triangles' own, normals that fold nothing are kept.
#include <gtest/gtest.h>

#include <algorithm>
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

namespace {

double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// cof(J) v for J = Rz(a1) diag(s) Rx(a2) Rz(a3): the map of normals under a linear
// deformation with singular values s. cof(J) = det(J) J^-T = Rz(a1) diag(det / s) Rx(a2) Rz(a3)
// (R^-T = R for a rotation).
void cofactor_apply(double a1, double a2, double a3, const double s[3], const double* v, double* out) {
  const double c1 = std::cos(a1), s1 = std::sin(a1), c2 = std::cos(a2), s2 = std::sin(a2);
  const double c3 = std::cos(a3), s3 = std::sin(a3);
  const double z[3] = {c3 * v[0] - s3 * v[1], s3 * v[0] + c3 * v[1], v[2]};
  const double x[3] = {z[0], c2 * z[1] - s2 * z[2], s2 * z[1] + c2 * z[2]};
  const double d = s[0] * s[1] * s[2];
  const double w[3] = {d / s[0] * x[0], d / s[1] * x[1], d / s[2] * x[2]};
  out[0] = c1 * w[0] - s1 * w[1];
  out[1] = s1 * w[0] + c1 * w[1];
  out[2] = w[2];
}

}  // namespace

TEST(AdjustNormals, ShadingNormalsTheGeometryCannotFollowAreTurned) {
  // The folding cap of the test above, bounded: where a normal stays more than 53.13 degrees
  // (cos 0.6) from the adjustment normal its corner's geometry follows, it is turned toward
  // that normal onto the 53.13-degree cone, within the plane of the two; the others are kept.
  Case c = sphere_cap();
  c.normals = corner_normals(c, [](const double* p) { return unit(2.14 + p[0], p[1], p[2]); });
  EdgeTable e = build_edges(c.tv);
  std::vector<uint8_t> sharp = classify_sharp_ends(e, c.tv, c.normals, std::cos(M_PI / 180));
  AdjustNormals an(c.X, c.tv, c.normals, std::vector<uint8_t>(6, 0));
  RestSurface rs;
  ASSERT_GT(bound_adjust_normals(c.X, c.tv, e, sharp, c.normals, an, rs), 0);
  std::vector<double> render = c.normals;
  std::vector<uint8_t> marks(18, 0);
  const int turned = bound_render_normals(an, render, &marks);
  int far = 0;
  for (int q = 0; q < 18; ++q) {
    const double *n = &c.normals[3 * q], *a = &an.corner[3 * q], *r = &render[3 * q];
    const bool was_far = dot(n, a) < 0.6;
    far += was_far;
    EXPECT_EQ(marks[q], was_far) << q;
    if (!was_far) {
      for (int i = 0; i < 3; ++i) EXPECT_EQ(r[i], n[i]) << q;
      continue;
    }
    EXPECT_NEAR(dot(r, r), 1.0, 1e-14) << q;
    EXPECT_NEAR(dot(r, a), 0.6, 1e-14) << q;
    // In the plane of n and a, between them: the angles add up.
    EXPECT_NEAR(std::acos(dot(n, r)) + std::acos(dot(r, a)), std::acos(dot(n, a)), 1e-12) << q;
    // No linear map with condition number under 2 turns r and a 90 degrees apart (what the
    // deformed shading normal and the deformed geometry would be), in any orientation.
    const double s[3] = {1.0, 1.4, 1.99};
    double worst = 1;
    for (int i = 0; i < 12; ++i)
      for (int j = 0; j < 24; ++j)
        for (int k = 0; k < 24; ++k) {
          double cr[3], ca[3];
          cofactor_apply(i * M_PI / 12, j * M_PI / 12, k * M_PI / 12, s, r, cr);
          cofactor_apply(i * M_PI / 12, j * M_PI / 12, k * M_PI / 12, s, a, ca);
          worst = std::min(worst, dot(cr, ca) / std::sqrt(dot(cr, cr) * dot(ca, ca)));
        }
    EXPECT_GT(worst, 0.0) << q;
  }
  EXPECT_EQ(turned, far);
  EXPECT_GT(far, 0);
  // Turned normals are at the limit: a second call turns nothing.
  EXPECT_EQ(bound_render_normals(an, render, nullptr), 0);
}
