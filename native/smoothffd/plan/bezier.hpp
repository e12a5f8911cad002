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

SFFD_ISA_BEGIN

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

// Power form of a cubic patch about corner 0: with s = b1, t = b2 (b0 = 1 - s - t) the patch
// is sum over j + k <= 3 of a_jk s^j t^k, a_jk = 3! / ((3-j-k)! j! k!) D1^j D2^k b300 (forward
// differences D1 = b(i-1, j+1, k) - b(i, j, k), D2 = b(i-1, j, k+1) - b(i, j, k)). Why: a grid
// point then costs 9 multiply-adds a coordinate (cubic_power_eval) instead of the 10 basis
// values (cubic_basis: about 20 multiplies) and 10 multiply-adds of the Bernstein sum; every
// term beyond a00 is a difference of control points, so its rounding is relative to the
// patch's size, not to its distance from the origin. Coefficient order:
enum CubicPowerTerm { kA00, kA10, kA01, kA20, kA11, kA02, kA30, kA21, kA12, kA03 };

// a (power form, CubicPowerTerm order) from b (Bernstein, the control point order above). T:
// float or V3 (anything with +, - and float *).
template <class T>
SFFD_HD void cubic_power_form(const T b[10], T a[10]) {
  const T d10 = b[3] - b[0], d01 = b[8] - b[0];  // D1 b300, D2 b300
  const T e20 = b[4] - b[3], e02 = b[7] - b[8];  // D1 b210, D2 b201
  const T f11 = b[9] - b[3], g11 = b[9] - b[8];  // D2 b210, D1 b201
  const T h20 = e20 - d10, h02 = e02 - d01;      // D1^2 b300, D2^2 b300
  a[kA00] = b[0];
  a[kA10] = 3.0f * d10;
  a[kA01] = 3.0f * d01;
  a[kA20] = 3.0f * h20;
  a[kA11] = 6.0f * (f11 - d01);
  a[kA02] = 3.0f * h02;
  a[kA30] = (b[1] - b[4]) - 2.0f * e20 + d10;
  a[kA21] = 3.0f * ((b[5] - b[9]) - g11 - h20);
  a[kA12] = 3.0f * ((b[6] - b[9]) - f11 - h02);
  a[kA03] = (b[2] - b[7]) - 2.0f * e02 + d01;
}

// The patch at (s, t) from its power form: Horner in t for each power of s, then in s (9
// multiply-adds for a float; a00 is added last but one, so the small terms are summed first).
template <class T>
SFFD_HD T cubic_power_eval(const T a[10], float s, float t) {
  const T c2 = a[kA20] + t * a[kA21];
  const T c1 = a[kA10] + t * (a[kA11] + t * a[kA12]);
  const T c0 = a[kA01] + t * (a[kA02] + t * a[kA03]);
  const T x = c1 + s * (c2 + s * a[kA30]);
  return (a[kA00] + t * c0) + s * x;
}

SFFD_ISA_END

}  // namespace sffd
