// Unit tests of the per-axis piecewise polynomial bases (lattice/axis_basis.hpp).
#include <gtest/gtest.h>

#include <cmath>

#include "smoothffd/lattice/axis_basis.hpp"

using namespace sffd;

namespace {

std::vector<double> clamped_knots(int p, int n) {
  std::vector<double> U;
  for (int i = 0; i <= p; ++i) U.push_back(0);
  for (int i = 1; i < n - p; ++i) U.push_back(double(i) / (n - p));
  for (int i = 0; i <= p; ++i) U.push_back(1);
  return U;
}

double weight_sum(const AxisBasis& b, double s, double* dsum) {
  double w[kMaxTerms], dw[kMaxTerms];
  int pi = b.find_piece(s);
  b.weights(pi, s, w, dw);
  double sum = 0;
  *dsum = 0;
  for (int k = 0; k < b.pieces()[pi].count; ++k) {
    sum += w[k];
    *dsum += dw[k];
  }
  return sum;
}

}  // namespace

TEST(AxisBasis, BSplinePartitionOfUnityEveryDegree) {
  for (int p = 1; p <= 5; ++p) {
    AxisBasis b = AxisBasis::bspline(p, clamped_knots(p, p + 4), p + 4);
    EXPECT_EQ(b.degree(), p);
    for (double s = -0.5; s <= 1.5; s += 0.01) {
      double d;
      EXPECT_NEAR(weight_sum(b, s, &d), 1.0, 1e-12) << "p=" << p << " s=" << s;
      EXPECT_NEAR(d, 0.0, 1e-9);
    }
  }
}

TEST(AxisBasis, BSplineLinearPrecisionAtGreville) {
  const int p = 3, n = 7;
  std::vector<double> U = clamped_knots(p, n);
  AxisBasis b = AxisBasis::bspline(p, U, n);
  for (double s = 0; s <= 1.0; s += 0.05) {
    double w[kMaxTerms], dw[kMaxTerms];
    int pi = b.find_piece(s);
    b.weights(pi, s, w, dw);
    double x = 0;
    for (int k = 0; k < b.pieces()[pi].count; ++k) {
      int i = b.pieces()[pi].index[k];
      double g = 0;
      for (int j = 1; j <= p; ++j) g += U[i + j];
      x += w[k] * g / p;
    }
    EXPECT_NEAR(x, s, 1e-12);
  }
}

TEST(AxisBasis, BlenderPlanesAndConstantOutside) {
  AxisBasis b = AxisBasis::blender(BlenderInterp::BSpline, 4);
  std::vector<double> planes = b.planes();
  ASSERT_EQ(planes.size(), 6u);  // -1, 0, 1, 2, 3, 4
  EXPECT_DOUBLE_EQ(planes.front(), -1.0);
  EXPECT_DOUBLE_EQ(planes.back(), 4.0);
  EXPECT_EQ(b.pieces().front().degree, 0);
  EXPECT_EQ(b.pieces().back().degree, 0);
  AxisBasis one = AxisBasis::blender(BlenderInterp::Cardinal, 1);
  EXPECT_TRUE(one.planes().empty());
  AxisBasis lin = AxisBasis::blender(BlenderInterp::Linear, 3);
  EXPECT_EQ(lin.degree(), 1);
  EXPECT_EQ(lin.planes().size(), 3u);  // 0, 1, 2: the cells beyond -1..0 and 2..3 are constant
}

TEST(AxisBasis, RejectsBadInput) {
  EXPECT_THROW(AxisBasis::bspline(6, clamped_knots(5, 8), 8), std::invalid_argument);
  EXPECT_THROW(AxisBasis::bspline(2, {0, 0, 0, 1, 1}, 3), std::invalid_argument);
  EXPECT_THROW(AxisBasis::bspline(2, {0, 0, 0, 1, 0.5, 1}, 3), std::invalid_argument);
  EXPECT_THROW(parse_blender_interp("CUBIC"), std::invalid_argument);
}

TEST(AxisBasis, FindPieceWithAGuessIsTheSearch) {
  // Whatever the guess (right, a neighbour, far off, out of range), the piece is the search's,
  // on and within rounding of the planes included.
  const std::vector<double> U = {0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1};
  const AxisBasis b = AxisBasis::bspline(2, U, 7);
  const int n = (int)b.pieces().size();
  std::vector<double> s = {-1, 0, 1e-12, -1e-12, 0.1, 0.25, 0.25 - 1e-13, 0.5, 0.6, 0.75, 1 - 1e-12, 1, 1 + 1e-12, 2,
                           std::nan("")};
  for (double x : s)
    for (int g = -1; g <= n; ++g) EXPECT_EQ(b.find_piece(x, g), b.find_piece(x)) << x << " guess " << g;
}
