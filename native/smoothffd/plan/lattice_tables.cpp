#include "smoothffd/plan/lattice_tables.hpp"

#include <cmath>
#include <vector>

namespace sffd {

double float_shift(const AxisBasis& axis) {
  const std::vector<double> planes = axis.planes();
  if (!planes.empty() && std::fabs(planes.front()) > planes.back() - planes.front()) return planes.front();
  return 0.0;
}

void build_lattice_tables(Plan& plan, const LatticeSpec& lattice) {
  plan.components = lattice.components;
  plan.pieces.clear();
  for (int a = 0; a < 3; ++a) {
    plan.axis_offset[a] = (int)plan.pieces.size();
    plan.dims[a] = lattice.axes[a].n_ctrl();
    const double shift = float_shift(lattice.axes[a]);
    for (const AxisPiece& pc : lattice.axes[a].pieces()) {
      AxisPieceF f{};
      f.origin = (float)(pc.origin - shift);
      f.inv_scale = (float)(1.0 / pc.scale);
      f.degree = pc.degree;
      f.count = pc.count;
      for (int k = 0; k < kMaxTerms; ++k) {
        f.index[k] = k < pc.count ? pc.index[k] : 0;  // padded terms: weight 0, any valid index
        for (int q = 0; q < kMaxTerms; ++q) f.coef[k][q] = (float)pc.coef[k][q];
      }
      plan.pieces.push_back(f);
    }
    for (int c = 0; c < 3; ++c) plan.param_map[4 * a + c] = (float)lattice.object_to_param[a][c];
    plan.param_map[4 * a + 3] = (float)(lattice.object_to_param[a][3] - shift);
  }
}

}  // namespace sffd
