#include "smoothffd/plan/sources.hpp"

#include <algorithm>
#include <stdexcept>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {

void build_patch_sources(Plan& plan, const InputMesh& mesh, const Triangulation& tr, const ClipResult& clip) {
  const int P = clip.patches();
  plan.patch_face.resize(P);
  for (int p = 0; p < P; ++p) plan.patch_face[p] = tr.face[clip.patch_tri[p]];
  plan.input_corners = (int)mesh.corner_vertex.size();
  plan.input_triangle_corner = tr.corners;
  plan.input_triangle_face = tr.face;
  plan.patch_triangle = clip.patch_tri;
  plan.patch_bary = clip.patch_bary;
}

void interpolate_corners(const Plan& plan, const float* values, int k, float* out, int threads) {
  if (k < 1) throw std::invalid_argument("interpolate_corners: need at least one value a corner");
  const TessellationTables tess = build_tessellation(plan.level);
  const int P = (int)plan.patch_triangle.size(), LL = plan.level * plan.level;
  const int* tc = plan.input_triangle_corner.data();
  parallel_for(P, threads > 0 ? threads : default_threads(), [&](long long b, long long e) {
    std::vector<float> corner(3 * (size_t)k);  // the values at the patch's corners
    for (long long p = b; p < e; ++p) {
      const int t = plan.patch_triangle[p];
      for (int c = 0; c < 3; ++c) {
        const double* w = &plan.patch_bary[9 * (size_t)p + 3 * c];
        for (int i = 0; i < k; ++i) {
          double v = 0;
          for (int q = 0; q < 3; ++q) v += w[q] * values[(size_t)k * tc[3 * (size_t)t + q] + i];
          corner[(size_t)k * c + i] = (float)v;
        }
      }
      float* o = out + (size_t)p * LL * 3 * k;
      for (int j = 0; j < 3 * LL; ++j) {
        const double* w = &tess.bary[3 * (size_t)tess.triangles[j]];
        for (int i = 0; i < k; ++i) {
          double v = 0;
          for (int q = 0; q < 3; ++q) v += w[q] * corner[(size_t)k * q + i];
          o[(size_t)k * j + i] = (float)v;
        }
      }
    }
  });
}

void vertex_sources(const Plan& plan, int* triangle, float* bary) {
  const TessellationTables tess = build_tessellation(plan.level);
  const long long N = plan.output_vertices;
  const int P = (int)plan.patch_triangle.size(), G = tess.grid;
  std::fill(triangle, triangle + N, -1);
  std::fill(bary, bary + 3 * N, 0.0f);
  for (int p = 0; p < P; ++p)
    for (int g = 0; g < G; ++g) {
      const long long o = plan.patch_grid_vertex[(size_t)p * G + g];
      if (triangle[o] >= 0) continue;
      triangle[o] = plan.patch_triangle[p];
      const double* w = &tess.bary[3 * (size_t)g];
      for (int q = 0; q < 3; ++q) {
        double v = 0;
        for (int c = 0; c < 3; ++c) v += w[c] * plan.patch_bary[9 * (size_t)p + 3 * c + q];
        bary[3 * o + q] = (float)v;
      }
    }
}

}  // namespace sffd
