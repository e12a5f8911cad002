// The float lattice tables (plan/lattice_tables.hpp): the shift of far-off knots, the map, and
// the pieces as the evaluators read them.
#include <gtest/gtest.h>

#include <cmath>

#include "smoothffd/plan/lattice_tables.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

TEST(LatticeTables, ShiftOnlyForKnotsFarFromZero) {
  EXPECT_EQ(float_shift(AxisBasis::bspline(2, clamped_knots(2, 5), 5)), 0.0);
  // Planes at 1000 .. 1001: further from 0 than their extent.
  std::vector<double> far = clamped_knots(2, 5);
  for (double& k : far) k += 1000;
  EXPECT_EQ(float_shift(AxisBasis::bspline(2, far, 5)), 1000.0);
  // Planes at -3 .. 7: 3 from 0, 10 wide.
  std::vector<double> wide = clamped_knots(2, 5);
  for (double& k : wide) k = 10 * k - 3;
  EXPECT_EQ(float_shift(AxisBasis::bspline(2, wide, 5)), 0.0);
}

TEST(LatticeTables, ABoxMapsAndPiecesByHand) {
  // Degree 2, 5 control points on [2, 4]^3: s = (p - 2) / 2, knot spans of 1/3 in s.
  const LatticeSpec s = bspline_box(2, 5, 2.0, 4.0);
  Plan plan;
  build_lattice_tables(plan, s);
  EXPECT_EQ(plan.components, 3);
  for (int a = 0; a < 3; ++a) {
    EXPECT_EQ(plan.dims[a], 5);
    for (int c = 0; c < 3; ++c) EXPECT_EQ(plan.param_map[4 * a + c], a == c ? 0.5f : 0.0f);
    EXPECT_EQ(plan.param_map[4 * a + 3], -1.0f);
  }
  const int per_axis = (int)s.axes[0].pieces().size();
  EXPECT_EQ(plan.axis_offset[0], 0);
  EXPECT_EQ(plan.axis_offset[1], per_axis);
  EXPECT_EQ(plan.axis_offset[2], 2 * per_axis);
  ASSERT_EQ(plan.pieces.size(), 3u * per_axis);
  for (int a = 0; a < 3; ++a)
    for (int i = 0; i < per_axis; ++i) {
      const AxisPieceF& f = plan.pieces[plan.axis_offset[a] + i];
      const AxisPiece& d = s.axes[a].pieces()[i];
      EXPECT_EQ(f.degree, d.degree);
      EXPECT_EQ(f.count, d.count);
      EXPECT_EQ(f.origin, (float)d.origin);  // no shift
      EXPECT_FLOAT_EQ(f.inv_scale, 1.0f / (float)d.scale);
      for (int k = 0; k < kMaxTerms; ++k) {
        EXPECT_GE(f.index[k], 0);
        EXPECT_LT(f.index[k], 5);
        if (k >= f.count) {  // padding: index 0, weight 0
          EXPECT_EQ(f.index[k], 0);
          for (int q = 0; q < kMaxTerms; ++q) EXPECT_EQ(f.coef[k][q], 0.0f);
        }
      }
    }
  LatticeSpec w = s;
  w.components = 4;
  build_lattice_tables(plan, w);
  EXPECT_EQ(plan.components, 4);
  EXPECT_EQ(plan.pieces.size(), 3u * per_axis);  // built afresh
}

TEST(LatticeTables, FarOffKnotsKeepTheirSpansInFloat) {
  // An axis u with knot spans of 2.4e-4 near s = -13451.5 (s = p - 13451.5): in float, s has
  // steps of 1e-3 there and the spans vanish; measured from the first plane they keep 7 digits.
  const double s0 = -13451.4916, h = 2.4e-4;
  LatticeSpec s = bspline_box(2, 5);
  std::vector<double> U = clamped_knots(2, 5);
  for (double& k : U) k = s0 + 3 * h * k;  // spans of h
  s.axes[0] = AxisBasis::bspline(2, U, 5);
  s.object_to_param[0][0] = 1.0;
  s.object_to_param[0][3] = s0;  // p = 0 at the first plane
  Plan plan;
  build_lattice_tables(plan, s);
  EXPECT_EQ(plan.param_map[3], 0.0f);  // b - shift
  // t of p = 1.5 h (the middle of the second span) from the float tables, as the evaluators
  // compute it: (A p + b - origin) * inv_scale.
  const float p = (float)(1.5 * h);
  int hit = 0;
  for (int i = 0; i < plan.axis_offset[1]; ++i) {
    const AxisPieceF& f = plan.pieces[i];
    const AxisPiece& d = s.axes[0].pieces()[i];
    if (!(d.lo <= s0 + 1.5 * h && s0 + 1.5 * h < d.hi)) continue;
    ++hit;
    const float t = (plan.param_map[0] * p + plan.param_map[3] - f.origin) * f.inv_scale;
    const double want = (1.5 * h - (d.origin - s0)) / d.scale;
    EXPECT_NEAR(t, want, 1e-3);
  }
  EXPECT_EQ(hit, 1);
}
