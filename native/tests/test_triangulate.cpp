// Unit tests of polygon triangulation (mesh/triangulate.hpp): convex, concave, repeated
// vertices, degenerate polygons.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "smoothffd/mesh/triangulate.hpp"
#include "test_util.hpp"

using namespace sffd;

namespace {

// Polygons given as 2D points in the plane z = 0.5 (counter-clockwise = normal +z).
struct Poly2 {
  std::vector<double> X;
  std::vector<int> cv, fo{0};
  void add(const std::vector<std::pair<double, double>>& pts) {
    for (auto& p : pts) {
      cv.push_back((int)X.size() / 3);
      X.insert(X.end(), {p.first, p.second, 0.5});
    }
    fo.push_back((int)cv.size());
  }
  // Corner list reusing existing vertex ids.
  void add_ids(const std::vector<int>& ids) {
    cv.insert(cv.end(), ids.begin(), ids.end());
    fo.push_back((int)cv.size());
  }
};

double signed_area_z(const std::vector<double>& X, int a, int b, int c) {
  const double *p = &X[3 * a], *q = &X[3 * b], *r = &X[3 * c];
  return 0.5 * ((q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]));
}

double shoelace(const std::vector<std::pair<double, double>>& pts) {
  double s = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    auto a = pts[i], b = pts[(i + 1) % pts.size()];
    s += a.first * b.second - b.first * a.second;
  }
  return 0.5 * s;
}

// Checks the basic contract: every triangle belongs to its face, uses corners of that face
// and three distinct vertices.
void check_contract(const Poly2& p, const Triangulation& tr) {
  ASSERT_EQ(tr.corners.size(), 3 * tr.face.size());
  for (size_t t = 0; t < tr.face.size(); ++t) {
    int f = tr.face[t];
    ASSERT_GE(f, 0);
    ASSERT_LT(f + 1, (int)p.fo.size());
    std::set<int> verts;
    for (int k = 0; k < 3; ++k) {
      int c = tr.corners[3 * t + k];
      EXPECT_GE(c, p.fo[f]);
      EXPECT_LT(c, p.fo[f + 1]);
      verts.insert(p.cv[c]);
    }
    EXPECT_EQ(verts.size(), 3u) << "triangle " << t << " repeats a vertex";
  }
}

}  // namespace

TEST(Triangulate, ConvexQuadAndPentagon) {
  Poly2 p;
  p.add({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
  p.add({{0, 0}, {2, 0}, {3, 1}, {1, 2}, {-1, 1}});
  Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
  check_contract(p, tr);
  ASSERT_EQ(tr.face.size(), 2u + 3u);
  double area[2] = {0, 0};
  for (size_t t = 0; t < tr.face.size(); ++t) {
    double a = signed_area_z(p.X, p.cv[tr.corners[3 * t]], p.cv[tr.corners[3 * t + 1]],
                             p.cv[tr.corners[3 * t + 2]]);
    EXPECT_GT(a, 0) << "winding of the polygon must be kept";
    area[tr.face[t]] += a;
  }
  EXPECT_NEAR(area[0], 1.0, 1e-14);
  EXPECT_NEAR(area[1], shoelace({{0, 0}, {2, 0}, {3, 1}, {1, 2}, {-1, 1}}), 1e-13);
}

TEST(Triangulate, ConcavePolygonsCoverTheirAreaOnce) {
  std::vector<std::vector<std::pair<double, double>>> polys = {
      {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}},                  // L shape
      {{0, 0}, {4, 0}, {4, 3}, {3, 3}, {3, 1}, {1, 1}, {1, 3}, {0, 3}},  // U shape
      {{0, 0}, {2, 1}, {4, 0}, {2, 3}},                                  // dart (arrowhead)
  };
  // Star with 40 spikes (80 corners, every other one reflex).
  std::vector<std::pair<double, double>> star;
  for (int i = 0; i < 80; ++i) {
    double r = i % 2 ? 0.3 : 1.0, t = 2 * M_PI * i / 80;
    star.push_back({r * std::cos(t), r * std::sin(t)});
  }
  polys.push_back(star);
  for (auto& pts : polys) {
    Poly2 p;
    p.add(pts);
    Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
    check_contract(p, tr);
    ASSERT_EQ(tr.face.size(), pts.size() - 2) << pts.size() << "-gon";
    double sum = 0;
    for (size_t t = 0; t < tr.face.size(); ++t) {
      double a = signed_area_z(p.X, p.cv[tr.corners[3 * t]], p.cv[tr.corners[3 * t + 1]],
                               p.cv[tr.corners[3 * t + 2]]);
      EXPECT_GT(a, 0) << "an ear outside the polygon (" << pts.size() << "-gon)";
      sum += a;
    }
    EXPECT_NEAR(sum, shoelace(pts), 1e-12) << pts.size() << "-gon";
  }
}

TEST(Triangulate, ClockwisePolygonKeepsItsWinding) {
  Poly2 p;
  p.add({{0, 2}, {1, 2}, {1, 1}, {2, 1}, {2, 0}, {0, 0}});  // clockwise L: normal -z
  Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
  check_contract(p, tr);
  ASSERT_EQ(tr.face.size(), 4u);
  for (size_t t = 0; t < tr.face.size(); ++t)
    EXPECT_LT(signed_area_z(p.X, p.cv[tr.corners[3 * t]], p.cv[tr.corners[3 * t + 1]],
                            p.cv[tr.corners[3 * t + 2]]), 0);
}

TEST(Triangulate, RepeatedVertices) {
  Poly2 p;
  p.add({{0, 0}, {1, 0}, {1, 1}, {0, 1}});  // vertices 0..3
  p.add_ids({0, 1, 1, 2, 3});               // consecutive repeat: a quad
  p.add_ids({0, 1, 2, 0});                  // closing repeat: a triangle
  p.add_ids({2, 2, 2});                     // one vertex: nothing
  p.add_ids({0, 1, 0});                     // two vertices: nothing
  p.add_ids({0, 1, 2, 0, 2, 3});            // non-consecutive repeat (touching loops)
  Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
  check_contract(p, tr);
  int per_face[6] = {0, 0, 0, 0, 0, 0};
  for (int f : tr.face) per_face[f]++;
  EXPECT_EQ(per_face[0], 2);
  EXPECT_EQ(per_face[1], 2);
  EXPECT_EQ(per_face[2], 1);
  EXPECT_EQ(per_face[3], 0);
  EXPECT_EQ(per_face[4], 0);
  EXPECT_LE(per_face[5], 4);
}

TEST(Triangulate, DegeneratePolygonsDoNotCrash) {
  Poly2 p;
  p.add({{0, 0}, {1, 0}, {2, 0}, {3, 0}});                   // collinear
  p.add({{0, 0}, {0, 0}, {0, 0}, {0, 0}});                   // one point, distinct ids
  p.add({{0, 0}, {1, 0}, {1, 1e-300}, {0, 1e-300}});         // zero area in double
  p.add({{0, 0}, {2, 2}, {2, 0}, {0, 2}});                   // self-intersecting bow tie
  p.add({{0, 0}, {1e12, 0}, {1e12, 1e-12}, {0, 1}});         // extreme aspect
  Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
  check_contract(p, tr);
  int per_face[5] = {0, 0, 0, 0, 0};
  for (int f : tr.face) per_face[f]++;
  for (int f = 0; f < 5; ++f) EXPECT_LE(per_face[f], 2) << "face " << f;
  // Every corner of a non-degenerate quad ends up in some triangle.
  EXPECT_EQ(per_face[3], 2);
}

TEST(Triangulate, NonPlanarPolygonUsesNewellPlane) {
  // A quad in 3D (twisted) and a hexagon in a tilted plane.
  std::vector<double> X = {0, 0, 0, 1, 0, 0.2, 1, 1, 0, 0, 1, 0.2};
  for (int i = 0; i < 6; ++i) {
    double t = 2 * M_PI * i / 6;
    X.insert(X.end(), {std::cos(t), std::sin(t) * 0.6, std::sin(t) * 0.8});
  }
  std::vector<int> cv = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9}, fo = {0, 4, 10};
  Triangulation tr = triangulate_polygons(X, cv, fo);
  ASSERT_EQ(tr.face.size(), 2u + 4u);
  double area = 0;
  for (size_t t = 0; t < tr.face.size(); ++t)
    if (tr.face[t] == 1)
      area += sffd_test::tri_area(&X[3 * cv[tr.corners[3 * t]]], &X[3 * cv[tr.corners[3 * t + 1]]],
                                  &X[3 * cv[tr.corners[3 * t + 2]]]);
  EXPECT_NEAR(area, 1.5 * std::sqrt(3.0), 1e-12);  // regular hexagon of radius 1
}

TEST(Triangulate, EmptyInput) {
  Triangulation tr = triangulate_polygons({}, {}, {0});
  EXPECT_TRUE(tr.face.empty());
  EXPECT_TRUE(tr.corners.empty());
}
