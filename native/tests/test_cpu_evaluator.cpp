// Unit tests of the CPU evaluator (eval/cpu_evaluator.hpp): the identity lattice (zero
// displacements) keeps input vertices and flat meshes, a translation moves everything,
// thread counts agree bitwise, random control values give finite unit-normal output.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>

#include "smoothffd/core/hd.hpp"
#include "smoothffd/eval/cpu_evaluator.hpp"
#include "smoothffd/eval/stages.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

void expect_unit_normals(const CpuOut& o) {
  for (size_t i = 0; i < o.nrm.size(); i += 3) {
    double l = std::sqrt(double(o.nrm[i]) * o.nrm[i] + double(o.nrm[i + 1]) * o.nrm[i + 1] +
                         double(o.nrm[i + 2]) * o.nrm[i + 2]);
    ASSERT_NEAR(l, 1.0, 1e-5) << "normal " << i / 3;
  }
}

}  // namespace

TEST(CpuEvaluator, IdentityKeepsAFlatGridFlat) {
  for (auto s : {bspline_box(2, 4), bspline_box(3, 7), blender_box(BlenderInterp::BSpline, 4)}) {
    InputMesh m = flat_grid(5, 0.1, 0.9, 0.37);
    auto plan = plan_of(m, s, 4);
    CpuOut o = run_cpu(plan, zero_values(s));
    const int V = plan->input_vertices;
    for (int v = 0; v < V; ++v)
      for (int i = 0; i < 3; ++i) EXPECT_EQ(o.pos[3 * v + i], (float)m.positions[3 * v + i]);
    for (int v = 0; v < plan->output_vertices; ++v) {
      EXPECT_NEAR(o.pos[3 * v + 2], 0.37f, 1e-6f);
      for (int i = 0; i < 3; ++i) EXPECT_NEAR(o.pos[3 * v + i], plan->rest_positions[3 * v + i], 2e-6f);
    }
    for (size_t i = 0; i < o.nrm.size(); i += 3) {
      EXPECT_NEAR(o.nrm[i], 0.0f, 1e-5f);
      EXPECT_NEAR(o.nrm[i + 1], 0.0f, 1e-5f);
      EXPECT_NEAR(o.nrm[i + 2], 1.0f, 1e-5f);
    }
  }
}

TEST(CpuEvaluator, IdentityFixesInputVerticesOfAClosedMesh) {
  InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
  LatticeSpec s = bspline_box(2, 5);
  auto plan = plan_of(m, s, 5);
  CpuOut o = run_cpu(plan, zero_values(s));
  for (int v = 0; v < 6; ++v)
    for (int i = 0; i < 3; ++i) EXPECT_EQ(o.pos[3 * v + i], (float)m.positions[3 * v + i]);
  for (float x : o.pos) ASSERT_TRUE(std::isfinite(x));
  expect_unit_normals(o);
  // Clip vertices sit on the PN rest surface, which bulges outwards from the flat faces.
  for (int v = 6; v < plan->sub_vertices; ++v) {
    double r2 = 0, c[3] = {0.47, 0.52, 0.55};
    for (int i = 0; i < 3; ++i) r2 += (o.pos[3 * v + i] - c[i]) * (o.pos[3 * v + i] - c[i]);
    EXPECT_LE(std::sqrt(r2), 0.4 + 1e-5);
  }
}

TEST(CpuEvaluator, TranslationMovesEverything) {
  InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
  LatticeSpec s = bspline_box(3, 6);
  auto plan = plan_of(m, s, 4);
  CpuOut rest = run_cpu(plan, zero_values(s));
  std::vector<float> D(3 * (size_t)s.count());
  const float t[3] = {0.25f, -0.5f, 1.0f};
  for (size_t i = 0; i < D.size(); ++i) D[i] = t[i % 3];
  CpuOut moved = run_cpu(plan, D);
  for (size_t i = 0; i < rest.pos.size(); ++i) EXPECT_NEAR(moved.pos[i], rest.pos[i] + t[i % 3], 2e-6f);
  for (size_t i = 0; i < rest.nrm.size(); ++i) EXPECT_NEAR(moved.nrm[i], rest.nrm[i], 1e-5f);
}

TEST(CpuEvaluator, ThreadCountDoesNotChangeBits) {
  InputMesh m = flat_grid(12, 0.05, 0.95, 0.4);
  for (size_t i = 2; i < m.positions.size(); i += 3) m.positions[i] += 0.1 * std::sin(7 * m.positions[i - 2]);
  LatticeSpec s = bspline_box(2, 5);
  auto plan = plan_of(m, s, 6);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> U(-0.2f, 0.2f);
  std::vector<float> D(3 * (size_t)s.count());
  for (float& d : D) d = U(rng);
  CpuOut one = run_cpu(plan, D, 1), two = run_cpu(plan, D, 2), many = run_cpu(plan, D, 7);
  ASSERT_GT(plan->output_vertices, 4096);  // several chunks
  EXPECT_EQ(0, std::memcmp(one.pos.data(), two.pos.data(), 4 * one.pos.size()));
  EXPECT_EQ(0, std::memcmp(one.nrm.data(), two.nrm.data(), 4 * one.nrm.size()));
  EXPECT_EQ(0, std::memcmp(one.pos.data(), many.pos.data(), 4 * one.pos.size()));
  EXPECT_EQ(0, std::memcmp(one.nrm.data(), many.nrm.data(), 4 * one.nrm.size()));
}

TEST(CpuEvaluator, RandomMeshesAndControlValuesGiveFiniteOutput) {
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  std::uniform_int_distribution<int> lvl(1, 4);
  for (int trial = 0; trial < 60; ++trial) {
    InputMesh m = random_mesh(rng);
    LatticeSpec s = random_lattice(rng);
    auto plan = plan_of(m, s, lvl(rng));
    std::vector<float> D(3 * (size_t)s.count());
    for (float& d : D) d = U(rng);
    CpuOut o = run_cpu(plan, D);
    for (float x : o.pos) ASSERT_TRUE(std::isfinite(x)) << "trial " << trial;
    for (float x : o.nrm) ASSERT_TRUE(std::isfinite(x)) << "trial " << trial;
    expect_unit_normals(o);
  }
}

TEST(CpuEvaluator, CollapsingLatticeGivesFiniteOutput) {
  // All control points pulled to one point (a singular deformation: J = 0 inside).
  InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
  LatticeSpec s = bspline_box(2, 4);
  auto plan = plan_of(m, s, 3);
  // Greville abscissae of the clamped degree-2, 4-point axis: 0, 1/4, 3/4, 1; D = -p_ijk.
  const double g[4] = {0, 0.25, 0.75, 1};
  std::vector<float> D;
  for (int i = 0; i < 4; ++i)
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 4; ++k) D.insert(D.end(), {(float)-g[i], (float)-g[j], (float)-g[k]});
  CpuOut o = run_cpu(plan, D);
  for (float x : o.pos) EXPECT_NEAR(x, 0.0f, 1e-5f);
  for (float x : o.nrm) ASSERT_TRUE(std::isfinite(x));
  expect_unit_normals(o);
}

TEST(CpuEvaluator, HugeDisplacementsGiveFiniteOutput) {
  // Regression: vectors above ~1.8e19 overflowed the squared length in normalized_or and
  // 0 * inf made NaN normals, then NaN positions (core/hd.hpp).
  EXPECT_NEAR(length(normalized_or(v3(3e19f, -2e19f, 1e30f), v3(0, 0, 1))), 1.0f, 1e-6f);  // was 0
  V3 n = normalized_or(v3(INFINITY, 0, 0), v3(0, 0, 1));
  EXPECT_EQ(n.z, 1.0f);
  InputMesh m = octahedron(0.47, 0.52, 0.55, 0.4);
  LatticeSpec s = bspline_box(2, 4);
  auto plan = plan_of(m, s, 3);
  for (float scale : {1e20f, 1e30f, 1e36f}) {
    std::vector<float> D(3 * (size_t)s.count());
    for (size_t i = 0; i < D.size(); ++i) D[i] = scale * float((i * 7919) % 13) / 13.0f * (i % 2 ? 1 : -1);
    CpuOut o = run_cpu(plan, D);
    for (float x : o.pos) ASSERT_TRUE(std::isfinite(x)) << scale;
    expect_unit_normals(o);
  }
}

TEST(CpuEvaluator, PositionsOnlyMatchesEvaluateBitwise) {
  // evaluate_positions skips the Jacobians of every sample batch without a sub-vertex, the
  // normal patches and the normal tessellation; its positions must be evaluate's, bit for
  // bit. Each case runs it on a fresh evaluator (zero Jacobian buffer) and on one whose
  // buffers hold another frame (stale Jacobians): a Jacobian read that should not happen
  // changes bits.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> U(-0.6f, 0.6f);
  std::uniform_int_distribution<int> lvl(1, 5);
  int cases = 0;
  auto check = [&](const InputMesh& m, const LatticeSpec& s, int level) {
    auto plan = plan_of(m, s, level);
    std::vector<float> D(3 * (size_t)s.count()), other(D.size());
    for (float& d : D) d = U(rng);
    for (float& d : other) d = U(rng);
    CpuOut full = run_cpu(plan, D);
    std::vector<float> fresh(full.pos.size()), reused(full.pos.size());
    CpuEvaluator a(plan), b(plan);
    a.evaluate_positions(D.data(), fresh.data(), Frame::whole);
    CpuOut scratch{std::vector<float>(full.pos.size()), std::vector<float>(full.nrm.size())};
    b.evaluate(other.data(), scratch.pos.data(), scratch.nrm.data(), Frame::whole);
    StageTimes t = b.evaluate_positions(D.data(), reused.data(), Frame::whole);
    ASSERT_EQ(0, std::memcmp(full.pos.data(), fresh.data(), 4 * full.pos.size())) << "case " << cases;
    ASSERT_EQ(0, std::memcmp(full.pos.data(), reused.data(), 4 * full.pos.size())) << "case " << cases;
    ASSERT_EQ(t.size(), 4u);
    EXPECT_EQ(t.back().first, "tessellate_positions");
    ++cases;
  };
  for (int p = 1; p <= 3; ++p) check(octahedron(0.47, 0.52, 0.55, 0.4), bspline_box(p, p + 3), 4);
  for (int type = 0; type < 4; ++type) check(cube_quads(), blender_box(BlenderInterp(type), 4), 3);
  for (int trial = 0; trial < 40; ++trial) check(random_mesh(rng), random_lattice(rng), lvl(rng));
}

TEST(CpuEvaluator, CentreRowsGiveTheFittedCentre) {
  // The plan's centre rows (plan/centre_rows.hpp, built in double from the lattice) against
  // the fit itself (fit_patch_into, float, from every sample): each patch's geometry from its
  // row and from the fit, on lattices whose knot planes cut the mesh (a patch's samples in
  // several boxes: the rest surface carries them across the planes), Blender's four bases,
  // and random meshes and lattices (repeated knots: bases that jump at a plane).
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> U(-0.6f, 0.6f);
  std::uniform_int_distribution<int> lvl(1, 3);
  int with_rows = 0, straddling = 0;
  double worst = 0;
  auto check = [&](const InputMesh& m, const LatticeSpec& s, int level) {
    auto plan = plan_of(m, s, level);
    if (plan->centre_row.empty()) return;
    ++with_rows;
    std::vector<float> D(3 * (size_t)s.count());
    for (float& d : D) d = U(rng);
    const PlanView pv = host_view(*plan);
    std::vector<float> value(3 * (size_t)pv.samples), jac(9 * (size_t)pv.samples), edge(6 * (size_t)pv.edges);
    FrameView fv{value.data(), jac.data(), edge.data(), nullptr, nullptr, nullptr, nullptr};
    for (int i = 0; i < pv.samples; ++i) sample_point(pv, D.data(), i, value.data() + 3 * i, jac.data() + 9 * i);
    for (int e = 0; e < pv.edges; ++e) adjust_edge(pv, fv, e);
    float scale = 1.0f;
    for (float x : value) scale = std::max(scale, std::fabs(x));
    for (int p = 0; p < pv.patches; ++p) {
      float g[30], n[30];
      fit_patch_into(pv, fv, p, g, n);
      V3 corner[3], cp[3][2], h[10];
      patch_boundary(pv, fv, p, corner, cp);
      patch_from_centre_row(corner, cp, centre_row_value(pv, D.data(), p), h);
      for (int r = 0; r < 10; ++r) {
        const V3 d = h[r] - load3(g + 3 * r);
        const double err = std::max({std::fabs(d.x), std::fabs(d.y), std::fabs(d.z)}) / scale;
        worst = std::max(worst, err);
        // The fit's float sums (K ~ 10-40 samples, M_r's entries up to about 10) round to a
        // few 1e-6 of the samples' size; a wrong term in a row moves the centre by 1e-2 and more.
        ASSERT_LE(err, 1e-5) << "patch " << p << " row " << r;
        if (r < kCentre) ASSERT_EQ(err, 0.0);  // corners and edge points: the same floats
      }
      const int* ps = pv.patch_samples + (size_t)p * pv.columns;
      for (int k = 1; k < pv.columns; ++k) straddling += pv.sample_piece[ps[k]] != pv.sample_piece[ps[0]];
    }
  };
  for (int p = 1; p <= 3; ++p) check(octahedron(0.47, 0.52, 0.55, 0.4), bspline_box(p, p + 3), 3);
  for (int type = 0; type < 4; ++type) check(cube_quads(), blender_box(BlenderInterp(type), 4), 2);
  for (int trial = 0; trial < 40; ++trial) check(random_mesh(rng), random_lattice(rng), lvl(rng));
  EXPECT_GE(with_rows, 30);
  EXPECT_GT(straddling, 0);  // patches whose samples lie in several boxes were met
  std::printf("centre rows: %d plans, %d samples in another box than their patch's first, largest "
              "difference %.2e of the scale\n",
              with_rows, straddling, worst);
}

TEST(CpuEvaluator, CentreRowsOnlyWhereTheCentreIsLinear) {
  // Point weights (F = p + w^2 s d) are not linear in the control values: no rows, and the
  // plan still evaluates (the fit's centre).
  LatticeSpec w = blender_box(BlenderInterp::BSpline, 4);
  w.components = 4;
  auto weighted = plan_of(octahedron(), w, 2);
  EXPECT_TRUE(weighted->centre_row.empty());
  auto plain = plan_of(octahedron(), blender_box(BlenderInterp::BSpline, 4), 2);
  ASSERT_EQ(plain->centre_start.size(), (size_t)plain->patches + 1);
  EXPECT_EQ(plain->centre_row.size(), (size_t)plain->centre_start.back());
  std::vector<float> D(4 * (size_t)w.count(), 0.1f), D3(3 * (size_t)w.count(), 0.1f);
  for (size_t i = 0; i < D3.size(); ++i) D[4 * (i / 3) + i % 3] = D3[i];
  for (size_t i = 3; i < D.size(); i += 4) D[i] = 1.0f;  // weight 1 everywhere: the plain lattice
  CpuOut a = run_cpu(weighted, D), b = run_cpu(plain, D3);
  ASSERT_EQ(a.pos.size(), b.pos.size());
  for (size_t i = 0; i < a.pos.size(); ++i) ASSERT_NEAR(a.pos[i], b.pos[i], 1e-6f);
}

TEST(CpuEvaluator, UpdateMatchesWholeFramesBitwise) {
  // Incremental frames (eval/cpu_update.hpp) against a fresh evaluator's whole frame
  // for the same control values, bit for bit, in each kind (corner normals, compact, positions
  // only), over a run of frames that move one point, a few, none, or all of them. An element
  // whose block missed a control point it reads keeps a stale value and changes bits.
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> U(-0.3f, 0.3f);
  int cases = 0, partial = 0;
  auto check = [&](const InputMesh& m, const LatticeSpec& s, int level) {
    auto plan = plan_of(m, s, level);
    const int C = s.components;
    const size_t points = (size_t)s.count();
    std::vector<float> D(C * points);
    for (size_t i = 0; i < D.size(); ++i) D[i] = C == 4 && i % 4 == 3 ? 1.0f : U(rng);
    const size_t N = 3 * (size_t)plan->output_vertices;
    for (int kind = 0; kind < 3; ++kind) {
      CpuEvaluator inc(plan);
      const size_t nn = kind == 0 ? 9 * (size_t)plan->output_triangles : kind == 1 ? 3 * (size_t)plan->render_vertices : 0;
      std::vector<float> pos(N), nrm(nn), want_pos(N), want_nrm(nn);
      auto frame = [&](CpuEvaluator& ev, Frame f, float* p, float* n) {
        if (kind == 0) return ev.evaluate(D.data(), p, n, f);
        if (kind == 1) return ev.evaluate_compact(D.data(), p, n, f);
        return ev.evaluate_positions(D.data(), p, f);
      };
      for (int step = 0; step < 8; ++step) {
        // step 0: the first frame (whole); 1-4: one random point; 5: three; 6: none; 7: all
        std::uniform_int_distribution<size_t> pick(0, points - 1);
        const int moves = step == 0 ? 0 : step <= 4 ? 1 : step == 5 ? 3 : step == 6 ? 0 : (int)points;
        for (int i = 0; i < moves; ++i) {
          const size_t q = step == 7 ? (size_t)i : pick(rng);
          D[C * q + rng() % 3] += U(rng);
          if (C == 4 && step == 5) D[C * q + 3] = 0.5f + 0.5f * (U(rng) + 0.3f);  // a weight too
        }
        frame(inc, Frame::incremental, pos.data(), nrm.data());
        CpuEvaluator whole(plan);
        frame(whole, Frame::whole, want_pos.data(), want_nrm.data());
        ASSERT_EQ(0, std::memcmp(pos.data(), want_pos.data(), 4 * N)) << "case " << cases << " kind " << kind << " step " << step;
        // (positions only: no normals, and memcmp may not be handed the empty vectors' nullptr)
        ASSERT_TRUE(nn == 0 || std::memcmp(nrm.data(), want_nrm.data(), 4 * nn) == 0)
            << "case " << cases << " kind " << kind << " step " << step;
        const FrameCounts c = inc.last_frame();
        if (step == 0 || step == 7) EXPECT_EQ(c.patches, plan->patches);
        if (step == 6) {
          EXPECT_EQ(c.changed_points, 0);
          EXPECT_EQ(c.patches, 0);
        }
        if (step >= 1 && step <= 4) EXPECT_EQ(c.changed_points, 1);
        partial += step >= 1 && step <= 4 && c.patches < plan->patches;
      }
    }
    ++cases;
  };
  for (int p = 1; p <= 3; ++p) check(octahedron(0.47, 0.52, 0.55, 0.4), bspline_box(p, p + 4), 3);
  for (int type = 0; type < 4; ++type) check(cube_quads(), blender_box(BlenderInterp(type), 6), 2);
  LatticeSpec weighted = blender_box(BlenderInterp::BSpline, 5);
  weighted.components = 4;
  check(flat_grid(6), weighted, 2);
  for (int trial = 0; trial < 30; ++trial) check(random_mesh(rng), random_lattice(rng), 1 + trial % 4);
  EXPECT_GT(partial, 50);  // most single-point frames recompute part of the mesh only
}

TEST(CpuEvaluator, IncrementalFrameIsWholeWhereItCannotContinue) {
  // Another kind, other arrays, a whole frame, or no frame before: a whole frame, right output.
  // Through the evaluator interface, as the bindings call it.
  auto plan = plan_of(cube_quads(), blender_box(BlenderInterp::BSpline, 6), 2);
  std::vector<float> D(3 * 216, 0.0f);
  std::vector<float> pos(3 * (size_t)plan->output_vertices), other(pos.size()), nrm(3 * (size_t)plan->render_vertices);
  CpuEvaluator cpu(plan);
  Evaluator& ev = cpu;
  EXPECT_EQ(ev.last_frame().patches, 0);  // no frame yet
  ev.evaluate_positions(D.data(), pos.data(), Frame::incremental);
  EXPECT_EQ(ev.last_frame().patches, plan->patches);  // none before
  D[0] = 0.1f;
  ev.evaluate_positions(D.data(), pos.data(), Frame::incremental);
  EXPECT_LT(ev.last_frame().patches, plan->patches);
  EXPECT_EQ(ev.last_frame().changed_points, 1);
  D[1] = 0.1f;
  ev.evaluate_positions(D.data(), other.data(), Frame::incremental);  // other arrays
  EXPECT_EQ(ev.last_frame().patches, plan->patches);
  ev.evaluate_compact(D.data(), other.data(), nrm.data(), Frame::incremental);  // another kind
  EXPECT_EQ(ev.last_frame().patches, plan->patches);
  D[2] = 0.1f;
  ev.evaluate_compact(D.data(), other.data(), nrm.data(), Frame::whole);  // asked for a whole frame
  EXPECT_EQ(ev.last_frame().patches, plan->patches);
  EXPECT_EQ(ev.last_frame().changed_points, 216);
  D[2] = 0.2f;
  ev.evaluate_compact(D.data(), other.data(), nrm.data(), Frame::incremental);  // continues the whole frame
  EXPECT_LT(ev.last_frame().patches, plan->patches);
  EXPECT_EQ(ev.last_frame().changed_points, 1);
  CpuOut want = run_cpu(plan, D);
  EXPECT_EQ(0, std::memcmp(want.pos.data(), other.data(), 4 * other.size()));
  EXPECT_GT(cpu.update_bytes(), 0u);
}
