// Constrained least-squares fitting of cubic triangular patches (paper sec. 4.1, Eqs. 4-11).
//
// Columns of a patch's sample matrix: the (n+1)(n+2)/2 fitting points (i, j, k)/n, then the 9
// constraint points on the boundary (corners, then (2,1,0)/3, (1,2,0)/3, (0,2,1)/3, (0,1,2)/3,
// (1,0,2)/3, (2,0,1)/3). Barycentric points are kept as integer numerators over 3n so that
// coincident points (shared by neighbours) are recognised exactly.
#pragma once

#include <vector>

namespace sffd {

struct FitTables {
  int n = 0;                     // fitting degree
  int columns = 0;               // K = (n+1)(n+2)/2 + 9
  std::vector<int> numerator;    // K x 3, over 3n
  std::vector<double> M_r;       // 10 x K: control points = M_r * samples (Eq. 11)
};

// M_r = first 10 rows of [[M^T M, Mc^T], [Mc, 0]]^-1 [[M^T, 0], [0, I]], computed in double.
// Entries below 1e-12 are set to zero, so the boundary control points depend on the
// constraint samples alone (exactly: the shared edges of neighbours come out identical).
FitTables build_fit_tables(int n);

}  // namespace sffd
