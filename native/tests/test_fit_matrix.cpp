// Unit tests of the constrained least-squares fitting matrix M_r (plan/fit_matrix.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "smoothffd/plan/bezier.hpp"
#include "smoothffd/plan/fit_matrix.hpp"

using namespace sffd;

namespace {
constexpr int kConstraints = 9;
// Constraint columns (after the fitting columns) lying on patch edge k (corner k -> k + 1):
// its two corners and its two interior constraint points.
std::vector<int> edge_constraint_columns(int k) {
  // Order: corners 0, 1, 2, then (2,1,0), (1,2,0) | (0,2,1), (0,1,2) | (1,0,2), (2,0,1).
  return {k, (k + 1) % 3, 3 + 2 * k, 4 + 2 * k};
}
}  // namespace

TEST(FitMatrix, ColumnsAndNumerators) {
  for (int n = 3; n <= 15; ++n) {
    FitTables ft = build_fit_tables(n);
    const int fit = (n + 1) * (n + 2) / 2;
    ASSERT_EQ(ft.columns, fit + kConstraints);
    ASSERT_EQ((int)ft.numerator.size(), 3 * ft.columns);
    ASSERT_EQ(ft.M_r.size(), 10u * ft.columns);
    for (int k = 0; k < ft.columns; ++k) {
      const int* q = &ft.numerator[3 * k];
      EXPECT_EQ(q[0] + q[1] + q[2], 3 * n) << "column " << k;
      for (int i = 0; i < 3; ++i) EXPECT_GE(q[i], 0);
    }
  }
}

// Affine invariance: the fit of a constant is that constant, so every row sums to 1.
TEST(FitMatrix, RowsSumToOne) {
  for (int n = 3; n <= 15; ++n) {
    FitTables ft = build_fit_tables(n);
    for (int r = 0; r < 10; ++r) {
      double sum = 0;
      for (int k = 0; k < ft.columns; ++k) sum += ft.M_r[(size_t)r * ft.columns + k];
      EXPECT_NEAR(sum, 1.0, 1e-10) << "n=" << n << " row " << r;
    }
  }
}

// The boundary control points (corners and edge points) depend only on the constraint samples
// of their own edge, exactly (zero, not small), so neighbours sharing an edge agree bitwise.
TEST(FitMatrix, BoundaryRowsDependOnlyOnTheirConstraintColumns) {
  for (int n = 3; n <= 15; ++n) {
    FitTables ft = build_fit_tables(n);
    const int fit = ft.columns - kConstraints;
    for (int r = 0; r < 9; ++r) {
      std::vector<bool> allowed(ft.columns, false);
      if (r < 3) {
        allowed[fit + r] = true;  // a corner is its own constraint sample
      } else {
        for (int c : edge_constraint_columns((r - 3) / 2)) allowed[fit + c] = true;
      }
      for (int k = 0; k < ft.columns; ++k) {
        double v = ft.M_r[(size_t)r * ft.columns + k];
        if (!allowed[k]) EXPECT_EQ(v, 0.0) << "n=" << n << " row " << r << " column " << k;
      }
      if (r < 3) EXPECT_NEAR(ft.M_r[(size_t)r * ft.columns + fit + r], 1.0, 1e-12);
    }
    // The centre is what the least-squares part decides: it uses fitting columns.
    double centre_fit = 0;
    for (int k = 0; k < fit; ++k) centre_fit += std::fabs(ft.M_r[(size_t)kCentre * ft.columns + k]);
    EXPECT_GT(centre_fit, 0.1);
  }
}

// Cubic precision: samples of a cubic patch are fitted back to its own control points.
TEST(FitMatrix, ReproducesCubicPatches) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int n = 3; n <= 12; ++n) {
    FitTables ft = build_fit_tables(n);
    for (int trial = 0; trial < 3; ++trial) {
      double cp[10];
      for (double& c : cp) c = U(rng);
      std::vector<double> samples(ft.columns);
      for (int k = 0; k < ft.columns; ++k) {
        double b[3], B[10];
        for (int i = 0; i < 3; ++i) b[i] = ft.numerator[3 * k + i] / (3.0 * n);
        cubic_basis<double>(b, B);
        samples[k] = 0;
        for (int q = 0; q < 10; ++q) samples[k] += B[q] * cp[q];
      }
      for (int r = 0; r < 10; ++r) {
        double x = 0;
        for (int k = 0; k < ft.columns; ++k) x += ft.M_r[(size_t)r * ft.columns + k] * samples[k];
        EXPECT_NEAR(x, cp[r], 1e-9) << "n=" << n << " row " << r;
      }
    }
  }
}

// The fit is the constrained least-squares optimum (Eqs. 4-11), checked from its definition
// with a basis written out here (not bezier.hpp's): for arbitrary samples s, the control
// points b = M_r s interpolate the 9 constraint samples, and the centre b111 (the one free
// control point) leaves a residual orthogonal to its basis function over the fitting points,
// sum_k B111(u_k) (sum_q B_q(u_k) b_q - s_k) = 0.
TEST(FitMatrix, IsTheConstrainedLeastSquaresOptimum) {
  const int exponents[10][3] = {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 1, 0}, {1, 2, 0},
                                {0, 2, 1}, {0, 1, 2}, {1, 0, 2}, {2, 0, 1}, {1, 1, 1}};
  const double factorial[4] = {1, 1, 2, 6};
  auto bernstein = [&](const double u[3], int q) {
    const int* e = exponents[q];
    return 6.0 / (factorial[e[0]] * factorial[e[1]] * factorial[e[2]]) *
           std::pow(u[0], e[0]) * std::pow(u[1], e[1]) * std::pow(u[2], e[2]);
  };
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int n = 3; n <= 15; ++n) {
    FitTables ft = build_fit_tables(n);
    const int fit = ft.columns - kConstraints;
    for (int trial = 0; trial < 3; ++trial) {
      std::vector<double> s(ft.columns);
      for (double& v : s) v = U(rng);
      double b[10];
      for (int r = 0; r < 10; ++r) {
        b[r] = 0;
        for (int k = 0; k < ft.columns; ++k) b[r] += ft.M_r[(size_t)r * ft.columns + k] * s[k];
      }
      double residual_dot_centre = 0, scale = 0;
      for (int k = 0; k < ft.columns; ++k) {
        double u[3];
        for (int i = 0; i < 3; ++i) u[i] = ft.numerator[3 * k + i] / (3.0 * n);
        double x = 0;
        for (int q = 0; q < 10; ++q) x += bernstein(u, q) * b[q];
        if (k >= fit) {
          EXPECT_NEAR(x, s[k], 1e-10) << "n=" << n << " constraint " << k - fit;
        } else {
          residual_dot_centre += bernstein(u, kCentre) * (x - s[k]);
          scale += bernstein(u, kCentre) * std::fabs(s[k]);
        }
      }
      EXPECT_NEAR(residual_dot_centre, 0.0, 1e-10 * scale) << "n=" << n;
    }
  }
}
