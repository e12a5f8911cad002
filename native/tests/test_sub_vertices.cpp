// The rest-surface bound and the sub-vertices placed on it (plan/sub_vertices.hpp): on a flat
// grid the rest surface is its plane, and weights are interpolated linearly; on a smooth
// octahedron the clip vertices move outwards onto the curved rest surface.
#include <gtest/gtest.h>

#include <cmath>

#include "smoothffd/plan/sub_vertices.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

const double kCos1Degree = std::cos(M_PI / 180.0);

double linear_weight(const double* p) { return 1 + 2 * p[0] + 3 * p[1]; }

}  // namespace

TEST(SubVertices, FlatGridStaysInItsPlane) {
  InputMesh mesh = flat_grid(3, 0.1, 0.9, 0.37);
  const int V = (int)mesh.positions.size() / 3;
  for (int v = 0; v < V; ++v) mesh.vertex_weight.push_back((float)linear_weight(&mesh.positions[3 * v]));
  InputSurface in = build_input_surface(mesh, kCos1Degree);
  const ClipResult clip = clip_to_knot_boxes(mesh.positions, in.tv, bspline_box(2, 5));
  ASSERT_GT(clip.sub_vertices(), V) << "the planes x, y = 1/3, 2/3 cut the grid";
  const BoundedRest rest = bound_rest_surface(mesh.positions, in, clip);
  EXPECT_EQ(rest.flat_triangles, 18);  // every triangle is its own flat face
  EXPECT_EQ(rest.bounded_vertices, 0);
  EXPECT_EQ(rest.turned_normals, 0);
  EXPECT_EQ(rest.shade, in.normal);
  const SubVertices sv = place_sub_vertices(mesh, in, rest.surface, clip);
  ASSERT_EQ(sv.position.size(), 3u * clip.sub_vertices());
  ASSERT_EQ(sv.weight.size(), (size_t)clip.sub_vertices());
  for (int v = 0; v < clip.sub_vertices(); ++v) {
    const double* p = &sv.position[3 * v];
    if (v < V) {
      for (int i = 0; i < 3; ++i) EXPECT_EQ(p[i], mesh.positions[3 * v + i]);
      EXPECT_EQ(sv.weight[v], mesh.vertex_weight[v]);
      continue;
    }
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(p[i], clip.flat[3 * v + i], 1e-12) << v;
    EXPECT_NEAR(p[2], 0.37, 1e-15);
    // On a knot plane: x or y at 1/3 or 2/3 (within the clip's snapping).
    const double dx = std::min(std::fabs(p[0] - 1 / 3.0), std::fabs(p[0] - 2 / 3.0));
    const double dy = std::min(std::fabs(p[1] - 1 / 3.0), std::fabs(p[1] - 2 / 3.0));
    EXPECT_LT(std::min(dx, dy), 1e-12) << v;
    EXPECT_NEAR(sv.weight[v], linear_weight(p), 1e-6) << v;
  }
  mesh.vertex_weight.clear();
  const SubVertices unweighted = place_sub_vertices(mesh, in, rest.surface, clip);
  for (double w : unweighted.weight) EXPECT_EQ(w, 1.0);
}

TEST(SubVertices, SmoothOctahedronBulgesOutwards) {
  const double c[3] = {0.5, 0.5, 0.5}, r = 0.4;
  const InputMesh mesh = octahedron(c[0], c[1], c[2], r);
  const int V = 6;
  InputSurface in = build_input_surface(mesh, kCos1Degree);
  const ClipResult clip = clip_to_knot_boxes(mesh.positions, in.tv, bspline_box(2, 5));
  ASSERT_GT(clip.sub_vertices(), V);
  const BoundedRest rest = bound_rest_surface(mesh.positions, in, clip);
  EXPECT_EQ(rest.flat_triangles, 0);  // radial normals, 54.7 degrees from the faces'
  const SubVertices sv = place_sub_vertices(mesh, in, rest.surface, clip);
  for (int v = V; v < clip.sub_vertices(); ++v) {
    double flat = 0, moved = 0;
    for (int i = 0; i < 3; ++i) {
      flat += (clip.flat[3 * v + i] - c[i]) * (clip.flat[3 * v + i] - c[i]);
      moved += (sv.position[3 * v + i] - c[i]) * (sv.position[3 * v + i] - c[i]);
    }
    // Off the flat faces, outwards, and no further out than the vertices.
    EXPECT_GT(std::sqrt(moved), std::sqrt(flat) + 1e-4) << v;
    EXPECT_LT(std::sqrt(moved), r + 1e-12) << v;
    EXPECT_EQ(sv.weight[v], 1.0);
  }
}
