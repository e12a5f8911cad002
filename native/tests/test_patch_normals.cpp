// The patches' corner normals (plan/patch_normals.hpp): barycentric shading normals, the
// input's adjustment normals at input vertices and the PN quadratic field at clip vertices, and
// the bound on the sub-mesh, on a flat grid and a smooth octahedron.
#include <gtest/gtest.h>

#include <cmath>

#include "smoothffd/plan/patch_normals.hpp"
#include "smoothffd/plan/sub_vertices.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

const double kCos1Degree = std::cos(M_PI / 180.0);

struct Staged {
  InputMesh mesh;
  InputSurface in;
  ClipResult clip;
  BoundedRest rest;
  SubVertices sv;
  Staged(InputMesh m, const LatticeSpec& s)
      : mesh(std::move(m)),
        in(build_input_surface(mesh, kCos1Degree)),
        clip(clip_to_knot_boxes(mesh.positions, in.tv, s)),
        rest(bound_rest_surface(mesh.positions, in, clip)),
        sv(place_sub_vertices(mesh, in, rest.surface, clip)) {}
};

double dot(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

}  // namespace

TEST(PatchNormals, FlatGridFacesUp) {
  Staged st(flat_grid(3), bspline_box(2, 5));
  const int P = st.clip.patches();
  const PatchNormals pn = patch_corner_normals(st.mesh.positions, st.in, st.clip, st.rest.shade);
  ASSERT_EQ(pn.render.size(), 9u * P);
  ASSERT_EQ(pn.adjust.size(), 9u * P);
  for (int i = 0; i < 3 * P; ++i) {
    EXPECT_NEAR(pn.render[3 * i + 2], 1.0, 1e-15) << i;
    EXPECT_NEAR(pn.adjust[3 * i + 2], 1.0, 1e-15) << i;
  }
  Plan plan;
  const EdgeTable sub = build_edges(st.clip.patch_vertex);
  const std::vector<uint8_t> sharp =
      bound_patch_normals(plan, pn, sub, st.sv.position, st.clip, st.in.adjust.flat, kCos1Degree);
  ASSERT_EQ(sharp.size(), (size_t)sub.count());
  for (uint8_t f : sharp) EXPECT_EQ(f, 0);
  EXPECT_EQ(plan.bounded_sub_vertices, 0);
  EXPECT_EQ(plan.turned_sub_normals, 0);
  ASSERT_EQ(plan.patch_render_normal.size(), 9u * P);
  for (int i = 0; i < 3 * P; ++i) {
    EXPECT_EQ(plan.patch_render_normal[3 * i + 2], 1.0f);
    EXPECT_EQ(plan.patch_adjust_normal[3 * i + 2], 1.0f);
  }
}

TEST(PatchNormals, SmoothOctahedronByFormula) {
  const double c[3] = {0.5, 0.5, 0.5}, r = 0.4;
  Staged st(octahedron(c[0], c[1], c[2], r), bspline_box(2, 5));
  const int P = st.clip.patches(), V = 6;
  const PatchNormals pn = patch_corner_normals(st.mesh.positions, st.in, st.clip, st.rest.shade);
  // The octahedron's smooth normals are radial: (x - c) / r at its vertices.
  auto radial = [&](int v, double* n) {
    for (int i = 0; i < 3; ++i) n[i] = (st.mesh.positions[3 * v + i] - c[i]) / r;
  };
  for (int p = 0; p < P; ++p) {
    const int t = st.clip.patch_tri[p];
    for (int k = 0; k < 3; ++k) {
      const double* b = &st.clip.patch_bary[9 * p + 3 * k];
      const int v = st.clip.patch_vertex[3 * p + k];
      // Shading: the corners' normals interpolated at b, normalized.
      double want[3] = {0, 0, 0}, n[3];
      for (int j = 0; j < 3; ++j) {
        radial(st.in.tv[3 * t + j], n);
        for (int i = 0; i < 3; ++i) want[i] += b[j] * n[i];
      }
      const double len = std::sqrt(dot(want, want));
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(pn.render[9 * p + 3 * k + i], want[i] / len, 1e-7) << p << " " << k;
      const double* a = &pn.adjust[9 * p + 3 * k];
      EXPECT_NEAR(dot(a, a), 1.0, 1e-12);
      if (v < V) {
        radial(v, n);
        for (int i = 0; i < 3; ++i) EXPECT_NEAR(a[i], n[i], 1e-7) << p << " " << k;
      } else {
        // The PN normal field of a sphere-like octahedron stays close to the radial direction
        // of the point on the rest surface.
        double d[3];
        for (int i = 0; i < 3; ++i) d[i] = st.sv.position[3 * v + i] - c[i];
        EXPECT_GT(dot(a, d) / std::sqrt(dot(d, d)), 0.95) << p << " " << k;
      }
    }
  }
}
