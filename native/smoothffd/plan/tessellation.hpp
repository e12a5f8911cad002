// Uniform tessellation of a triangular patch at level L (paper sec. 5.5): grid point (i, j),
// 0 <= i, j, i + j <= L, has barycentric ((L-i-j)/L, i/L, j/L) and index
// g = j (L + 1) - j (j - 1) / 2 + i. Corner 0 is g(0,0), corner 1 g(L,0), corner 2 g(0,L).
#pragma once

#include <vector>

namespace sffd {

struct GridPoint {
  int kind;   // 0: corner, 1: edge, 2: interior
  int which;  // corner index, patch edge k (corner k -> k + 1), or interior ordinal
  int step;   // edge: m in 1..L-1 steps from corner k
};

struct TessellationTables {
  int level = 0, grid = 0;
  std::vector<double> bary;        // G x 3
  std::vector<float> basis;        // G x 10 cubic Bernstein values (B_q of Eq. 14)
  std::vector<int> triangles;      // L^2 x 3 grid indices, winding of the patch
  std::vector<GridPoint> points;   // G
};

TessellationTables build_tessellation(int level);

}  // namespace sffd
