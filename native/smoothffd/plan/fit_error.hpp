// The fit's error estimate (the paper's first open problem, sec. 7: a bound to guide the
// discretization): how far a fitted cubic patch lies from the surface its samples come from.
//
// A patch's samples are the exact FFD at the (n+1)(n+2)/2 points (i, j, k)/n of its
// sub-triangle and at 9 boundary points (plan/fit_matrix.hpp), n the sum of the lattice's
// degrees. Inside one knot box the FFD of a flat triangle is a polynomial of total degree n in
// the triangle's barycentric coordinates, so the grid samples determine it exactly: its
// degree-n Bezier coefficients are A x (the grid samples), A the inverse of the degree-n
// Bernstein basis at the grid points. The fitted cubic (M_r x all samples) elevated to degree
// n has coefficients Elev M_r x samples. Their difference
//
//     E = Q x samples,   Q = [A | 0] - Elev M_r    ((n+1)(n+2)/2 x K)
//
// holds the Bezier coefficients of (exact image - fitted cubic), and since Bernstein
// polynomials are non-negative and sum to 1, |exact - fitted| <= max_i |E_i| everywhere on the
// patch: a bound, not a sample. The table holds these coefficients on each of the patch's four
// halves (midpoint subdivision), whose maximum is a much closer bound (rows: 4 x the degree-n
// count). It is exact arithmetic up to rounding wherever the image is a
// degree-n polynomial (the lattice's own FFD of a flat piece, vertex weights constant on the
// patch); with a per-vertex deformation factor that varies over the patch (vertex groups) or
// Blender's point weights the image has a higher degree and max |E_i| is an estimate.
//
// The same Q applied to the patch's sampled unit normals bounds the distance between the
// normal patch and the degree-n interpolant of the deformed normal field: an estimate of the
// normal error (the exact field is a normalised polynomial, not a polynomial).
#pragma once

#include <vector>

#include "smoothffd/plan/fit_matrix.hpp"

namespace sffd {

struct FitErrorTable {
  int rows = 0;           // 4 (n+1)(n+2)/2: the degree-n Bezier coefficients of each half
  int columns = 0;        // K, the fit's columns
  std::vector<double> Q;  // rows x columns, row-major
};

// Q for the fit tables `ft` (computed in double).
FitErrorTable build_fit_error_table(const FitTables& ft);

}  // namespace sffd
