// Unit tests of where the output lies on the input (plan/sources.hpp): the triangulation the
// plan records, the barycentric points of the output vertices and the corner interpolation,
// each against a computation of its own (rest positions, linear functions, the plan's UVs).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/sources.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// A cube of quads plus a concave pentagon (an L-ish shape) and a triangle, cut by a 4x4x4
// quadratic B-spline lattice's knot planes (interior knots at 1/2): polygons, clip vertices.
InputMesh polygon_mesh() {
  InputMesh m = cube_quads(0.15, 0.85);
  const double extra[] = {0.1, 0.1, 0.95, 0.9, 0.1, 0.95, 0.9, 0.5, 0.95,
                          0.5, 0.45, 0.95, 0.3, 0.9, 0.95, 0.2, 0.2, 0.05};
  int V = (int)m.positions.size() / 3;
  m.positions.insert(m.positions.end(), std::begin(extra), std::end(extra));
  for (int k = 0; k < 5; ++k) m.corner_vertex.push_back(V + k);  // concave pentagon
  m.face_offset.push_back((int)m.corner_vertex.size());
  m.corner_vertex.insert(m.corner_vertex.end(), {V, V + 5, V + 1});  // a triangle
  m.face_offset.push_back((int)m.corner_vertex.size());
  return m;
}

// Corner values that differ per face (a seam everywhere), from a fixed random sequence.
std::vector<float> random_corner_values(size_t C, int k, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-1, 2);
  std::vector<float> v((size_t)k * C);
  for (float& x : v) x = U(rng);
  return v;
}

Plan plan_at(const InputMesh& m, int level) {
  PlanOptions opt;
  opt.level = level;
  return build_plan(m, bspline_box(2, 4), opt);
}

}  // namespace

TEST(PlanSources, TriangulationCoversEachFaceByItsOwnCorners) {
  InputMesh m = polygon_mesh();
  Plan p = plan_at(m, 3);
  const size_t Tin = p.input_triangle_face.size();
  ASSERT_EQ(p.input_triangle_corner.size(), 3 * Tin);
  EXPECT_EQ(p.input_corners, (int)m.corner_vertex.size());
  std::vector<int> per_face(m.face_offset.size() - 1, 0);
  for (size_t t = 0; t < Tin; ++t) {
    int f = p.input_triangle_face[t];
    per_face[f]++;
    for (int k = 0; k < 3; ++k) {
      int c = p.input_triangle_corner[3 * t + k];
      EXPECT_GE(c, m.face_offset[f]);
      EXPECT_LT(c, m.face_offset[f + 1]);
    }
  }
  for (size_t f = 0; f < per_face.size(); ++f)  // n-gon: n - 2 triangles (nothing degenerate)
    EXPECT_EQ(per_face[f], m.face_offset[f + 1] - m.face_offset[f] - 2) << "face " << f;
  // Every output triangle's patch lies in a triangle of the output triangle's own face.
  const int LL = p.level * p.level;
  ASSERT_EQ(p.patch_triangle.size(), (size_t)p.patches);
  ASSERT_EQ(p.patch_bary.size(), 9u * p.patches);
  for (int t = 0; t < p.output_triangles; ++t)
    ASSERT_EQ(p.input_triangle_face[p.patch_triangle[t / LL]], p.face_index[t]) << t;
}

TEST(PlanSources, VertexPointsReproduceRestPositions) {
  for (int level : {1, 2, 5}) {
    InputMesh m = polygon_mesh();
    Plan p = plan_at(m, level);
    ASSERT_GT(p.sub_vertices, p.input_vertices);  // clipped: clip vertices exist
    const long long N = p.output_vertices;
    std::vector<int> tri(N);
    std::vector<float> bary(3 * N);
    vertex_sources(p, tri.data(), bary.data());
    const int V = p.input_vertices;
    double worst = 0;
    for (long long o = 0; o < N; ++o) {
      ASSERT_GE(tri[o], 0) << o;
      double s = 0, x[3] = {0, 0, 0};
      for (int q = 0; q < 3; ++q) {
        float b = bary[3 * o + q];
        EXPECT_GE(b, 0.0f);
        s += b;
        int v = m.corner_vertex[p.input_triangle_corner[3 * (size_t)tri[o] + q]];
        for (int i = 0; i < 3; ++i) x[i] += b * m.positions[3 * (size_t)v + i];
        if (o < V && b != 0.0f) {  // an input vertex: exactly its own corner, one-hot
          EXPECT_EQ(b, 1.0f);
          EXPECT_EQ(v, o);
        }
      }
      EXPECT_NEAR(s, 1.0, 1e-6);
      for (int i = 0; i < 3; ++i) worst = std::max(worst, std::fabs(x[i] - p.rest_positions[3 * o + i]));
    }
    EXPECT_LT(worst, 2e-6) << "level " << level;
  }
}

TEST(PlanSources, LooseInputVertexHasNoTriangle) {
  InputMesh m = octahedron();
  for (double x : {0.5, 0.5, 0.5}) m.positions.push_back(x);  // vertex 6: used by no face
  Plan p = plan_at(m, 2);
  std::vector<int> tri(p.output_vertices);
  std::vector<float> bary(3 * (size_t)p.output_vertices);
  vertex_sources(p, tri.data(), bary.data());
  EXPECT_EQ(tri[6], -1);
  EXPECT_EQ(bary[18] + bary[19] + bary[20], 0.0f);
}

TEST(PlanSources, CornerInterpolationIsTheUvArithmetic) {
  InputMesh m = polygon_mesh();
  const size_t C = m.corner_vertex.size();
  m.corner_uv = random_corner_values(C, 2, 3);
  Plan p = plan_at(m, 4);
  ASSERT_EQ(p.uvs.size(), 6u * p.output_triangles);
  // The same values through interpolate_corners: bitwise the plan's UVs, for any thread count.
  for (int threads : {1, 3}) {
    std::vector<float> out(6 * (size_t)p.output_triangles);
    interpolate_corners(p, m.corner_uv.data(), 2, out.data(), threads);
    EXPECT_EQ(out, p.uvs) << threads << " threads";
  }
  // k = 3 columns at once: each column as if alone.
  std::vector<float> three = random_corner_values(C, 3, 4), col(C), all(9 * (size_t)p.output_triangles),
                     one(3 * (size_t)p.output_triangles);
  interpolate_corners(p, three.data(), 3, all.data());
  for (int i = 0; i < 3; ++i) {
    for (size_t c = 0; c < C; ++c) col[c] = three[3 * c + i];
    interpolate_corners(p, col.data(), 1, one.data());
    for (size_t j = 0; j < one.size(); ++j) ASSERT_EQ(one[j], all[3 * j + i]) << i << " " << j;
  }
}

TEST(PlanSources, LinearCornerValuesGiveTheirValueAtTheRestPoint) {
  // Values that are one affine function of the corner's position (the same on every face):
  // any barycentric interpolation in the right triangle gives the function at the rest point.
  InputMesh m = polygon_mesh();
  const size_t C = m.corner_vertex.size();
  auto f = [](const double* x, int i) { return i == 0 ? 0.3 + x[0] - 2 * x[1] + 0.5 * x[2] : -x[0] + x[2] * 3; };
  std::vector<float> vals(2 * C);
  for (size_t c = 0; c < C; ++c)
    for (int i = 0; i < 2; ++i) vals[2 * c + i] = (float)f(&m.positions[3 * (size_t)m.corner_vertex[c]], i);
  Plan p = plan_at(m, 5);
  std::vector<float> out(6 * (size_t)p.output_triangles);
  interpolate_corners(p, vals.data(), 2, out.data());
  double worst = 0;
  for (int t = 0; t < p.output_triangles; ++t)
    for (int c = 0; c < 3; ++c) {
      double x[3];
      for (int i = 0; i < 3; ++i) x[i] = p.rest_positions[3 * (size_t)p.triangles[3 * t + c] + i];
      for (int i = 0; i < 2; ++i) worst = std::max(worst, std::fabs(out[6 * (size_t)t + 2 * c + i] - f(x, i)));
    }
  EXPECT_LT(worst, 1e-5);
}

TEST(PlanSources, SeamValuesComeFromTheOutputTrianglesOwnFace) {
  // Per-face values (corner c of face f carries f): every output corner gets exactly its face's.
  InputMesh m = polygon_mesh();
  std::vector<float> vals(m.corner_vertex.size());
  for (size_t f = 0; f + 1 < m.face_offset.size(); ++f)
    for (int c = m.face_offset[f]; c < m.face_offset[f + 1]; ++c) vals[c] = (float)f;
  Plan p = plan_at(m, 3);
  std::vector<float> out(3 * (size_t)p.output_triangles);
  interpolate_corners(p, vals.data(), 1, out.data());
  for (int t = 0; t < p.output_triangles; ++t)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(out[3 * (size_t)t + c], (float)p.face_index[t]) << t;
}
