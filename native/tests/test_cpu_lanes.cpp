// The CPU's vectorized stages against the scalar code of eval/stages.hpp, which the CUDA
// evaluator runs one thread an element:
// * batched sampling (eval/cpu_sampling.hpp: kLanes samples of one lattice box at a time) vs
//   sample_point: same values and Jacobians up to float rounding, for every sample of random
//   meshes in random lattices (every supported degree, both kinds, 1-point axes, with and
//   without point weights), and every sample written exactly once by the batches; with point
//   weights both also against LatticeSpec::evaluate (double);
// * the fit with the centre row on lanes (eval/cpu_fitting.hpp) vs fit_patch_into, including
//   columns whose Jacobian is singular (the normalization fallbacks);
// * the grid normals on lanes (eval/cpu_tessellation.hpp) vs tessellate_normal, including
//   normal patches that vanish (the fallback);
// * the edge adjustment from the per-frame table of distinct end normals (eval/cpu_frame.hpp)
//   vs adjust_edge: bitwise (the same operations on the same values), including sharp ends,
//   boundary and kept edges and singular Jacobians.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "smoothffd/eval/cpu_fitting.hpp"
#include "smoothffd/eval/cpu_frame.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/eval/cpu_tessellation.hpp"
#include "smoothffd/eval/lanes.hpp"
#include "smoothffd/eval/stages.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

TEST(CpuSampling, BatchesMatchScalarSamplePoint) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.2f, 0.2f);
  int checked = 0, weighted = 0;
  for (int trial = 0; trial < 40; ++trial) {
    LatticeSpec s = random_lattice(rng);
    if (trial >= 34) s = bspline_box(trial % 2 ? 5 : 4, 7, -0.1, 1.1);  // the 6-term contraction
    // Point weights (Blender's lattice vertex group) come only with Blender's lattices, at most
    // 4 terms an axis: the 6-term boxes above are unweighted (cpu_sampling.cpp has no such copy).
    if (trial % 3 == 2 && trial < 34) s.components = 4;
    InputMesh m = random_mesh(rng);  // half of them with per-vertex factors
    PlanOptions opt;
    opt.level = 2;
    Plan plan;
    try {
      plan = build_plan(m, s, opt);
    } catch (const std::invalid_argument&) {
      continue;  // a degenerate random mesh: not this test's subject
    }
    std::vector<float> D = zero_values(s);
    for (float& d : D) d = jitter(rng);
    if (s.components == 4)  // the weights in [0, 1]
      for (size_t i = 3; i < D.size(); i += 4) D[i] = 2.5f * (D[i] + 0.2f);
    ASSERT_EQ(plan.components, s.components);
    const PlanView pv = host_view(plan);
    const SampleBatches sb = make_sample_batches(plan);
    // Every sample in exactly one batch, every batch one box and at most kLanes samples.
    std::vector<int> seen(plan.samples, 0);
    for (long long b = 0; b < sb.count(); ++b) {
      ASSERT_LE(sb.start[b + 1] - sb.start[b], kLanes);
      ASSERT_GT(sb.start[b + 1] - sb.start[b], 0);
      for (int i = sb.start[b]; i < sb.start[b + 1]; ++i) {
        ++seen[sb.order[i]];
        ASSERT_EQ(plan.sample_piece[sb.order[i]], plan.sample_piece[sb.order[sb.start[b]]]);
      }
    }
    for (int c : seen) ASSERT_EQ(c, 1);
    // Each box's samples together, in plan order, in as few batches as kLanes allows.
    std::map<uint32_t, int> in_box;
    for (int s2 = 0; s2 < plan.samples; ++s2) ++in_box[plan.sample_piece[s2]];
    long long fewest = 0;
    for (const auto& kv : in_box) fewest += (kv.second + kLanes - 1) / kLanes;
    ASSERT_EQ(sb.count(), fewest);
    for (int i = 1; i < plan.samples; ++i)
      if (plan.sample_piece[sb.order[i]] == plan.sample_piece[sb.order[i - 1]])
        ASSERT_LT(sb.order[i - 1], sb.order[i]);

    std::vector<float> F(3 * (size_t)plan.samples, NAN), J(9 * (size_t)plan.samples, NAN);
    std::vector<float> Fv(3 * (size_t)plan.samples, NAN);
    for (long long b = 0; b < sb.count(); ++b) {
      sample_batch(pv, D.data(), sb, b, F.data(), J.data());
      sample_batch(pv, D.data(), sb, b, Fv.data(), nullptr);
    }
    for (int i = 0; i < plan.samples; ++i) {
      float f[3], j[9];
      sample_point(pv, D.data(), i, f, j);
      double scale = 1.0;
      for (int r = 0; r < 3; ++r) scale = std::max(scale, (double)std::fabs(f[r]));
      for (int r = 0; r < 3; ++r) {
        ASSERT_NEAR(F[3 * i + r], f[r], 2e-6 * scale) << "sample " << i;
        ASSERT_EQ(Fv[3 * i + r], F[3 * i + r]) << "values-only batch differs, sample " << i;
      }
      for (int r = 0; r < 9; ++r)
        ASSERT_NEAR(J[9 * i + r], j[r], 2e-5 * std::max(1.0, (double)std::fabs(j[r]))) << "sample " << i;
      if (s.components == 4) {
        const std::vector<double> Dd(D.begin(), D.end());
        const double p[3] = {pv.sample_position[3 * i], pv.sample_position[3 * i + 1], pv.sample_position[3 * i + 2]};
        double fd[3], jd[9];
        s.evaluate(p, Dd.data(), pv.sample_weight[i], fd, jd);
        for (int r = 0; r < 3; ++r) ASSERT_NEAR(f[r], fd[r], 2e-6 * scale) << "weighted sample " << i;
        ++weighted;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_GT(weighted, 300);
}

namespace {

// A level-2 plan of m in s with random control values D (in +-0.2) and every sample's value
// and Jacobian from the scalar sample_point; false for a degenerate random mesh (not these
// tests' subject).
struct SampledPlan {
  Plan plan;
  std::vector<float> D, value, jac;
};

bool sampled_plan(const InputMesh& m, const LatticeSpec& s, std::mt19937& rng, SampledPlan& out) {
  std::uniform_real_distribution<float> jitter(-0.2f, 0.2f);
  PlanOptions opt;
  opt.level = 2;
  try {
    out.plan = build_plan(m, s, opt);
  } catch (const std::invalid_argument&) {
    return false;
  }
  out.D = zero_values(s);
  for (float& d : out.D) d = jitter(rng);
  const PlanView pv = host_view(out.plan);
  out.value.assign(3 * (size_t)out.plan.samples, 0.0f);
  out.jac.assign(9 * (size_t)out.plan.samples, 0.0f);
  for (int i = 0; i < out.plan.samples; ++i) sample_point(pv, out.D.data(), i, &out.value[3 * i], &out.jac[9 * i]);
  return true;
}

}  // namespace

TEST(CpuFitting, LanesMatchScalarFitPatch) {
  std::mt19937 rng(11);
  int checked = 0;
  for (int trial = 0; trial < 30; ++trial) {
    LatticeSpec s = trial < 25 ? random_lattice(rng) : bspline_box(trial % 2 ? 5 : 3, 7, -0.1, 1.1);
    InputMesh m = random_mesh(rng);
    SampledPlan sp;
    if (!sampled_plan(m, s, rng, sp)) continue;
    const Plan& plan = sp.plan;
    std::vector<float>& value = sp.value;
    std::vector<float>& jac = sp.jac;
    const PlanView pv = host_view(plan);
    std::vector<float> edge(6 * (size_t)plan.edges + 6);
    // Singular Jacobians at every 5th sample past the corners: zero cofactor, fallback normals.
    for (int i = plan.sub_vertices; i < plan.samples; i += 5)
      for (int r = 0; r < 9; ++r) jac[9 * (size_t)i + r] = 0.0f;
    FrameView fv{value.data(), jac.data(), edge.data(), nullptr, nullptr, nullptr, nullptr};
    for (int e = 0; e < plan.edges; ++e) adjust_edge(pv, fv, e);
    const FitColumns fc = make_fit_columns(plan);
    for (int p = 0; p < plan.patches; ++p) {
      float g0[30], n0[30], g1[30], n1[30], g2[30];
      fit_patch_into(pv, fv, p, g0, n0);
      fit_patch_lanes(pv, fv, fc, p, g1, n1);
      fit_patch_lanes(pv, fv, fc, p, g2, nullptr);
      for (int i = 0; i < 30; ++i) {
        ASSERT_NEAR(g1[i], g0[i], 2e-5 * std::max(1.0f, std::fabs(g0[i]))) << "patch " << p;
        ASSERT_NEAR(n1[i], n0[i], 2e-5 * std::max(1.0f, std::fabs(n0[i]))) << "patch " << p;
        ASSERT_EQ(g2[i], g1[i]) << "geometry-only fit differs, patch " << p;
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 300);
}

TEST(CpuTessellation, GridNormalsMatchScalarTessellateNormal) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(-1.0f, 1.0f);
  InputMesh m = octahedron();
  for (int level : {1, 2, 3, 7, 10}) {
    PlanOptions opt;
    opt.level = level;
    Plan plan = build_plan(m, bspline_box(2, 4), opt);
    const PlanView pv = host_view(plan);
    std::vector<float> normal_patches(30 * (size_t)plan.patches);
    for (float& x : normal_patches) x = U(rng);
    // Patch 0: all zero (every grid normal falls back); patch 1: huge (l2 overflows).
    for (int i = 0; i < 30; ++i) normal_patches[i] = 0.0f;
    for (int i = 30; i < 60; ++i) normal_patches[i] *= 3e19f;
    FrameView fv{nullptr, nullptr, nullptr, nullptr, normal_patches.data(), nullptr, nullptr};
    const GridBasisLanes gb = make_grid_basis_lanes(plan);
    std::vector<float> out(3 * (size_t)gb.padded);
    for (int p = 0; p < plan.patches; ++p) {
      patch_grid_normals(pv, fv, gb, p, out.data());
      for (int g = 0; g < plan.grid; ++g) {
        V3 ref = tessellate_normal(pv, fv, p, g);
        ASSERT_NEAR(out[g], ref.x, 1e-6f) << "patch " << p << " grid " << g;
        ASSERT_NEAR(out[gb.padded + g], ref.y, 1e-6f);
        ASSERT_NEAR(out[2 * gb.padded + g], ref.z, 1e-6f);
      }
    }
  }
}

TEST(CpuEdges, EndNormalTableMatchesAdjustEdge) {
  std::mt19937 rng(23);
  int checked = 0, shared = 0;
  for (int trial = 0; trial < 36; ++trial) {
    LatticeSpec s = trial % 4 == 3 ? blender_box(BlenderInterp::BSpline, 4, -0.1, 1.1) : random_lattice(rng);
    InputMesh m = trial % 6 == 0 ? octahedron() : trial % 6 == 1 ? cube_quads() : random_mesh(rng);
    SampledPlan sp;
    if (!sampled_plan(m, s, rng, sp)) continue;
    const Plan& plan = sp.plan;
    std::vector<float>& value = sp.value;
    std::vector<float>& jac = sp.jac;
    const PlanView pv = host_view(plan);
    for (int i = 0; i < plan.sub_vertices; i += 7)  // singular: the fallback normals
      for (int r = 0; r < 9; ++r) jac[9 * (size_t)i + r] = 0.0f;
    std::vector<float> edge0(6 * (size_t)plan.edges), edge1(6 * (size_t)plan.edges, -1.0f);
    FrameView fv{value.data(), jac.data(), edge0.data(), nullptr, nullptr, nullptr, nullptr};
    for (int e = 0; e < plan.edges; ++e) adjust_edge(pv, fv, e);
    const EdgeEndNormals en = make_edge_end_normals(plan);
    int ends = 0;
    for (int id : en.edge_end) ends += id >= 0;
    ASSERT_LE(en.count(), ends);
    shared += en.count() < ends;
    std::vector<float> normals(3 * (size_t)en.count());
    FrameView fv1 = fv;
    fv1.edge_control = edge1.data();
    cpu_frame_kernels_baseline.end_normals(fv1, en, 0, en.count(), normals.data());
    cpu_frame_kernels_baseline.adjust_edges(pv, fv1, en, normals.data(), 0, plan.edges);
    for (size_t i = 0; i < edge0.size(); ++i) ASSERT_EQ(edge1[i], edge0[i]) << "edge " << i / 6;
    ++checked;
  }
  EXPECT_GT(checked, 25);
  EXPECT_GT(shared, 20);  // smooth vertices: the patches around them share their end normals
}
