// The plan build's input surface (plan/input_surface.hpp): triangles, corner normals, edges,
// sharp edge ends and flat faces on meshes whose answers are known by hand.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "smoothffd/plan/input_surface.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

const double kCos1Degree = std::cos(M_PI / 180.0);

// cube_quads' faces (vertex i at (i & 1, i & 2, i & 4) of the box) with their outward normals.
const double kCubeFaceNormal[6][3] = {{0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {0, 1, 0}, {-1, 0, 0}, {1, 0, 0}};

InputMesh cube_split_normals() {
  InputMesh m = cube_quads();
  for (int f = 0; f < 6; ++f)
    for (int c = 0; c < 4; ++c)
      for (int i = 0; i < 3; ++i) m.corner_normal.push_back((float)kCubeFaceNormal[f][i]);
  return m;
}

// Whether vertices a and b of cube_quads are the ends of one of the cube's 12 edges (their
// indices differ in one bit) rather than a face diagonal (two bits).
bool cube_edge(int a, int b) {
  const int x = a ^ b;
  return x == 1 || x == 2 || x == 4;
}

}  // namespace

TEST(InputSurface, TrianglesKeepTheirCornersAndFaces) {
  const InputMesh m = octahedron();
  const InputSurface in = build_input_surface(m, kCos1Degree);
  ASSERT_EQ(in.tv.size(), 24u);
  ASSERT_EQ(in.triangulation.face.size(), 8u);
  for (int t = 0; t < 8; ++t) {
    const int f = in.triangulation.face[t];
    std::vector<int> got(&in.tv[3 * t], &in.tv[3 * t] + 3), want(&m.corner_vertex[3 * f], &m.corner_vertex[3 * f] + 3);
    // The same triangle, the same winding (a rotation of the face's corners).
    const int r = int(std::find(got.begin(), got.end(), want[0]) - got.begin());
    ASSERT_LT(r, 3);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(got[(r + k) % 3], want[k]) << "triangle " << t;
    for (int k = 0; k < 3; ++k) EXPECT_EQ(in.tv[3 * t + k], m.corner_vertex[in.triangulation.corners[3 * t + k]]);
  }
  // A closed octahedron: 12 edges, two triangles on each.
  ASSERT_EQ(in.edges().count(), 12);
  for (int e = 0; e < 12; ++e) EXPECT_EQ(in.edges().face_count[e], 2);
}

TEST(InputSurface, SplitNormalsOfACubeMarkItsEdgesSharpAndItsFacesFlat) {
  const InputMesh m = cube_split_normals();
  const InputSurface in = build_input_surface(m, kCos1Degree);
  ASSERT_EQ(in.tv.size(), 36u);  // 6 quads, 2 triangles each
  for (int f = 0; f < 6; ++f)
    EXPECT_EQ(std::count(in.triangulation.face.begin(), in.triangulation.face.end(), f), 2) << "face " << f;
  // 12 cube edges, sharp at both ends; 6 face diagonals, smooth.
  ASSERT_EQ(in.edges().count(), 18);
  int cube_edges = 0;
  for (int e = 0; e < 18; ++e) {
    const int a = in.edges().vertex[2 * e], b = in.edges().vertex[2 * e + 1];
    EXPECT_EQ(in.edges().face_count[e], 2);
    if (cube_edge(a, b)) {
      ++cube_edges;
      EXPECT_EQ(in.sharp[e], 3) << a << "-" << b;
    } else {
      EXPECT_EQ(in.sharp[e], 0) << a << "-" << b;
    }
  }
  EXPECT_EQ(cube_edges, 12);
  // Every triangle is a flat face's; its corners carry the face's normal, for shading and for
  // the geometry.
  ASSERT_EQ(in.adjust.flat.size(), 12u);
  for (int t = 0; t < 12; ++t) {
    EXPECT_EQ(in.adjust.flat[t], 1) << t;
    const double* n = kCubeFaceNormal[in.triangulation.face[t]];
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(in.normal[9 * t + 3 * k + i], n[i], 1e-7);
        EXPECT_NEAR(in.adjust.corner[9 * t + 3 * k + i], n[i], 1e-12);
      }
  }
}

TEST(InputSurface, SmoothNormalsOfACubeSplitNothing) {
  const InputMesh m = cube_quads(0.2, 0.8);  // no normals: smooth vertex normals
  const InputSurface in = build_input_surface(m, kCos1Degree);
  ASSERT_EQ(in.edges().count(), 18);
  for (int e = 0; e < 18; ++e) EXPECT_EQ(in.sharp[e], 0);
  for (int t = 0; t < 12; ++t) {
    EXPECT_EQ(in.adjust.flat[t], 0) << t;  // a corner's normal is ~55 degrees from its face's
    for (int k = 0; k < 3; ++k) {
      const int v = in.tv[3 * t + k];
      const double* n = &in.normal[9 * t + 3 * k];
      EXPECT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-12);
      // Outward at every corner: along the vertex's direction from the centre (0.5, 0.5, 0.5).
      const double out[3] = {v & 1 ? 1.0 : -1.0, v & 2 ? 1.0 : -1.0, v & 4 ? 1.0 : -1.0};
      for (int i = 0; i < 3; ++i) EXPECT_GT(n[i] * out[i], 0.2) << "vertex " << v;
    }
  }
  // One normal a vertex: every triangle at v carries the same.
  for (int t = 0; t < 12; ++t)
    for (int u = 0; u < 12; ++u)
      for (int k = 0; k < 3; ++k)
        for (int j = 0; j < 3; ++j)
          if (in.tv[3 * t + k] == in.tv[3 * u + j])
            for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(in.normal[9 * t + 3 * k + i], in.normal[9 * u + 3 * j + i]);
}
