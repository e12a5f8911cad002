// Unit tests of the cubic patch's power form (plan/bezier.hpp), which the CUDA tessellation
// evaluates instead of the Bernstein sum the CPU evaluator uses.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <random>

#include "smoothffd/plan/bezier.hpp"
#include "smoothffd/plan/tessellation.hpp"

using namespace sffd;

namespace {

// The Bernstein sum in double (the reference).
double bernstein(const double b[10], double s, double t) {
  const double bary[3] = {1.0 - s - t, s, t};
  double B[10];
  cubic_basis(bary, B);
  double x = 0.0;
  for (int k = 0; k < 10; ++k) x += B[k] * b[k];
  return x;
}

}  // namespace

TEST(CubicPowerForm, EqualsTheBernsteinSumEverywhere) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    double b[10], a[10];
    for (double& v : b) v = n01(rng);
    cubic_power_form(b, a);
    EXPECT_EQ(a[kA00], b[0]);  // corner 0 exactly
    for (int i = 0; i < 20; ++i) {
      double s = u01(rng), t = u01(rng);
      if (s + t > 1.0) s = 1.0 - s, t = 1.0 - t;
      EXPECT_NEAR(cubic_power_eval(a, (float)s, (float)t), bernstein(b, (float)s, (float)t), 1e-12);
    }
    // The corners are the corner control points; each term is checked by a monomial below.
    EXPECT_NEAR(cubic_power_eval(a, 1.0f, 0.0f), b[1], 1e-12);
    EXPECT_NEAR(cubic_power_eval(a, 0.0f, 1.0f), b[2], 1e-12);
  }
}

TEST(CubicPowerForm, TermsAreTheMonomials) {
  // Each monomial s^j t^k (j + k <= 3) written in Bernstein form must come back as that one
  // term of the power form (the order of CubicPowerTerm).
  const int exps[10][2] = {{0, 0}, {1, 0}, {0, 1}, {2, 0}, {1, 1}, {0, 2}, {3, 0}, {2, 1}, {1, 2}, {0, 3}};
  for (int term = 0; term < 10; ++term) {
    // The Bernstein coefficients of the monomial: the cubic interpolating it at the 10 points
    // of the level-3 grid (a unisolvent set), by Gauss-Jordan elimination in double.
    double b[10], a[10];
    TessellationTables tt = build_tessellation(3);
    double M[10][11];
    for (int g = 0; g < 10; ++g) {
      const double* q = &tt.bary[3 * g];
      double B[10];
      cubic_basis(q, B);
      for (int k = 0; k < 10; ++k) M[g][k] = B[k];
      M[g][10] = std::pow(q[1], exps[term][0]) * std::pow(q[2], exps[term][1]);
    }
    for (int c = 0; c < 10; ++c) {  // partial pivoting
      int piv = c;
      for (int r = c + 1; r < 10; ++r)
        if (std::fabs(M[r][c]) > std::fabs(M[piv][c])) piv = r;
      for (int k = 0; k < 11; ++k) std::swap(M[c][k], M[piv][k]);
      for (int r = 0; r < 10; ++r) {
        if (r == c) continue;
        const double f = M[r][c] / M[c][c];
        for (int k = 0; k < 11; ++k) M[r][k] -= f * M[c][k];
      }
    }
    for (int k = 0; k < 10; ++k) b[k] = M[k][10] / M[k][k];
    cubic_power_form(b, a);
    for (int k = 0; k < 10; ++k) EXPECT_NEAR(a[k], k == term ? 1.0 : 0.0, 1e-12) << "term " << term << " coef " << k;
  }
}

TEST(CubicPowerForm, FloatRoundingIsRelativeToThePatchNotTheOrigin) {
  // A small patch far from the origin: the power form's differences must not lose more than
  // the Bernstein sum itself does (a few ulp of the coordinates).
  std::mt19937 rng(11);
  std::normal_distribution<double> n01(0.0, 1.0);
  const int L = 16;
  TessellationTables tt = build_tessellation(L);
  for (int trial = 0; trial < 50; ++trial) {
    V3 bf[10], af[10];
    double bd[3][10];
    for (int k = 0; k < 10; ++k) {
      const double x = 1000.0 + 0.01 * n01(rng), y = -500.0 + 0.01 * n01(rng), z = 0.01 * n01(rng);
      bf[k] = v3((float)x, (float)y, (float)z);
      bd[0][k] = bf[k].x, bd[1][k] = bf[k].y, bd[2][k] = bf[k].z;
    }
    cubic_power_form(bf, af);
    for (int g = 0; g < tt.grid; ++g) {
      const float s = (float)tt.bary[3 * g + 1], t = (float)tt.bary[3 * g + 2];
      const V3 p = cubic_power_eval(af, s, t);
      const double ref[3] = {bernstein(bd[0], s, t), bernstein(bd[1], s, t), bernstein(bd[2], s, t)};
      const float got[3] = {p.x, p.y, p.z};
      for (int c = 0; c < 3; ++c) EXPECT_NEAR(got[c], ref[c], 4.0 * FLT_EPSILON * 1000.0) << "grid point " << g;
    }
  }
}
