#include "smoothffd/plan/fit_matrix.hpp"

#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "smoothffd/plan/bezier.hpp"

namespace sffd {

FitTables build_fit_tables(int n) {
  FitTables ft;
  ft.n = n;
  int fit = (n + 1) * (n + 2) / 2;
  ft.columns = fit + 9;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n - j; ++i) {  // same row order as the tessellation grid
      ft.numerator.push_back(3 * (n - i - j));
      ft.numerator.push_back(3 * i);
      ft.numerator.push_back(3 * j);
    }
  const int cons[9][3] = {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 1, 0}, {1, 2, 0},
                          {0, 2, 1}, {0, 1, 2}, {1, 0, 2}, {2, 0, 1}};
  for (const auto& c : cons)
    for (int i = 0; i < 3; ++i) ft.numerator.push_back(n * c[i]);

  Eigen::MatrixXd M(fit, 10), Mc(9, 10);
  for (int k = 0; k < ft.columns; ++k) {
    double b[3], B[10];
    for (int i = 0; i < 3; ++i) b[i] = ft.numerator[3 * k + i] / (3.0 * n);
    cubic_basis<double>(b, B);
    for (int c = 0; c < 10; ++c) (k < fit ? M(k, c) : Mc(k - fit, c)) = B[c];
  }
  Eigen::MatrixXd KKT = Eigen::MatrixXd::Zero(19, 19), R = Eigen::MatrixXd::Zero(19, ft.columns);
  KKT.topLeftCorner(10, 10) = M.transpose() * M;
  KKT.topRightCorner(10, 9) = Mc.transpose();
  KKT.bottomLeftCorner(9, 10) = Mc;
  R.topLeftCorner(10, fit) = M.transpose();
  R.bottomRightCorner(9, 9).setIdentity();
  Eigen::MatrixXd X = KKT.fullPivLu().solve(R);
  ft.M_r.resize(10 * (size_t)ft.columns);
  for (int r = 0; r < 10; ++r)
    for (int k = 0; k < ft.columns; ++k) {
      double v = X(r, k);
      ft.M_r[(size_t)r * ft.columns + k] = std::fabs(v) < 1e-12 ? 0.0 : v;
      // The evaluators rely on this structure (stages.hpp, fit_patch_into).
      if (r < 9 && k < fit && ft.M_r[(size_t)r * ft.columns + k] != 0.0)
        throw std::logic_error("fit matrix: a boundary row depends on a fitting sample");
    }
  return ft;
}

}  // namespace sffd
