// Unit tests of the plan build (plan/plan.hpp): sizes and index ranges on random meshes and
// lattices, a watertight welded output on closed input, degenerate and invalid input.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "smoothffd/plan/plan.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

template <class T>
void expect_in_range(const std::vector<T>& v, long long lo, long long hi, const char* what) {
  for (size_t i = 0; i < v.size(); ++i)
    if (!((long long)v[i] >= lo && (long long)v[i] < hi)) {
      ADD_FAILURE() << what << "[" << i << "] = " << (long long)v[i] << " not in [" << lo << ", " << hi << ")";
      return;
    }
}

// Every size and every index of the plan is consistent: what the evaluators rely on to stay
// inside their buffers.
void check_plan(const Plan& p, const InputMesh& m, const LatticeSpec& s) {
  const int V = (int)m.positions.size() / 3, L = p.level;
  const int P = p.patches, E = p.edges, S = p.samples, K = p.columns, G = p.grid;
  const long long N = p.output_vertices, T = p.output_triangles;
  EXPECT_EQ(p.input_vertices, V);
  EXPECT_GE(p.sub_vertices, V);
  EXPECT_EQ(p.fit_degree, std::max(3, s.degree_sum()));
  EXPECT_EQ(K, (p.fit_degree + 1) * (p.fit_degree + 2) / 2 + 9);
  EXPECT_EQ(G, (L + 1) * (L + 2) / 2);
  EXPECT_EQ(N, (long long)p.sub_vertices + (long long)E * (L - 1) + (long long)P * (L - 1) * (L - 2) / 2);
  EXPECT_EQ(T, (long long)P * L * L);
  for (int a = 0; a < 3; ++a) EXPECT_EQ(p.dims[a], s.axes[a].n_ctrl());
  ASSERT_EQ(p.sample_position.size(), 3u * S);
  ASSERT_EQ(p.sample_piece.size(), (size_t)S);
  ASSERT_EQ(p.sample_weight.size(), (size_t)S);
  ASSERT_EQ(p.fit_matrix.size(), 10u * K);
  ASSERT_EQ(p.patch_samples.size(), (size_t)P * K);
  ASSERT_EQ(p.patch_vertex.size(), 3u * P);
  ASSERT_EQ(p.patch_edge.size(), 3u * P);
  ASSERT_EQ(p.patch_render_normal.size(), 9u * P);
  ASSERT_EQ(p.patch_adjust_normal.size(), 9u * P);
  ASSERT_EQ(p.edge_vertex.size(), 2u * E);
  ASSERT_EQ(p.edge_constraint.size(), 2u * E);
  ASSERT_EQ(p.edge_patch.size(), 2u * E);
  ASSERT_EQ(p.edge_slot.size(), 4u * E);
  ASSERT_EQ(p.patch_grid_vertex.size(), (size_t)P * G);
  ASSERT_EQ(p.output_owner.size(), 2u * (N - p.sub_vertices));
  ASSERT_EQ(p.rest_positions.size(), 3u * N);
  ASSERT_EQ(p.triangles.size(), 3u * T);
  ASSERT_EQ(p.face_index.size(), (size_t)T);
  if (!m.corner_uv.empty()) EXPECT_EQ(p.uvs.size(), 6u * T);
  expect_in_range(p.patch_samples, 0, S, "patch_samples");
  expect_in_range(p.patch_vertex, 0, p.sub_vertices, "patch_vertex");
  expect_in_range(p.patch_edge, 0, E, "patch_edge");
  expect_in_range(p.edge_vertex, 0, p.sub_vertices, "edge_vertex");
  expect_in_range(p.edge_constraint, p.sub_vertices, S, "edge_constraint");
  expect_in_range(p.edge_patch, -1, P, "edge_patch");
  expect_in_range(p.edge_slot, 0, 3, "edge_slot");
  expect_in_range(p.patch_grid_vertex, 0, N, "patch_grid_vertex");
  expect_in_range(p.triangles, 0, N, "triangles");
  expect_in_range(p.face_index, 0, (long long)m.face_offset.size() - 1, "face_index");
  expect_in_range(p.patch_face, 0, (long long)m.face_offset.size() - 1, "patch_face");
  expect_in_range(p.local_triangles, 0, G, "local_triangles");
  for (size_t i = 0; i < p.output_owner.size(); i += 2) {
    EXPECT_GE(p.output_owner[i], 0) << "output vertex without an owner patch";
    EXPECT_LT(p.output_owner[i], P);
    EXPECT_GE(p.output_owner[i + 1], 0);
    EXPECT_LT(p.output_owner[i + 1], G);
  }
  for (int a = 0; a < 3; ++a) {
    long long pieces = (a < 2 ? p.axis_offset[a + 1] : (long long)p.pieces.size()) - p.axis_offset[a];
    for (uint32_t packed : p.sample_piece) {
      long long pc = (packed >> (10 * a)) & 1023u;
      if (pc >= pieces) {
        ADD_FAILURE() << "sample piece " << pc << " of axis " << a << " out of " << pieces;
        break;
      }
    }
  }
  for (float x : p.sample_position) ASSERT_TRUE(std::isfinite(x));
  for (float x : p.rest_positions) ASSERT_TRUE(std::isfinite(x));
  for (float x : p.patch_render_normal) ASSERT_TRUE(std::isfinite(x));
  for (float x : p.patch_adjust_normal) ASSERT_TRUE(std::isfinite(x));
  // Edges: one side at least, patch p's edge k really joins its corners k and k + 1.
  for (int q = 0; q < P; ++q)
    for (int k = 0; k < 3; ++k) {
      int e = p.patch_edge[3 * q + k];
      int a = p.patch_vertex[3 * q + k], b = p.patch_vertex[3 * q + (k + 1) % 3];
      bool rev = p.patch_edge_reversed[3 * q + k];
      EXPECT_EQ(p.edge_vertex[2 * e + (rev ? 1 : 0)], a);
      EXPECT_EQ(p.edge_vertex[2 * e + (rev ? 0 : 1)], b);
    }
}

}  // namespace

TEST(Plan, RandomMeshesAndLattices) {
  std::mt19937 rng(12345);
  std::uniform_int_distribution<int> lvl(1, 4);
  for (int trial = 0; trial < 60; ++trial) {
    InputMesh m = random_mesh(rng);
    LatticeSpec s = random_lattice(rng);
    PlanOptions opt;
    opt.level = lvl(rng);
    Plan p = build_plan(m, s, opt);
    SCOPED_TRACE("trial " + std::to_string(trial));
    check_plan(p, m, s);
  }
}

TEST(Plan, ClosedInputGivesWatertightOutput) {
  for (int L : {1, 2, 3, 6}) {
    InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
    LatticeSpec s = bspline_box(2, 5);
    PlanOptions opt;
    opt.level = L;
    Plan p = build_plan(m, s, opt);
    check_plan(p, m, s);
    EXPECT_GT(p.sub_vertices, 6);  // it was clipped
    EdgeCounts e = count_edges(p.triangles);
    for (auto& kv : e.undirected) EXPECT_EQ(kv.second, 2) << "L=" << L;
    for (auto& kv : e.directed) EXPECT_EQ(kv.second, 1) << "L=" << L;
    EXPECT_EQ(p.output_vertices - (long long)e.undirected.size() + p.output_triangles, 2);
  }
}

TEST(Plan, PolygonsAndSplitNormals) {
  InputMesh m = cube_quads(0.15, 0.85);
  // Flat face normals per corner: every cube edge is sharp.
  const float n[6][3] = {{0, 0, -1}, {0, 0, 1}, {0, -1, 0}, {0, 1, 0}, {-1, 0, 0}, {1, 0, 0}};
  for (int f = 0; f < 6; ++f)
    for (int k = 0; k < 4; ++k) m.corner_normal.insert(m.corner_normal.end(), n[f], n[f] + 3);
  LatticeSpec s = bspline_box(2, 4);
  PlanOptions opt;
  opt.level = 3;
  Plan p = build_plan(m, s, opt);
  check_plan(p, m, s);
  EXPECT_FALSE(p.sharp_edges.empty());
  int sharp = 0;
  for (uint8_t f : p.edge_flags) sharp += (f & (kSharpAtA | kSharpAtB)) != 0;
  EXPECT_GT(sharp, 0);
}

TEST(Plan, AllFacesDegenerate) {
  // Every face repeats vertices: nothing to patch, the input vertices still come out.
  InputMesh m = tri_mesh({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 1, 2, 2, 2});
  LatticeSpec s = bspline_box(2, 4);
  Plan p = build_plan(m, s, PlanOptions{});
  check_plan(p, m, s);
  EXPECT_EQ(p.patches, 0);
  EXPECT_EQ(p.output_triangles, 0);
  EXPECT_EQ(p.output_vertices, 3);
}

TEST(Plan, RejectsInvalidInput) {
  LatticeSpec s = bspline_box(2, 4);
  InputMesh ok = octahedron();
  auto expect_bad = [&](InputMesh m, int level = 2) {
    PlanOptions opt;
    opt.level = level;
    EXPECT_THROW(build_plan(m, s, opt), std::invalid_argument);
  };
  expect_bad(ok, 0);
  expect_bad(ok, -3);
  InputMesh m = ok;
  m.corner_vertex[4] = 6;
  expect_bad(m);
  m = ok;
  m.corner_vertex[4] = -1;
  expect_bad(m);
  m = ok;
  m.positions[5] = NAN;
  expect_bad(m);
  m = ok;
  m.positions[0] = INFINITY;
  expect_bad(m);
  m = ok;
  m.positions.pop_back();
  expect_bad(m);
  m = ok;
  m.face_offset = {0, 2, 24};  // a face of two corners
  expect_bad(m);
  m = ok;
  m.face_offset.back() = 23;
  expect_bad(m);
  m = ok;
  m.face_offset.clear();
  expect_bad(m);
  m = ok;
  m.corner_normal.assign(5, 0.0f);
  expect_bad(m);
  m = ok;
  m.corner_uv.assign(7, 0.0f);
  expect_bad(m);
  m = ok;
  m.vertex_weight.assign(2, 1.0f);
  expect_bad(m);
}

// The evaluators run in float: a lattice whose knot spans or map cannot be represented there
// (here: knots 1e-40 apart, an inverse span of 1e40) is refused by name, never NaN output
// (native/fuzz/corpus/plan/regress_nan_tiny_span.bin, found by fuzz_plan).
TEST(Plan, LatticeBeyondFloatRangeIsRefused) {
  InputMesh m = tri_mesh({0.1, 0.1, 0.1, 0.9, 0.1, 0.1, 0.1, 0.9, 0.1}, {0, 1, 2});
  LatticeSpec s = bspline_box(2, 4);
  std::vector<double> tiny = clamped_knots(2, 4);
  for (double& k : tiny) k *= 1e-40;
  s.axes[0] = AxisBasis::bspline(2, tiny, 4);
  s.object_to_param[0][0] = 1e-40;
  PlanOptions opt;
  opt.level = 2;
  try {
    build_plan(m, s, opt);
    FAIL() << "a lattice beyond float range was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("axis u"), std::string::npos) << e.what();
  }
  EXPECT_NO_THROW(build_plan(m, bspline_box(2, 4), opt));
}
