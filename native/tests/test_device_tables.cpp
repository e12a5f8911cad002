// Unit tests of the CUDA evaluator's device tables (cuda/device_tables.hpp), without a GPU:
// each table is checked against the plan it was built from, the way the kernels read it.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>

#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/plan/bezier.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd::cuda_impl;
using namespace sffd_test;

namespace {

DeviceTables tables_of(const Plan& p) { return build_device_tables(p, build_tessellation(p.level)); }

// A mesh with a sharp crease (cube) and a smooth one (octahedron with averaged normals).
std::vector<std::shared_ptr<const Plan>> sample_plans() {
  std::vector<std::shared_ptr<const Plan>> out;
  InputMesh cube = cube_quads(0.15, 0.85);  // split normals: every edge sharp
  for (int f = 0; f < 6; ++f) {
    const int a = cube.corner_vertex[4 * f], b = cube.corner_vertex[4 * f + 1], c = cube.corner_vertex[4 * f + 2];
    double u[3], w[3], n[3];
    for (int i = 0; i < 3; ++i) {
      u[i] = cube.positions[3 * b + i] - cube.positions[3 * a + i];
      w[i] = cube.positions[3 * c + i] - cube.positions[3 * a + i];
    }
    n[0] = u[1] * w[2] - u[2] * w[1], n[1] = u[2] * w[0] - u[0] * w[2], n[2] = u[0] * w[1] - u[1] * w[0];
    const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 4; ++k)
      for (int i = 0; i < 3; ++i) cube.corner_normal.push_back((float)(n[i] / l));
  }
  out.push_back(plan_of(cube, bspline_box(2, 4), 5));
  EXPECT_GT(out.back()->render_vertices, out.back()->output_vertices);  // normals split at the creases
  out.push_back(plan_of(octahedron(), bspline_box(2, 5), 4));
  out.push_back(plan_of(octahedron(0.45, 0.5, 0.55, 0.42), blender_box(BlenderInterp::BSpline, 4), 3));
  out.push_back(plan_of(flat_grid(3), bspline_box(1, 3), 6));  // open mesh: boundary edges
  return out;
}

}  // namespace

TEST(DeviceTables, GridWalkIsAPermutationBoundaryFirst) {
  for (int L : {1, 2, 3, 7, 10}) {
    auto p = plan_of(octahedron(), bspline_box(2, 4), L);
    const DeviceTables t = tables_of(*p);
    const int G = p->grid, IG = (L - 1) * (L - 2) / 2, NB = G - IG;
    ASSERT_EQ((int)t.grid_info.size(), G);
    EXPECT_EQ(t.walk_boundary, NB);
    std::vector<int> seen(G, 0);
    for (int w = 0; w < G; ++w) {
      const int g = t.grid_info[w].order;
      ASSERT_TRUE(g >= 0 && g < G);
      ++seen[g];
      const GridInfo& q = t.grid_info[g];
      if (w < NB) EXPECT_NE(q.kind, 2) << "L " << L << " walk " << w;
      if (w >= NB) EXPECT_EQ(q.kind == 2 ? q.which : -1, w - NB) << "L " << L << " walk " << w;
    }
    for (int g = 0; g < G; ++g) EXPECT_EQ(seen[g], 1);
    // The walk's (s, t): the boundary points from 0, the interior from st_interior (even).
    const TessellationTables tt = build_tessellation(L);
    EXPECT_EQ(t.st_interior % 2, 0);
    for (int w = 0; w < G; ++w) {
      const int g = t.grid_info[w].order, i = w < NB ? w : t.st_interior + w - NB;
      EXPECT_EQ(t.grid_st[i].x, (float)tt.bary[3 * g + 1]);
      EXPECT_EQ(t.grid_st[i].y, (float)tt.bary[3 * g + 2]);
      if (w < NB) EXPECT_EQ(t.grid_walk[w].which, t.grid_info[g].which);
    }
  }
}

// Every boundary grid point of every patch writes, through its record, exactly the output
// vertex and the render vertex the plan assigns it when the plan makes that patch their owner,
// and nothing otherwise; corners' positions once each.
TEST(DeviceTables, PatchRecordsWriteWhatThePlanOwns) {
  for (const auto& pp : sample_plans()) {
    const Plan& p = *pp;
    const DeviceTables t = tables_of(p);
    ASSERT_TRUE(t.no_inline.empty());
    ASSERT_GT(p.patches, 8);
    const int G = p.grid, SV = p.sub_vertices;
    std::vector<int> corner_writes(SV, 0);
    for (int q = 0; q < p.patches; ++q) {
      const InlinePatch& r = t.patch_rec[q];
      for (int g = 0; g < G; ++g) {
        const GridInfo& gi = t.grid_info[g];
        if (gi.kind == 2) continue;
        const int o = p.patch_grid_vertex[(size_t)q * G + g], rv = p.patch_grid_render[(size_t)q * G + g];
        const bool owns_r = p.render_owner[2 * (size_t)rv] == q && p.render_owner[2 * (size_t)rv + 1] == g;
        if (gi.kind == 0) {
          EXPECT_EQ(r.bound.corner[gi.which], owns_r ? rv : -1) << "patch " << q << " corner " << gi.which;
          EXPECT_EQ(r.vertex[gi.which], o);
          if ((r.flags >> (8 + gi.which)) & 1) ++corner_writes[o];
          continue;
        }
        const I4 e = r.bound.edge[gi.which];
        const int o_rec = e.x + gi.step * e.y, r_rec = e.z + gi.step * e.w;
        const bool owns_o = p.output_owner[2 * (size_t)(o - SV)] == q && p.output_owner[2 * (size_t)(o - SV) + 1] == g;
        EXPECT_EQ(o_rec, owns_o ? o : -1) << "patch " << q << " edge " << gi.which << " step " << gi.step;
        EXPECT_EQ(r_rec, owns_r ? rv : -1) << "patch " << q << " edge " << gi.which << " step " << gi.step;
        EXPECT_EQ((t.owns[q] >> gi.which) & 1, owns_o ? 1 : 0);
      }
    }
    std::set<int> loose(t.loose.begin(), t.loose.end());
    for (int v = 0; v < SV; ++v) EXPECT_EQ(corner_writes[v], loose.count(v) ? 0 : 1) << "sub-vertex " << v;
  }
}

// The edge bits and the neighbours' adjustment normals are the plan's edge tables as
// edge_control_points reads them.
TEST(DeviceTables, PatchRecordsCarryTheEdgeTables) {
  for (const auto& pp : sample_plans()) {
    const Plan& p = *pp;
    const DeviceTables t = tables_of(p);
    for (int q = 0; q < p.patches; ++q) {
      const InlinePatch& r = t.patch_rec[q];
      for (int i = 0; i < 9; ++i) {
        EXPECT_EQ(r.rest[i], p.patch_render_normal[9 * (size_t)q + i]);
        EXPECT_EQ(r.adjust[i], p.patch_adjust_normal[9 * (size_t)q + i]);
      }
      for (int k = 0; k < 3; ++k) {
        const int e = p.patch_edge[3 * q + k], p0 = p.edge_patch[2 * e], p1 = p.edge_patch[2 * e + 1];
        EXPECT_EQ((r.flags >> (3 + k)) & 1, p.patch_edge_reversed[3 * q + k] ? 1u : 0u);
        const uint32_t bits = (r.flags >> (12 + 4 * k)) & 15u;
        EXPECT_EQ((bits & 1) != 0, (p.edge_flags[e] & kSharpAtA) != 0);
        EXPECT_EQ((bits & 2) != 0, (p.edge_flags[e] & kSharpAtB) != 0);
        EXPECT_EQ((bits & 4) != 0, (p.edge_flags[e] & kKeepFitted) != 0);  // non-manifold or a flat face's
        EXPECT_EQ((bits & 8) != 0, p1 >= 0);
        EXPECT_EQ((r.flags >> (24 + k)) & 1, p1 == q ? 1u : 0u);
        if ((p.edge_flags[e] & kNonManifold) || p1 < 0) continue;
        const int side = p1 == q ? 1 : 0, other = side ? p0 : p1;
        for (int end = 0; end < 2; ++end)
          for (int i = 0; i < 3; ++i)
            EXPECT_EQ(r.nb[k][3 * end + i],
                      p.patch_adjust_normal[9 * (size_t)other + 3 * p.edge_slot[4 * (size_t)e + 2 * (1 - side) + end] + i]);
      }
    }
  }
}

// inline_sample_point puts every column's sample where the plan has it, from the patch's
// corner samples alone, and each record's boxes are its samples' pieces.
TEST(DeviceTables, SamplesPlacedFromTheCorners) {
  for (const auto& pp : sample_plans()) {
    const Plan& p = *pp;
    const DeviceTables t = tables_of(p);
    ASSERT_TRUE(t.shared_why.empty()) << t.shared_why;
    const int K = p.columns;
    for (int q = 0; q < p.patches; ++q) {
      const InlinePatch& r = t.patch_rec[q];
      for (size_t i = 0; i < t.evaluated.size(); ++i) {
        const int k = t.evaluated[i], s = p.patch_samples[(size_t)q * K + k];
        const F4 x = inline_sample_point(t.column[k], r.flags, r.corner[0], r.corner[1], r.corner[2]);
        EXPECT_NEAR(x.x, p.sample_position[3 * s], 2e-6);
        EXPECT_NEAR(x.y, p.sample_position[3 * s + 1], 2e-6);
        EXPECT_NEAR(x.z, p.sample_position[3 * s + 2], 2e-6);
        EXPECT_NEAR(x.w, p.sample_weight[s], 2e-6);
        const I4 box = t.box_list[r.box[i]];
        const uint32_t pk = p.sample_piece[s];
        for (int a = 0; a < 3; ++a) EXPECT_EQ((&box.x)[a], p.axis_offset[a] + (int)((pk >> (10 * a)) & 1023u));
      }
    }
  }
}

// The columns the kernel evaluates: every grid column, the constraint columns that are no grid
// column with the same sample in every patch, corners first, then edges, then interior.
TEST(DeviceTables, ColumnsAndTheirOrder) {
  for (const auto& pp : sample_plans()) {
    const Plan& p = *pp;
    const DeviceTables t = tables_of(p);
    const int K = p.columns, K0 = K - 9;
    std::vector<int> sorted(t.evaluated);
    std::sort(sorted.begin(), sorted.end());
    for (int k = 0; k < K0; ++k) EXPECT_TRUE(std::binary_search(sorted.begin(), sorted.end(), k));
    EXPECT_EQ(t.column_map.n_cols, (int)t.evaluated.size());
    int last_kind = 0, constraints = 0;
    for (size_t i = 0; i < t.evaluated.size(); ++i) {
      const InlineColumn& c = t.column[t.evaluated[i]];
      const int kind = c.corner >= 0 ? 0 : c.edge >= 0 ? 1 : 2;
      EXPECT_GE(kind, last_kind);
      last_kind = kind;
      EXPECT_EQ(t.column_map.order[i], t.evaluated[i]);
    }
    for (int k = 0; k < K0; ++k) {
      const int j = t.column_map.con_of[k];
      if (j < 0) continue;
      ++constraints;
      for (int q = 0; q < p.patches; ++q)
        EXPECT_EQ(p.patch_samples[(size_t)q * K + k], p.patch_samples[(size_t)q * K + K0 + j]);
    }
    EXPECT_EQ(constraints + (int)t.evaluated.size() - K0, 9);  // each constraint column once
    // Row 10 of mrow: the six edge rows' sum; the columns' centre-row coefficients.
    for (int q = 0; q < 9; ++q) {
      float s = 0.0f;
      for (int k = 0; k < 3; ++k) s += t.mrow[edge_control_index(k, false)][q] + t.mrow[edge_control_index(k, true)][q];
      EXPECT_EQ(t.mrow[10][q], s);
    }
    for (int k = 0; k < K0; ++k) EXPECT_EQ(t.column[k].bary.w, p.fit_matrix[(size_t)kCentre * K + k]);
  }
}

// The pieces' folded maps give the parameter the plan's pieces define, and their terms.
TEST(DeviceTables, PiecesFoldTheParameterMap) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (const auto& pp : sample_plans()) {
    const Plan& p = *pp;
    const DeviceTables t = tables_of(p);
    const int stride[3] = {p.dims[1] * p.dims[2], p.dims[2], 1};
    for (int a = 0; a < 3; ++a) {
      const int end = a < 2 ? p.axis_offset[a + 1] : (int)p.pieces.size();
      for (int i = p.axis_offset[a]; i < end; ++i) {
        const AxisPieceF& pc = p.pieces[i];
        const InlinePieceWide& w = t.pieces_wide[i];
        const InlinePiece& n = t.pieces[i];
        for (int rep = 0; rep < 5; ++rep) {
          const double x[3] = {U(rng), U(rng), U(rng)};
          const float* m = p.param_map + 4 * a;
          const double want = pc.degree == 0 ? 0.0 : ((m[0] * x[0] + m[1] * x[1] + m[2] * x[2] + m[3]) - pc.origin) * pc.inv_scale;
          const double got = w.map.x * x[0] + w.map.y * x[1] + w.map.z * x[2] + w.map.w;
          EXPECT_NEAR(got, want, 1e-5 * std::max(1.0, std::fabs(want)));
        }
        for (int k = 0; k < kMaxTerms; ++k) {
          EXPECT_EQ(w.off[k], pc.index[k] * stride[a]);
          for (int q = 0; q < kMaxTerms; ++q) EXPECT_EQ(w.coef[k][q], pc.coef[k][q]);
        }
        for (int k = 0; k < 4; ++k) {
          EXPECT_EQ((&n.off.x)[k], w.off[k]);
          for (int q = 0; q < 4; ++q) EXPECT_EQ((&n.coef[k].x)[q], w.coef[k][q]);
        }
      }
    }
  }
}

// Each group's boundary list holds exactly the (patch, walk position) pairs that write a
// position or a normal, in walk order per patch, and every record of the group its count.
TEST(DeviceTables, BoundaryListsHoldTheWritingPoints) {
  for (const auto& pp : sample_plans()) {
    DeviceTables t = tables_of(*pp);
    const std::vector<uint16_t> list = build_boundary_lists(t);
    const int stride = t.list_stride(), P = (int)t.patch_rec.size();
    ASSERT_EQ((int)list.size(), (P + 31) / 32 * stride);
    for (int g = 0; g * 32 < P; ++g) {
      std::vector<std::pair<int, int>> want;
      for (int q = 0; q < 32 && g * 32 + q < P; ++q) {
        const PatchBoundary& b = t.patch_rec[g * 32 + q].bound;
        for (int w = 0; w < t.walk_boundary; ++w) {
          const GridInfo& gi = t.grid_walk[w];
          if (gi.kind == 0 ? b.corner[gi.which] >= 0 : b.edge[gi.which].x >= 0 || b.edge[gi.which].z >= 0)
            want.push_back({q, w});
        }
      }
      const int items = t.patch_rec[g * 32].bound.items;
      ASSERT_EQ(items, (int)want.size());
      for (int i = 0; i < items; ++i) {
        const uint16_t e = list[(size_t)g * stride + i];
        EXPECT_EQ(e & 31, want[i].first);
        EXPECT_EQ(e >> 5, want[i].second);
      }
    }
  }
}

// The mode for a budget: boxes where they fit, else the weights, else global; global for
// what the shared tables cannot hold (degree 4: 5 terms an axis).
TEST(DeviceTables, ModeFollowsTheBudgetAndThePlan) {
  auto p = plan_of(octahedron(), bspline_box(2, 5), 6);
  DeviceTables t = tables_of(*p);
  EXPECT_EQ(t.terms, 3);
  const size_t boxes = t.shared_bytes(true), weights = t.shared_bytes(false);
  EXPECT_EQ(choose_inline_mode(t, std::max(boxes, weights)), kInlineBoxes);
  EXPECT_EQ(choose_inline_mode(t, 0), kInlineGlobal);
  EXPECT_FALSE(t.shared_why.empty());
  DeviceTables t2 = tables_of(*p);
  if (weights < boxes) EXPECT_EQ(choose_inline_mode(t2, weights), kInlineWeights);

  auto p4 = plan_of(octahedron(), bspline_box(4, 6), 3);
  DeviceTables t4 = tables_of(*p4);
  EXPECT_EQ(t4.max_terms, 5);
  EXPECT_EQ(t4.terms, 5);  // a kernel of its own: no padded sixth term
  EXPECT_EQ(t4.shared_why, "more than 4 terms an axis");
  EXPECT_EQ(choose_inline_mode(t4, size_t(1) << 30), kInlineGlobal);
  EXPECT_EQ((int)t4.evaluated.size(), p4->columns - 9 + 9 - [&] {
    int dup = 0;
    for (int k = 0; k < p4->columns - 9; ++k) dup += t4.column_map.con_of[k] >= 0;
    return dup;
  }());
}

// A lattice with point weights (4 control values a point): no inline kernel (its tables hold
// 3), the reference kernels serve it; the tables the reference path uses still build.
TEST(DeviceTables, PointWeightsRunTheReferenceKernels) {
  LatticeSpec s = blender_box(BlenderInterp::BSpline, 4, -0.2, 1.2);
  s.components = 4;
  auto p = plan_of(octahedron(), s, 3);
  EXPECT_EQ(p->components, 4);
  DeviceTables t = tables_of(*p);
  EXPECT_NE(t.no_inline.find("point weights"), std::string::npos) << t.no_inline;
  EXPECT_EQ(choose_inline_mode(t, size_t(1) << 30), kInlineNone);
  EXPECT_EQ((int)t.render.size(), p->patches);
  s.components = 5;
  EXPECT_THROW(plan_of(octahedron(), s, 3), std::invalid_argument);
}

// Random meshes and lattices: the tables build (or say why not) and their sizes agree.
TEST(DeviceTables, RandomPlans) {
  std::mt19937 rng(20);
  int built = 0;
  for (int it = 0; it < 60; ++it) {
    InputMesh m = random_mesh(rng);
    LatticeSpec s = random_lattice(rng);
    std::shared_ptr<const Plan> p;
    try {
      p = plan_of(m, s, 1 + it % 5);
    } catch (const std::invalid_argument&) {
      continue;
    }
    const DeviceTables t = tables_of(*p);
    ++built;
    EXPECT_TRUE(t.no_inline.empty());
    EXPECT_EQ((int)t.patch_rec.size(), p->patches);
    EXPECT_EQ((int)t.render.size(), p->patches);
    EXPECT_EQ((int)t.column.size(), p->columns);
    EXPECT_EQ(t.terms, kernel_terms(plan_max_terms(*p)));
    EXPECT_LE((int)t.evaluated.size(), kMaxInlineColumns);
  }
  EXPECT_GT(built, 20);
}
