// Unit tests of polygon triangulation (mesh/triangulate.hpp): convex, concave, repeated
// vertices, degenerate polygons.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <map>
#include <set>
#include <unordered_map>

#include "smoothffd/core/cancel.hpp"
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

using Pts = std::vector<std::pair<double, double>>;

// The triangles tile the simple polygon `pts` (one face, corner i = vertex i) exactly: n - 2 of
// them, each counter-clockwise, every polygon edge used once in its own direction and every
// other edge once in each direction (so no triangle sticks out or overlaps another), and the
// areas add up to the polygon's.
void check_tiles_polygon(const Pts& pts, const Triangulation& tr) {
  const long long n = (long long)pts.size();
  ASSERT_EQ(tr.face.size(), (size_t)n - 2);
  std::unordered_map<long long, int> uses;
  double sum = 0;
  for (size_t t = 0; t < tr.face.size(); ++t) {
    const int* c = &tr.corners[3 * t];
    auto a = pts[c[0]], b = pts[c[1]], d = pts[c[2]];
    double area = 0.5 * ((b.first - a.first) * (d.second - a.second) - (b.second - a.second) * (d.first - a.first));
    ASSERT_GT(area, 0) << "triangle " << t << " is flat or outside the polygon";
    sum += area;
    for (int k = 0; k < 3; ++k) uses[c[k] * n + c[(k + 1) % 3]]++;
  }
  for (long long i = 0; i < n; ++i) {
    auto it = uses.find(i * n + (i + 1) % n);
    ASSERT_TRUE(it != uses.end() && it->second == 1) << "polygon edge " << i << " not used once";
    uses.erase(it);
  }
  for (auto& kv : uses) {
    ASSERT_EQ(kv.second, 1) << "an inner edge used twice in one direction";
    long long u = kv.first / n, v = kv.first % n;
    auto back = uses.find(v * n + u);
    ASSERT_TRUE(back != uses.end() && back->second == 1) << "inner edge " << u << "-" << v << " has one side";
  }
  EXPECT_NEAR(sum, shoelace(pts), 1e-10 * std::fabs(shoelace(pts)));  // rounding of 1e5 terms
}

// Large test polygons (counter-clockwise, simple).
Pts star_polygon(int n, double inner) {  // every other corner reflex
  Pts p;
  for (int i = 0; i < n; ++i) {
    double r = i % 2 ? inner : 1.0, t = 2 * M_PI * i / n;
    p.push_back({r * std::cos(t), r * std::sin(t)});
  }
  return p;
}
Pts comb_polygon(int teeth) {  // a base of height 0.1 with teeth of height 1: 4 teeth + 2 corners
  Pts p = {{0, 0}, {4.0 * teeth, 0}};
  for (int k = teeth - 1; k >= 0; --k) {
    double x0 = 4.0 * k, x1 = x0 + 2;
    p.insert(p.end(), {{x1, 0.1}, {x1, 1}, {x0, 1}, {x0, 0.1}});
  }
  return p;
}
Pts zigzag_polygon(int n) {  // two bottom corners, a top alternating between 1 and 0.5
  Pts p = {{0, 0}, {double(n - 3), 0}};
  for (int i = n - 3; i >= 0; --i) p.push_back({double(i), i % 2 ? 0.5 : 1.0});
  return p;
}
Pts spiral_polygon(int n) {  // a thick arm turning 6 times: long corridors
  Pts p;
  int h = n / 2;
  for (int i = 0; i < h; ++i) {
    double t = 12 * M_PI * i / (h - 1), r = 2 + 0.5 * t;
    p.push_back({r * std::cos(t), r * std::sin(t)});
  }
  for (int i = h - 1; i >= 0; --i) {
    double t = 12 * M_PI * i / (h - 1), r = 0.5 + 0.5 * t;
    p.push_back({r * std::cos(t), r * std::sin(t)});
  }
  return p;
}
Pts random_star_polygon(int n, unsigned seed) {  // radii uniform in [0.2, 1.2]
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> r(0.2, 1.2);
  Pts p;
  for (int i = 0; i < n; ++i) {
    double t = 2 * M_PI * i / n, ri = r(rng);
    p.push_back({ri * std::cos(t), ri * std::sin(t)});
  }
  return p;
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

// Polygons beyond 64 corners take the heap-and-k-d-tree ear clipper: the same contract, in
// O(n log n) for these shapes (the scan of the small polygons' clipper took 24-32 s for 128k
// corners). The times are printed, not asserted.
TEST(Triangulate, LargePolygonsTileTheirAreaInBoundedTime) {
  struct Case {
    const char* name;
    Pts pts;
  };
  std::vector<Case> cases = {
      {"star 128k", star_polygon(128000, 0.8)},   {"comb 128k", comb_polygon(32000)},
      {"zigzag 16k", zigzag_polygon(16000)},      {"spiral 16k", spiral_polygon(16000)},
      {"random star 16k", random_star_polygon(16000, 7)}, {"circle 16k", star_polygon(16000, 1.0)},
      {"star 65", star_polygon(65, 0.5)},         {"random star 200", random_star_polygon(200, 3)},
  };
  for (const Case& c : cases) {
    Poly2 p;
    p.add(c.pts);
    auto t0 = std::chrono::steady_clock::now();
    Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
    double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("  %-16s %7zu corners: %.3f s\n", c.name, c.pts.size(), s);
    SCOPED_TRACE(c.name);
    check_tiles_polygon(c.pts, tr);
  }
}

TEST(Triangulate, LargePolygonsOfManyShapesTile) {
  for (unsigned seed = 1; seed <= 20; ++seed) {
    std::mt19937 rng(seed);
    int n = 65 + (int)(rng() % 600);
    Pts pts = random_star_polygon(n, seed);
    if (seed % 2) std::reverse(pts.begin(), pts.end());  // clockwise: reversed back below
    Poly2 p;
    p.add(pts);
    Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
    check_contract(p, tr);
    if (seed % 2) {  // a clockwise polygon keeps its winding: check it mirrored
      for (auto& q : pts) q.second = -q.second;
    }
    SCOPED_TRACE(seed);
    check_tiles_polygon(pts, tr);
  }
}

TEST(Triangulate, LargeDegeneratePolygonsDoNotCrash) {
  Poly2 p;
  Pts line, point, bowtie, big, dup;
  for (int i = 0; i < 1000; ++i) line.push_back({double(i), 0});  // collinear
  for (int i = 0; i < 300; ++i) point.push_back({1, 1});            // one point, distinct ids
  for (int i = 0; i < 400; ++i)                                       // crossing zig-zags
    bowtie.push_back({double(i % 200), (i < 200) == (i % 2 == 0) ? 1.0 : -1.0});
  for (int i = 0; i < 100; ++i) {  // beyond double range in the cross products: NaN areas
    double t = 2 * M_PI * i / 100;
    big.push_back({1e300 * std::cos(t), 1e300 * std::sin(t)});
  }
  p.add(line);
  p.add(point);
  p.add(bowtie);
  p.add(big);
  // A 200-corner star whose corners each appear twice in a row but for a touching loop.
  Pts star = star_polygon(200, 0.6);
  p.add(star);
  std::vector<int> ids;
  for (int i = 0; i < 200; ++i) ids.insert(ids.end(), {p.cv[p.fo[4] + i], p.cv[p.fo[4] + i]});
  ids.insert(ids.end(), {p.cv[p.fo[4]], p.cv[p.fo[4] + 100]});  // back to 0, then to 100
  p.add_ids(ids);
  Triangulation tr = triangulate_polygons(p.X, p.cv, p.fo);
  check_contract(p, tr);
  std::vector<int> per_face(p.fo.size() - 1, 0);
  for (int f : tr.face) per_face[f]++;
  EXPECT_LE(per_face[0], 998);
  EXPECT_EQ(per_face[1], 298);  // distinct vertices at one point: flat triangles, all kept
  EXPECT_EQ(per_face[2], 398);
  EXPECT_LE(per_face[3], 98);
  EXPECT_EQ(per_face[4], 198);
  EXPECT_LE(per_face[5], 200);
}

// A cancel check installed in the calling thread stops a long triangulation (core/cancel.hpp);
// the next call, without one, gives the same triangles as an uncancelled run.
TEST(Triangulate, CancelStopsALargePolygon) {
  Poly2 p;
  p.add(random_star_polygon(16000, 11));
  Triangulation want = triangulate_polygons(p.X, p.cv, p.fo);
  int checks = 0;
  {
    CancelScope scope([&] { return ++checks >= 3; }, std::chrono::milliseconds(0));
    EXPECT_THROW(triangulate_polygons(p.X, p.cv, p.fo), Cancelled);
  }
  EXPECT_EQ(checks, 3);
  Triangulation again = triangulate_polygons(p.X, p.cv, p.fo);
  EXPECT_EQ(again.corners, want.corners);
}

// Suzanne's chin (Blender's monkey, vertices 70, 137, 138, 196, 197): two quads share three
// vertices. Each alone prefers the diagonal 70-138, which makes the same triangle in both, back
// to back (a fin whose edges have three and four faces). One of them takes its other diagonal.
TEST(Triangulate, FacesSharingThreeVerticesMakeNoDuplicateTriangle) {
  const std::vector<double> X = {0.0,       -0.796875, -0.1875,     // 0: vertex 70
                                 0.0,       -0.75,     -0.195312,   // 1: 137
                                 0.0,       -0.742188, -0.140625,   // 2: 138
                                 0.039062,  -0.78125,  -0.125,      // 3: 196
                                 -0.039062, -0.78125,  -0.125};     // 4: 197
  const std::vector<int> cv = {1, 0, 3, 2, 4, 0, 1, 2}, fo = {0, 4, 8};
  Triangulation tr = triangulate_polygons(X, cv, fo);
  ASSERT_EQ(tr.face.size(), 4u);
  std::set<std::vector<int>> sets;
  std::map<std::pair<int, int>, int> edge_faces;
  for (size_t t = 0; t < 4; ++t) {
    std::vector<int> k = {cv[tr.corners[3 * t]], cv[tr.corners[3 * t + 1]], cv[tr.corners[3 * t + 2]]};
    for (int e = 0; e < 3; ++e) edge_faces[{std::min(k[e], k[(e + 1) % 3]), std::max(k[e], k[(e + 1) % 3])}]++;
    std::sort(k.begin(), k.end());
    EXPECT_TRUE(sets.insert(k).second) << "triangle " << t << " repeats another's vertices";
  }
  for (auto& [e, n] : edge_faces) EXPECT_LE(n, 2) << "edge " << e.first << "-" << e.second;
  // Each face keeps its own corners: two triangles of its four.
  EXPECT_EQ(tr.face[0], 0);
  EXPECT_EQ(tr.face[1], 0);
  EXPECT_EQ(tr.face[2], 1);
  EXPECT_EQ(tr.face[3], 1);
}
