// The per-frame code paths of the CPU evaluator (runtime dispatch, core/isa.hpp): the
// baseline (x86-64-v2 in shipped builds) and the x86-64-v3 copy (AVX2 + FMA) agree to float
// rounding, each is bitwise the same for every thread count and its positions-only variant
// matches its full evaluation, and unknown or unavailable paths are refused.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <stdexcept>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/eval/cpu_evaluator.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

std::vector<float> random_values(const LatticeSpec& s, unsigned seed, float amplitude) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(-amplitude, amplitude);
  std::vector<float> D(3 * (size_t)s.count());
  for (float& d : D) d = U(rng);
  return D;
}

// Largest extent of the deformed model (the scale float rounding is relative to).
double model_size(const std::vector<float>& pos) {
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (size_t i = 0; i < pos.size(); ++i) {
    lo[i % 3] = std::min(lo[i % 3], (double)pos[i]);
    hi[i % 3] = std::max(hi[i % 3], (double)pos[i]);
  }
  return std::max({hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]});
}

bool have_v3() {
  auto isas = cpu_isas();
  return std::find(isas.begin(), isas.end(), "x86-64-v3") != isas.end();
}

struct Case {
  const char* name;
  InputMesh mesh;
  LatticeSpec lattice;
  int level;
  float amplitude;
};

std::vector<Case> cases() {
  InputMesh wavy = flat_grid(12, 0.05, 0.95, 0.4);
  for (size_t i = 2; i < wavy.positions.size(); i += 3) wavy.positions[i] += 0.1 * std::sin(7 * wavy.positions[i - 2]);
  return {
      {"wavy grid, B-spline 2 / 5^3", wavy, bspline_box(2, 5), 6, 0.2f},
      {"octahedron, B-spline 3 / 6^3", octahedron(0.47, 0.52, 0.55, 0.4), bspline_box(3, 6), 5, 0.15f},
      {"cube, Blender B-spline 4^3", cube_quads(), blender_box(BlenderInterp::BSpline, 4), 4, 0.3f},
  };
}

}  // namespace

TEST(CpuIsa, ReportsTheBaselineAndTheChosenPath) {
  const auto isas = cpu_isas();
  ASSERT_FALSE(isas.empty());
  EXPECT_EQ(isas.front(), SFFD_ISA_NAME);  // the baseline copy comes first
  EXPECT_EQ(cpu_isa(), isas.back());       // auto takes the best
  auto plan = plan_of(octahedron(), bspline_box(2, 4), 2);
  EXPECT_EQ(CpuEvaluator(plan).isa(), cpu_isa());
  EXPECT_EQ(CpuEvaluator(plan, 1, "auto").isa(), cpu_isa());
  for (const std::string& isa : isas) EXPECT_EQ(CpuEvaluator(plan, 1, isa).isa(), isa);
  EXPECT_THROW(CpuEvaluator(plan, 1, "x86-64-v9"), std::invalid_argument);
  EXPECT_THROW(CpuEvaluator(plan, 1, "avx2"), std::invalid_argument);
  if (!have_v3()) EXPECT_THROW(CpuEvaluator(plan, 1, "x86-64-v3"), std::invalid_argument);
}

TEST(CpuIsa, PathsAgreeToFloatRounding) {
  if (!have_v3()) GTEST_SKIP() << "one path only (no x86-64-v3 copy in this build, or a CPU without AVX2/FMA)";
  const std::string base = cpu_isas().front();
  for (const Case& c : cases()) {
    auto plan = plan_of(c.mesh, c.lattice, c.level);
    auto D = random_values(c.lattice, 11, c.amplitude);
    CpuOut a = run_cpu(plan, D, 0, base), b = run_cpu(plan, D, 0, "x86-64-v3");
    const double size = model_size(a.pos);
    ASSERT_GT(size, 0.1) << c.name;
    double dpos = 0, dnrm = 0;
    for (size_t i = 0; i < a.pos.size(); ++i) dpos = std::max(dpos, (double)std::fabs(a.pos[i] - b.pos[i]));
    for (size_t i = 0; i < a.nrm.size(); ++i) dnrm = std::max(dnrm, (double)std::fabs(a.nrm[i] - b.nrm[i]));
    EXPECT_LE(dpos, 1e-5 * size) << c.name;
    EXPECT_LE(dnrm, 1e-5) << c.name;  // unit normals
    // Not bitwise the same (FMA contraction), or the v3 path would not be running.
    EXPECT_NE(0, std::memcmp(a.pos.data(), b.pos.data(), 4 * a.pos.size())) << c.name;
  }
}

TEST(CpuIsa, EachPathIsBitwiseTheSameForEveryThreadCount) {
  for (const std::string& isa : cpu_isas()) {
    for (const Case& c : cases()) {
      auto plan = plan_of(c.mesh, c.lattice, c.level);
      auto D = random_values(c.lattice, 5, c.amplitude);
      CpuOut one = run_cpu(plan, D, 1, isa);
      for (int threads : {2, 7}) {
        CpuOut many = run_cpu(plan, D, threads, isa);
        EXPECT_EQ(0, std::memcmp(one.pos.data(), many.pos.data(), 4 * one.pos.size())) << isa << ", " << c.name;
        EXPECT_EQ(0, std::memcmp(one.nrm.data(), many.nrm.data(), 4 * one.nrm.size())) << isa << ", " << c.name;
      }
    }
  }
}

TEST(CpuIsa, EachPathsPositionsOnlyMatchItsEvaluateBitwise) {
  for (const std::string& isa : cpu_isas()) {
    for (const Case& c : cases()) {
      auto plan = plan_of(c.mesh, c.lattice, c.level);
      auto D = random_values(c.lattice, 9, c.amplitude);
      CpuOut full = run_cpu(plan, D, 0, isa);
      CpuEvaluator ev(plan, 0, isa);
      std::vector<float> pos(full.pos.size());
      ev.evaluate_positions(D.data(), pos.data(), Frame::whole);
      EXPECT_EQ(0, std::memcmp(full.pos.data(), pos.data(), 4 * pos.size())) << isa << ", " << c.name;
    }
  }
}
