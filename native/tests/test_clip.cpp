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
// consecutive planes (parameter space, within rounding).
void expect_one_box_each(const ClipResult& c, const LatticeSpec& s) {
  for (int p = 0; p < c.patches(); ++p)
    for (int a = 0; a < 3; ++a) {
      std::vector<double> planes = s.axes[a].planes();
      double lo = INFINITY, hi = -INFINITY;
      for (int k = 0; k < 3; ++k) {
        double prm[3];
        s.to_param(P(c, c.patch_vertex[3 * p + k]), prm);
        lo = std::min(lo, prm[a]);
        hi = std::max(hi, prm[a]);
      }
      for (double pl : planes)
        EXPECT_FALSE(pl > lo + 1e-9 && pl < hi - 1e-9)
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
