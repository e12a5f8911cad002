// Unit tests of knot-box clipping (plan/clip.hpp): a watertight sub-mesh, clip vertices shared
// across shared edges, triangles lying in a knot plane, vertices exactly on (or within
// rounding of) planes, degenerate triangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "smoothffd/plan/clip.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

ClipResult clip(const InputMesh& m, const LatticeSpec& s) {
  // clip_to_knot_boxes takes triangles: the test meshes here are triangle meshes.
  return clip_to_knot_boxes(m.positions, m.corner_vertex, s);
}

const double* P(const ClipResult& c, int v) { return &c.flat[3 * (size_t)v]; }

double patch_area(const ClipResult& c, int p) {
  return tri_area(P(c, c.patch_vertex[3 * p]), P(c, c.patch_vertex[3 * p + 1]),
                  P(c, c.patch_vertex[3 * p + 2]));
}

double input_area(const InputMesh& m) {
  double a = 0;
  for (size_t t = 0; t < m.corner_vertex.size(); t += 3)
    a += tri_area(&m.positions[3 * m.corner_vertex[t]], &m.positions[3 * m.corner_vertex[t + 1]],
                  &m.positions[3 * m.corner_vertex[t + 2]]);
  return a;
}

// Every patch lies in one knot box: on each axis, all its corners fall between two
// consecutive planes (parameter space), but for the snap distance of its corners (clip.hpp).
void expect_one_box_each(const ClipResult& c, const LatticeSpec& s) {
  ASSERT_EQ(c.snap.size(), (size_t)c.sub_vertices());
  for (int p = 0; p < c.patches(); ++p)
    for (int a = 0; a < 3; ++a) {
      std::vector<double> planes = s.axes[a].planes();
      const double* A = s.object_to_param[a];
      double grad = std::sqrt(A[0] * A[0] + A[1] * A[1] + A[2] * A[2]), snap = 0;
      double lo = INFINITY, hi = -INFINITY;
      for (int k = 0; k < 3; ++k) {
        double prm[3];
        s.to_param(P(c, c.patch_vertex[3 * p + k]), prm);
        lo = std::min(lo, prm[a]);
        hi = std::max(hi, prm[a]);
        snap = std::max(snap, c.snap[c.patch_vertex[3 * p + k]] * grad);
      }
      for (double pl : planes)
        EXPECT_FALSE(pl > lo + snap + 1e-9 && pl < hi - snap - 1e-9)
            << "patch " << p << " straddles plane " << pl << " of axis " << a;
    }
}

// The bookkeeping agrees with the geometry: clip vertices are the barycentric point of their
// origin triangle, patch corners the barycentric point of their patch's triangle.
void expect_consistent(const ClipResult& c, const InputMesh& m) {
  const int V = (int)m.positions.size() / 3;
  ASSERT_EQ(c.flat.size(), 3 * (size_t)c.sub_vertices());
  ASSERT_EQ(c.origin_bary.size(), 3 * (size_t)c.sub_vertices());
  ASSERT_EQ(c.patch_vertex.size(), 3 * (size_t)c.patches());
  ASSERT_EQ(c.patch_bary.size(), 9 * (size_t)c.patches());
  auto bary_point = [&](int t, const double* b, double* x) {
    for (int i = 0; i < 3; ++i) {
      x[i] = 0;
      for (int k = 0; k < 3; ++k) x[i] += b[k] * m.positions[3 * (size_t)m.corner_vertex[3 * t + k] + i];
    }
  };
  for (int v = 0; v < c.sub_vertices(); ++v) {
    if (v < V) {
      EXPECT_EQ(c.origin_tri[v], -1);
      continue;
    }
    int t = c.origin_tri[v];
    ASSERT_GE(t, 0);
    double x[3];
    bary_point(t, &c.origin_bary[3 * (size_t)v], x);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(x[i], P(c, v)[i], 1e-12);
  }
  for (int p = 0; p < c.patches(); ++p)
    for (int k = 0; k < 3; ++k) {
      int v = c.patch_vertex[3 * p + k];
      ASSERT_GE(v, 0);
      ASSERT_LT(v, c.sub_vertices());
      double x[3];
      bary_point(c.patch_tri[p], &c.patch_bary[9 * (size_t)p + 3 * k], x);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(x[i], P(c, v)[i], 1e-12);
    }
}

// Closed input: every sub-edge has exactly two patches with opposite directions, no two
// sub-vertices coincide, and the Euler characteristic is unchanged.
void expect_closed_watertight(const ClipResult& c, int euler) {
  EdgeCounts e = count_edges(c.patch_vertex);
  for (auto& kv : e.undirected)
    EXPECT_EQ(kv.second, 2) << "sub-edge " << kv.first.first << "-" << kv.first.second;
  for (auto& kv : e.directed) EXPECT_EQ(kv.second, 1) << "inconsistent winding";
  std::set<int> used(c.patch_vertex.begin(), c.patch_vertex.end());
  EXPECT_EQ((int)used.size() - (int)e.undirected.size() + c.patches(), euler);
  std::set<std::array<double, 3>> pos;
  for (int v : used) pos.insert({P(c, v)[0], P(c, v)[1], P(c, v)[2]});
  EXPECT_EQ(pos.size(), used.size()) << "duplicated clip vertices (a crack)";
}

}  // namespace

TEST(Clip, OffsetOctahedronIsWatertight) {
  for (auto spec : {bspline_box(2, 4), bspline_box(3, 8), bspline_box(1, 7)}) {
    InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
    ClipResult c = clip(m, spec);
    EXPECT_GT(c.patches(), 8);
    expect_consistent(c, m);
    expect_closed_watertight(c, 2);
    expect_one_box_each(c, spec);
    double a = 0;
    for (int p = 0; p < c.patches(); ++p) a += patch_area(c, p);
    EXPECT_NEAR(a, input_area(m), 1e-12);
  }
}

TEST(Clip, CentredOctahedronVerticesOnPlanes) {
  // Every vertex lies on two of the planes x, y, z = 0.5: no triangle is crossed.
  InputMesh m = octahedron(0.5, 0.5, 0.5, 0.4);
  ClipResult c = clip(m, bspline_box(2, 4));
  EXPECT_EQ(c.sub_vertices(), 6);
  EXPECT_EQ(c.patches(), 8);
  expect_closed_watertight(c, 2);
}

TEST(Clip, ClosedQuadCubeAcrossManyPlanes) {
  // The cube's quads split into triangles by hand (clip works on triangles).
  InputMesh q = cube_quads(0.13, 0.91);
  std::vector<int> tris;
  for (int f = 0; f < 6; ++f) {
    const int* c = &q.corner_vertex[4 * f];
    tris.insert(tris.end(), {c[0], c[1], c[2], c[0], c[2], c[3]});
  }
  InputMesh m = tri_mesh(q.positions, tris);
  LatticeSpec spec = bspline_box(3, 9);
  ClipResult c = clip(m, spec);
  expect_consistent(c, m);
  expect_closed_watertight(c, 2);
  expect_one_box_each(c, spec);
}

TEST(Clip, SharedEdgeGetsOneClipVertex) {
  // Two triangles sharing the diagonal; the plane x = 0.5 crosses bottom, top and diagonal.
  InputMesh m = tri_mesh({0.1, 0.1, 0.3, 0.9, 0.1, 0.3, 0.9, 0.4, 0.3, 0.1, 0.4, 0.3},
                         {0, 1, 2, 0, 2, 3});
  ClipResult c = clip(m, bspline_box(2, 4));
  EXPECT_EQ(c.sub_vertices(), 4 + 3);
  expect_consistent(c, m);
  EdgeCounts e = count_edges(c.patch_vertex);
  int interior = 0;
  for (auto& kv : e.undirected) {
    EXPECT_LE(kv.second, 2);
    interior += kv.second == 2;
  }
  for (auto& kv : e.directed) EXPECT_EQ(kv.second, 1);
  std::set<int> used(c.patch_vertex.begin(), c.patch_vertex.end());
  EXPECT_EQ((int)used.size() - (int)e.undirected.size() + c.patches(), 1);  // a disk
  EXPECT_GE(interior, 2);  // the two halves of the diagonal at least
}

TEST(Clip, TriangleLyingInAKnotPlane) {
  // All three vertices on z = 0.5 (a knot plane); the triangle spans x = 0.5 and y = 0.5.
  InputMesh m = tri_mesh({0.1, 0.1, 0.5, 0.9, 0.2, 0.5, 0.3, 0.85, 0.5}, {0, 1, 2});
  LatticeSpec spec = bspline_box(2, 4);
  ClipResult c = clip(m, spec);
  EXPECT_GE(c.patches(), 3);
  expect_consistent(c, m);
  expect_one_box_each(c, spec);
  for (int v = 0; v < c.sub_vertices(); ++v) EXPECT_EQ(P(c, v)[2], 0.5);
  double a = 0;
  for (int p = 0; p < c.patches(); ++p) a += patch_area(c, p);
  EXPECT_NEAR(a, input_area(m), 1e-13);
}

TEST(Clip, FlatGridOnPlanesIsWatertight) {
  // Grid lines coincide with knot planes (x, y in {0, .25, .5, .75, 1}); z on a plane too.
  InputMesh m = flat_grid(4, 0.0, 1.0, 0.5);
  LatticeSpec spec = bspline_box(2, 6);  // planes at 0, .25, .5, .75, 1
  ClipResult c = clip(m, spec);
  EXPECT_EQ(c.sub_vertices(), 25);
  EXPECT_EQ(c.patches(), 32);
  // A finer lattice: planes at multiples of 1/8 cut every triangle.
  LatticeSpec fine = bspline_box(1, 9);
  ClipResult f = clip(m, fine);
  expect_consistent(f, m);
  expect_one_box_each(f, fine);
  EdgeCounts e = count_edges(f.patch_vertex);
  double boundary = 0;
  for (auto& kv : e.undirected) {
    EXPECT_LE(kv.second, 2);
    if (kv.second == 1) {
      const double *a = P(f, kv.first.first), *b = P(f, kv.first.second);
      boundary += std::hypot(a[0] - b[0], a[1] - b[1]);
    }
  }
  EXPECT_NEAR(boundary, 4.0, 1e-12);  // no crack inside: only the outer square is open
  std::set<int> used(f.patch_vertex.begin(), f.patch_vertex.end());
  EXPECT_EQ((int)used.size() - (int)e.undirected.size() + f.patches(), 1);
}

TEST(Clip, VertexExactlyOnAPlane) {
  // Vertex 0 on x = 0.5, the others on either side; y, z stay inside one knot span.
  InputMesh m = tri_mesh({0.5, 0.1, 0.3, 0.8, 0.4, 0.3, 0.2, 0.45, 0.3}, {0, 1, 2});
  ClipResult c = clip(m, bspline_box(2, 4));
  ASSERT_EQ(c.sub_vertices(), 4);  // one crossing, on edge 1-2
  ASSERT_EQ(c.patches(), 2);
  for (int p = 0; p < 2; ++p) {
    std::set<int> vs(c.patch_vertex.begin() + 3 * p, c.patch_vertex.begin() + 3 * p + 3);
    EXPECT_TRUE(vs.count(0) && vs.count(3));
  }
  EXPECT_NEAR(P(c, 3)[0], 0.5, 1e-15);
}

TEST(Clip, VertexWithinRoundingOfAPlaneMakesNoSliver) {
  for (double eps : {1e-17, 1e-15, 1e-13, -1e-13, -1e-15}) {
    InputMesh m = tri_mesh({0.5 + eps, 0.1, 0.3, 0.8, 0.4, 0.3, 0.2, 0.45, 0.3}, {0, 1, 2});
    ClipResult c = clip(m, bspline_box(2, 4));
    expect_consistent(c, m);
    double total = input_area(m);
    for (int p = 0; p < c.patches(); ++p)
      EXPECT_GT(patch_area(c, p), 1e-6 * total) << "sliver at eps " << eps;
  }
}

TEST(Clip, DegenerateTrianglesDoNotCrash) {
  // Collinear, repeated-vertex and zero-size triangles crossing planes.
  InputMesh m = tri_mesh({0.1, 0.1, 0.1, 0.9, 0.9, 0.9, 0.5, 0.5, 0.5, 0.3, 0.7, 0.2},
                         {0, 1, 2, 0, 1, 1, 3, 3, 3, 0, 2, 1});
  LatticeSpec spec = bspline_box(3, 8);
  ClipResult c = clip(m, spec);
  expect_consistent(c, m);
  for (int p = 0; p < c.patches(); ++p) EXPECT_NEAR(patch_area(c, p), 0.0, 1e-12);
  for (double x : c.flat) EXPECT_TRUE(std::isfinite(x));
}

TEST(Clip, OutsideTheLatticeIsNotClippedBeyondIt) {
  // A triangle far outside the box on x: only the y/z planes it crosses (none here) apply.
  InputMesh m = tri_mesh({5.0, 0.1, 0.1, 7.0, 0.2, 0.1, 6.0, 0.3, 0.2}, {0, 1, 2});
  ClipResult c = clip(m, bspline_box(2, 4));
  EXPECT_EQ(c.patches(), 1);
  EXPECT_EQ(c.sub_vertices(), 3);
}

namespace {

// Smallest angle (degrees) of a flat triangle.
double min_angle(const double* a, const double* b, const double* c) {
  const double* p[3] = {a, b, c};
  double m = 180;
  for (int k = 0; k < 3; ++k) {
    const double *o = p[k], *u = p[(k + 1) % 3], *w = p[(k + 2) % 3];
    double e1[3], e2[3];
    for (int i = 0; i < 3; ++i) {
      e1[i] = u[i] - o[i];
      e2[i] = w[i] - o[i];
    }
    double cr[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double dt = e1[0] * e2[0] + e1[1] * e2[1] + e1[2] * e2[2];
    m = std::min(m, std::atan2(std::sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]), dt) * 180 / M_PI);
  }
  return m;
}

double patches_min_angle(const ClipResult& c) {
  double m = 180;
  for (int p = 0; p < c.patches(); ++p)
    m = std::min(m, min_angle(P(c, c.patch_vertex[3 * p]), P(c, c.patch_vertex[3 * p + 1]),
                              P(c, c.patch_vertex[3 * p + 2])));
  return m;
}

}  // namespace

TEST(Clip, PlaneNearAVertexCutsThroughIt) {
  // x = 0.5 crosses the edges at vertex 0 at 1% and 3% of their length (before: a tiny corner
  // piece and a needle of about 0.3 degrees beside it): the plane goes through vertex 0.
  for (double f : {0.01, 0.03}) {
    InputMesh m = tri_mesh({0.5 - 0.6 * f, 0.2, 0.3, 0.9 - 0.6 * f, 0.1, 0.3, 0.9 - 0.6 * f, 0.45, 0.3}, {0, 1, 2});
    ClipResult c = clip(m, bspline_box(2, 4));
    expect_consistent(c, m);
    expect_one_box_each(c, bspline_box(2, 4));
    EXPECT_EQ(c.sub_vertices(), 3) << f;  // no clip vertex: the triangle lies (within snap) beyond the plane
    EXPECT_EQ(c.patches(), 1) << f;
  }
  // Three vertices, the plane 2% from vertex 0 along edge 0-1 only: the cut runs from vertex 0.
  InputMesh m = tri_mesh({0.49, 0.2, 0.3, 0.99, 0.1, 0.3, 0.3, 0.45, 0.3}, {0, 1, 2});
  ClipResult c = clip(m, bspline_box(2, 4));
  expect_consistent(c, m);
  EXPECT_EQ(c.sub_vertices(), 4);  // one crossing, on edge 1-2
  EXPECT_EQ(c.patches(), 2);
  EXPECT_GT(patches_min_angle(c), 5.0);
}

TEST(Clip, CutsCloseTogetherOnAnEdgeMerge) {
  // The planes x = 0.5 and y = 0.5 cross the bottom edge 0.4% of its length apart: the second
  // passes through the first's clip vertex instead of cutting a sliver beside it.
  InputMesh m = tri_mesh({0.1, 0.1, 0.3, 0.9, 0.898, 0.3, 0.2, 0.9, 0.3}, {0, 1, 2});
  LatticeSpec spec = bspline_box(2, 4);
  ClipResult c = clip(m, spec);
  expect_consistent(c, m);
  expect_one_box_each(c, spec);
  for (int p = 0; p < c.patches(); ++p) EXPECT_GT(patch_area(c, p), 1e-3 * input_area(m)) << p;
  EXPECT_GT(patches_min_angle(c), 1.0);
}

TEST(Clip, SnappingKeepsRandomMeshesWatertight) {
  // Octahedra subdivided and jittered, under lattices whose planes fall near their vertices
  // and edges at every scale: watertight, area kept, pieces within their snap of one box, and
  // no needles beyond the snapping bound.
  std::srand(19);
  auto rnd = [] { return std::rand() / (RAND_MAX + 1.0); };
  double worst = 1;
  for (int trial = 0; trial < 400; ++trial) {
    InputMesh m = octahedron(0.5 + 0.1 * rnd(), 0.5 + 0.1 * rnd(), 0.5 + 0.1 * rnd(), 0.3 + 0.1 * rnd());
    // One 1-to-4 split, then jitter.
    std::map<std::pair<int, int>, int> mid;
    std::vector<int> T;
    auto midpoint = [&](int a, int b) {
      auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      int id = (int)m.positions.size() / 3;
      for (int i = 0; i < 3; ++i) m.positions.push_back(0.5 * (m.positions[3 * a + i] + m.positions[3 * b + i]));
      mid[key] = id;
      return id;
    };
    for (size_t t = 0; t < m.corner_vertex.size(); t += 3) {
      int a = m.corner_vertex[t], b = m.corner_vertex[t + 1], cc = m.corner_vertex[t + 2];
      int ab = midpoint(a, b), bc = midpoint(b, cc), ca = midpoint(cc, a);
      T.insert(T.end(), {a, ab, ca, b, bc, ab, cc, ca, bc, ab, bc, ca});
    }
    for (double& x : m.positions) x += 0.02 * (rnd() - 0.5);
    m = tri_mesh(m.positions, T);
    LatticeSpec spec = bspline_box(1 + trial % 3, 4 + trial % 7);
    SCOPED_TRACE("trial " + std::to_string(trial));
    ClipResult c = clip(m, spec);
    expect_consistent(c, m);
    expect_closed_watertight(c, 2);
    expect_one_box_each(c, spec);
    double a = 0;
    for (int p = 0; p < c.patches(); ++p) a += patch_area(c, p);
    EXPECT_NEAR(a, input_area(m), 1e-12);
    double in_angle = 180;
    for (size_t t = 0; t < T.size(); t += 3)
      in_angle = std::min(in_angle, min_angle(&m.positions[3 * T[t]], &m.positions[3 * T[t + 1]], &m.positions[3 * T[t + 2]]));
    // A cut crosses an input edge no nearer than kClipEdgeSnap of its length to an end, and a
    // segment no nearer than kClipSnap of its length to a clip vertex; what is left are thin
    // strips where a plane runs nearly parallel to an edge, their angle about the snap times the
    // input's angle (the worst of these 400 trials: 1/154 of the input's smallest angle in the
    // release build, 1/244 in the sanitizer build, whose rounding snaps other cuts).
    worst = std::min(worst, patches_min_angle(c) / in_angle);
    if (HasFailure()) break;
  }
  std::printf("smallest angle / input's smallest angle: 1/%.0f\n", 1 / worst);
  EXPECT_GT(worst, kClipEdgeSnap / 20);
}

TEST(Clip, FinePlanesSnapOnePlaneAnAxisToAVertex) {
  // A triangle across 100 planes an axis, vertices 0.3 and 0.7 plane spacings off a plane:
  // each vertex snaps to its nearest plane at most (a fan of cuts through one vertex would cut
  // needles between them), and the pieces are the strips and boxes the planes make.
  for (double off : {0.3, 0.7}) {
    const double h = 1.0 / 100;
    InputMesh m = tri_mesh({0.05 + off * h, 0.07 + off * h, 0.5, 0.95 + off * h, 0.11 + off * h, 0.5,
                            0.41 + off * h, 0.93 + off * h, 0.5},
                           {0, 1, 2});
    LatticeSpec spec = bspline_box(1, 101);
    ClipResult c = clip(m, spec);
    expect_consistent(c, m);
    expect_one_box_each(c, spec);
    double a = 0;
    for (int p = 0; p < c.patches(); ++p) a += patch_area(c, p);
    EXPECT_NEAR(a, input_area(m), 1e-12);
    double in_angle = min_angle(&m.positions[0], &m.positions[3], &m.positions[6]);
    // 4.1 and 8.0 degrees here (input 56); 0.57 and 0.48 with every plane near a vertex
    // snapped to it.
    EXPECT_GT(patches_min_angle(c), in_angle / 20) << off;
  }
}
