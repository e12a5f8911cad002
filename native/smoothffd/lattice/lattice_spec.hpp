// The structure of a lattice (everything but its control values): three axis bases and the
// affine map from object space into parameter space. Both lattice kinds reduce to
//   F(p) = p + sum_ijk W_ijk(s(p)) D_ijk,  s(p) = A p + b,
// with D the per-frame control values (displacements). A plan is built per LatticeSpec.
//
// components = 4: Blender's lattice vertex group (Lattice.vertex_group). Each control value
// carries a fourth number, the point's weight lw (times the modifier's strength), and
//   F(p) = p + weight^2 s(p) d(p),  d = sum W D,  s = sum W lw
// (compose_weighted_deformation, lattice/tensor_eval.hpp: Blender's own blend).
#pragma once

#include <array>
#include <vector>

#include "smoothffd/lattice/axis_basis.hpp"

namespace sffd {

struct LatticeSpec {
  std::array<AxisBasis, 3> axes;
  double object_to_param[3][4] = {};  // s = A p + b, row-major [A | b]
  int components = 3;  // values a control point: 3 (D), or 4 (D and the point's weight)

  int count() const { return axes[0].n_ctrl() * axes[1].n_ctrl() * axes[2].n_ctrl(); }
  // Sum of the per-axis degrees: the degree of the exact deformed triangle (paper, section 3).
  int degree_sum() const { return axes[0].degree() + axes[1].degree() + axes[2].degree(); }

  void to_param(const double p[3], double s[3]) const {
    for (int a = 0; a < 3; ++a)
      s[a] = object_to_param[a][0] * p[0] + object_to_param[a][1] * p[1] + object_to_param[a][2] * p[2] +
             object_to_param[a][3];
  }
  // Pieces containing s, one per axis.
  void find_pieces(const double s[3], int piece[3]) const;
  // Position and Jacobian (row-major dF_r/dp_c) in double precision; D: count() x components.
  void evaluate(const double p[3], const double* D, double weight, double F[3], double J[9]) const;
};

}  // namespace sffd
