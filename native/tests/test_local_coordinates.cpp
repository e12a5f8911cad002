// Samples' local coordinates (Plan::sample_local): where the evaluators' float
// arithmetic cannot place a sample within its knot span, the plan gives each sample its
// coordinate t in its span, computed in double; ordinary lattices keep t from the position
// (no table, bitwise the frames of before).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/eval/stages.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// Degree-2 lattice over [0, 1]^3 with inner knots `inner` (clamped) on every axis.
LatticeSpec knotted(const std::vector<double>& inner) {
  LatticeSpec s;
  const int p = 2, n = (int)inner.size() - 1 + p;
  std::vector<double> U(p, inner.front());
  U.insert(U.end(), inner.begin(), inner.end());
  U.insert(U.end(), p, inner.back());
  for (int a = 0; a < 3; ++a) {
    s.axes[a] = AxisBasis::bspline(p, U, n);
    s.object_to_param[a][a] = 1.0;
  }
  return s;
}

std::vector<float> random_values(const LatticeSpec& s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.1f, 0.1f);
  std::vector<float> D(3 * (size_t)s.count());
  for (float& d : D) d = u(rng);
  return D;
}

}  // namespace

TEST(LocalCoordinates, OrdinaryLatticesHaveNone) {
  InputMesh mesh = octahedron(0.47, 0.52, 0.55, 0.4);
  EXPECT_TRUE(plan_of(mesh, knotted({0, 0.25, 0.5, 0.75, 1}), 2)->sample_local.empty());
  EXPECT_TRUE(plan_of(mesh, bspline_box(3, 9), 2)->sample_local.empty());
}

TEST(LocalCoordinates, TinySpansAreEvaluatedAtTheSamplesOwnT) {
  // Two spans of 1e-7 next to spans of 0.2 .. 0.5: a float position resolves them to about a
  // quarter, the plan's t to float rounding.
  InputMesh mesh = octahedron(0.47, 0.52, 0.55, 0.4);
  LatticeSpec spec = knotted({0, 0.3, 0.5, 0.5 + 1e-7, 0.5 + 2e-7, 1});
  auto plan = plan_of(mesh, spec, 3);
  ASSERT_EQ(plan->sample_local.size(), 3 * (size_t)plan->samples);
  for (int s = 0; s < plan->samples; ++s)
    for (int a = 0; a < 3; ++a) {
      const float t = plan->sample_local[3 * (size_t)s + a];
      EXPECT_TRUE(t > -0.5f && t < 1.5f) << s << " " << a << " " << t;  // in (or next to) its span
    }
  // Every sample evaluates F where the plan placed it (in double), not where its float
  // position rounds to: sample_point against LatticeSpec::evaluate at the position the plan's
  // t gives, and the input vertices, exact samples, against their images.
  std::vector<float> D = random_values(spec, 3);
  std::vector<double> Dd(D.begin(), D.end());
  const PlanView pv = host_view(*plan);
  const int V = (int)mesh.positions.size() / 3;
  for (int v = 0; v < V; ++v) {
    float F[3], J[9];
    sample_point(pv, D.data(), v, F, J);
    double Fd[3], Jd[9];
    spec.evaluate(&mesh.positions[3 * (size_t)v], Dd.data(), 1.0, Fd, Jd);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(F[i], Fd[i], 1e-6) << v;
  }
  CpuOut out = run_cpu(plan, D, 1);
  for (int v = 0; v < V; ++v) {
    double Fd[3], Jd[9];
    spec.evaluate(&mesh.positions[3 * (size_t)v], Dd.data(), 1.0, Fd, Jd);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(out.pos[3 * (size_t)v + i], Fd[i], 1e-6) << v;
  }
}
