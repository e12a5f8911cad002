// B-spline knots that do not start at 0 (a case fuzz_plan generates): the float tables of
// the plan measure such an axis's parameter from its first knot plane, so a lattice whose knots
// sit at 2^20 + [0, 1] deforms as the same lattice at [0, 1]; ordinary lattices keep their
// tables bit for bit.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// bspline_box(p, n) over [0, 1]^3 with every knot and the map's offset moved by `offset`.
LatticeSpec offset_box(int p, int n, double offset) {
  LatticeSpec s;
  for (int a = 0; a < 3; ++a) {
    std::vector<double> U = clamped_knots(p, n);
    for (double& u : U) u += offset;
    s.axes[a] = AxisBasis::bspline(p, U, n);
    s.object_to_param[a][a] = 1.0;
    s.object_to_param[a][3] = offset;
  }
  return s;
}

std::vector<float> random_values(const LatticeSpec& s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.2f, 0.2f);
  std::vector<float> D(3 * (size_t)s.count());
  for (float& d : D) d = u(rng);
  return D;
}

}  // namespace

// The input vertices' images are exact lattice images (plan.hpp): with the knots moved away
// from 0 they are still the lattice's own (double) ones, and the unshifted lattice's. (The rest
// of the output is compared in size only: a clip vertex rounds differently at 2^20, which may
// flip a tie in the clipped pieces' triangulation.)
TEST(KnotOffsets, OffsetKnotsDeformAsUnshiftedOnes) {
  InputMesh mesh = flat_grid(6, 0.05, 0.95, 0.41);
  const int V = (int)mesh.positions.size() / 3;
  for (double offset : {1024.0, 1048576.0, -1048576.0}) {
    LatticeSpec ref = bspline_box(3, 6), moved = offset_box(3, 6, offset);
    std::vector<float> D = random_values(ref, 5);
    CpuOut a = run_cpu(plan_of(mesh, ref, 4), D, 1), b = run_cpu(plan_of(mesh, moved, 4), D, 1);
    ASSERT_EQ(a.pos.size(), b.pos.size());
    std::vector<double> Dd(D.begin(), D.end());
    double worst = 0;
    for (int v = 0; v < V; ++v) {
      double F[3], J[9];
      moved.evaluate(&mesh.positions[3 * (size_t)v], Dd.data(), 1.0, F, J);
      for (int i = 0; i < 3; ++i) {
        worst = std::fmax(worst, std::fabs(b.pos[3 * (size_t)v + i] - F[i]));
        worst = std::fmax(worst, std::fabs(b.pos[3 * (size_t)v + i] - a.pos[3 * (size_t)v + i]));
      }
    }
    // Before: 2^20 + [0, 1] in float has steps of 1/8 against knot spans of 1/3.
    EXPECT_LT(worst, 2e-6) << "offset " << offset;
  }
}

TEST(KnotOffsets, OrdinaryLatticesKeepTheirTables) {
  InputMesh mesh = octahedron();
  std::vector<LatticeSpec> specs = {bspline_box(2, 5, -0.3, 1.7), bspline_box(3, 7),
                                    blender_box(BlenderInterp::BSpline, 4),
                                    blender_box(BlenderInterp::Cardinal, 3, -2.0, 5.0)};
  for (const LatticeSpec& s : specs) {
    auto plan = plan_of(mesh, s, 2);
    for (int a = 0; a < 3; ++a) {
      for (int c = 0; c < 4; ++c) EXPECT_EQ(plan->param_map[4 * a + c], (float)s.object_to_param[a][c]);
      const auto& pieces = s.axes[a].pieces();
      for (size_t i = 0; i < pieces.size(); ++i)
        EXPECT_EQ(plan->pieces[plan->axis_offset[a] + i].origin, (float)pieces[i].origin);
    }
  }
}
