// Cubic triangular Bézier patches (paper Eq. 2 with n = 3): control point order and basis.
//
// Control points 0..9: b300 (corner 0), b030 (corner 1), b003 (corner 2), then per patch edge
// k (corner k -> corner k+1) the point near its start and the point near its end
// (b210, b120 | b021, b012 | b102, b201), and the centre b111.
#pragma once

#include "smoothffd/core/hd.hpp"

namespace sffd {

constexpr int kCubicCount = 10;
constexpr int kCentre = 9;

// Exponents of the barycentric coordinates (of corners 0, 1, 2) of each control point.
SFFD_HD void cubic_exponents(int k, int e[3]) {
  const int table[10][3] = {{3, 0, 0}, {0, 3, 0}, {0, 0, 3}, {2, 1, 0}, {1, 2, 0},
                            {0, 2, 1}, {0, 1, 2}, {1, 0, 2}, {2, 0, 1}, {1, 1, 1}};
  e[0] = table[k][0];
  e[1] = table[k][1];
  e[2] = table[k][2];
}

// Index of the control point on patch edge k (0..2) next to its start (end = false) or end.
SFFD_HD int edge_control_index(int k, bool at_end) { return 3 + 2 * k + (at_end ? 1 : 0); }

// B_ijk(b) = 3!/(i!j!k!) b0^i b1^j b2^k for all 10 control points.
template <class T>
SFFD_HD void cubic_basis(const T b[3], T out[10]) {
  T b0 = b[0], b1 = b[1], b2 = b[2];
  out[0] = b0 * b0 * b0;
  out[1] = b1 * b1 * b1;
  out[2] = b2 * b2 * b2;
  out[3] = 3 * b0 * b0 * b1;
  out[4] = 3 * b0 * b1 * b1;
  out[5] = 3 * b1 * b1 * b2;
  out[6] = 3 * b1 * b2 * b2;
  out[7] = 3 * b0 * b2 * b2;
  out[8] = 3 * b0 * b0 * b2;
  out[9] = 6 * b0 * b1 * b2;
}

}  // namespace sffd
