#include "smoothffd/plan/fit_error.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "smoothffd/plan/bezier.hpp"

namespace sffd {

namespace {

double binomial(int n, int k) {
  if (k < 0 || k > n) return 0.0;
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}

// Degree-n Bernstein polynomial with exponents e at barycentric point b.
double bernstein(int n, const int e[3], const double b[3]) {
  double c = binomial(n, e[0]) * binomial(n - e[0], e[1]);
  for (int a = 0; a < 3; ++a) c *= std::pow(b[a], e[a]);
  return c;
}

}  // namespace

FitErrorTable build_fit_error_table(const FitTables& ft) {
  const int n = ft.n, N = (n + 1) * (n + 2) / 2, K = ft.columns;
  if (n < 3 || K != N + 9) throw std::invalid_argument("fit error table: fit tables of degree >= 3 expected");
  // The degree-n coefficients in the grid's own order: coefficient g has the exponents of
  // grid point g (its numerators over 3n, divided by 3).
  std::vector<int> expo(3 * (size_t)N);
  for (int g = 0; g < N; ++g)
    for (int a = 0; a < 3; ++a) expo[3 * g + a] = ft.numerator[3 * g + a] / 3;
  Eigen::MatrixXd V(N, N);  // V(g, m): basis function m at grid point g
  for (int g = 0; g < N; ++g) {
    double b[3];
    for (int a = 0; a < 3; ++a) b[a] = ft.numerator[3 * g + a] / (3.0 * n);
    for (int m = 0; m < N; ++m) V(g, m) = bernstein(n, &expo[3 * m], b);
  }
  Eigen::MatrixXd A = V.fullPivLu().inverse();
  // Degree elevation 3 -> n: the cubic's control point c with exponents e contributes
  // C(i, e0) C(j, e1) C(k, e2) / C(n, 3) to the coefficient with exponents (i, j, k).
  Eigen::MatrixXd Elev(N, 10);
  for (int m = 0; m < N; ++m)
    for (int c = 0; c < 10; ++c) {
      int e[3];
      cubic_exponents(c, e);
      const int* x = &expo[3 * m];
      Elev(m, c) = binomial(x[0], e[0]) * binomial(x[1], e[1]) * binomial(x[2], e[2]) / binomial(n, 3);
    }
  Eigen::MatrixXd Mr(10, K);
  for (int r = 0; r < 10; ++r)
    for (int k = 0; k < K; ++k) Mr(r, k) = ft.M_r[(size_t)r * K + k];
  Eigen::MatrixXd Q0 = -Elev * Mr;  // the difference's coefficients on the whole patch
  Q0.leftCols(N) += A;
  // The same polynomial on the four halves of the patch (midpoint subdivision): its
  // coefficients there, A x (its values at each half's grid points), lie much closer to it
  // than the whole patch's (on random images of degree 4-9 the bound's median ratio to the
  // true maximum drops from 3-8 to 1.3-2.4).
  const double corners[4][3][3] = {
      {{1, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}},
      {{0.5, 0.5, 0}, {0, 1, 0}, {0, 0.5, 0.5}},
      {{0.5, 0, 0.5}, {0, 0.5, 0.5}, {0, 0, 1}},
      {{0.5, 0.5, 0}, {0, 0.5, 0.5}, {0.5, 0, 0.5}}};
  Eigen::MatrixXd Q(4 * N, K);
  for (int h = 0; h < 4; ++h) {
    Eigen::MatrixXd W(N, N);  // W(g, m): basis function m at the half's grid point g
    for (int g = 0; g < N; ++g) {
      double b[3] = {0, 0, 0};
      for (int c = 0; c < 3; ++c)
        for (int a = 0; a < 3; ++a) b[a] += ft.numerator[3 * g + c] / (3.0 * n) * corners[h][c][a];
      for (int m = 0; m < N; ++m) W(g, m) = bernstein(n, &expo[3 * m], b);
    }
    Q.middleRows(h * N, N) = A * W * Q0;
  }
  FitErrorTable t;
  t.rows = 4 * N;
  t.columns = K;
  t.Q.resize((size_t)t.rows * K);
  for (int m = 0; m < t.rows; ++m)
    for (int k = 0; k < K; ++k) t.Q[(size_t)m * K + k] = Q(m, k);
  return t;
}

}  // namespace sffd
