#include "smoothffd/lattice/lattice_spec.hpp"

#include "smoothffd/lattice/tensor_eval.hpp"

#include <algorithm>

namespace sffd {

void LatticeSpec::find_pieces(const double s[3], int piece[3]) const {
  for (int a = 0; a < 3; ++a) piece[a] = axes[a].find_piece(s[a]);
}

void LatticeSpec::evaluate(const double p[3], const double* D, double weight, double F[3],
                           double J[9]) const {
  double s[3];
  int piece[3];
  to_param(p, s);
  find_pieces(s, piece);
  double w[3][kMaxTerms] = {}, dw[3][kMaxTerms] = {};
  int idx[3][kMaxTerms] = {}, count = 0;
  for (int a = 0; a < 3; ++a) {
    axes[a].weights(piece[a], s[a], w[a], dw[a]);
    const AxisPiece& pc = axes[a].pieces()[piece[a]];
    count = std::max(count, pc.count);
    for (int k = 0; k < pc.count; ++k) idx[a][k] = pc.index[k];
  }
  double value[4], grad[12], A[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A[3 * r + c] = object_to_param[r][c];
  if (components == 4) {
    tensor_eval<double, double, 4>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2], dw[2], count,
                                   D, axes[1].n_ctrl(), axes[2].n_ctrl(), value, grad);
    compose_weighted_deformation<double>(p, weight, value, grad, A, F, J);
    return;
  }
  tensor_eval<double, double>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2], dw[2], count,
                              D, axes[1].n_ctrl(), axes[2].n_ctrl(), value, grad);
  compose_deformation<double>(p, weight, value, grad, A, F, J);
}

}  // namespace sffd
