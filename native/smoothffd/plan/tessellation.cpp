#include "smoothffd/plan/tessellation.hpp"

#include "smoothffd/plan/bezier.hpp"

namespace sffd {

TessellationTables build_tessellation(int L) {
  TessellationTables tt;
  tt.level = L;
  tt.grid = (L + 1) * (L + 2) / 2;
  auto g = [L](int i, int j) { return j * (L + 1) - j * (j - 1) / 2 + i; };
  int interior = 0;
  for (int j = 0; j <= L; ++j)
    for (int i = 0; i <= L - j; ++i) {
      double b[3] = {double(L - i - j) / L, double(i) / L, double(j) / L};
      double B[10];
      cubic_basis<double>(b, B);
      for (int k = 0; k < 3; ++k) tt.bary.push_back(b[k]);
      for (int k = 0; k < 10; ++k) tt.basis.push_back((float)B[k]);
      GridPoint p{2, 0, 0};
      if (i == 0 && j == 0) p = {0, 0, 0};
      else if (i == L) p = {0, 1, 0};
      else if (j == L) p = {0, 2, 0};
      else if (j == 0) p = {1, 0, i};
      else if (i + j == L) p = {1, 1, j};
      else if (i == 0) p = {1, 2, L - j};
      else p = {2, interior++, 0};
      tt.points.push_back(p);
    }
  for (int j = 0; j < L; ++j)
    for (int i = 0; i < L - j; ++i) {
      int up[3] = {g(i, j), g(i + 1, j), g(i, j + 1)};
      tt.triangles.insert(tt.triangles.end(), up, up + 3);
      if (i + j < L - 1) {
        int down[3] = {g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)};
        tt.triangles.insert(tt.triangles.end(), down, down + 3);
      }
    }
  return tt;
}

}  // namespace sffd
