#include "smoothffd/plan/sub_vertices.hpp"

#include <algorithm>

#include "smoothffd/core/parallel.hpp"

namespace sffd {

BoundedRest bound_rest_surface(const std::vector<double>& X, InputSurface& in, const ClipResult& clip) {
  BoundedRest out;
  const int P = clip.patches();
  {
    // The pieces of each triangle, in order (CSR).
    std::vector<int> piece_start(in.tv.size() / 3 + 1, 0);
    for (int p = 0; p < P; ++p) piece_start[clip.patch_tri[p] + 1]++;
    for (size_t t = 0; t + 1 < piece_start.size(); ++t) piece_start[t + 1] += piece_start[t];
    std::vector<double> piece_bary(9 * (size_t)P);
    std::vector<int> fill(piece_start.begin(), piece_start.end() - 1);
    for (int p = 0; p < P; ++p) {
      const int q = fill[clip.patch_tri[p]]++;
      std::copy(&clip.patch_bary[9 * (size_t)p], &clip.patch_bary[9 * (size_t)p] + 9, &piece_bary[9 * (size_t)q]);
    }
    out.bounded_vertices = bound_adjust_normals(X, in.tv, in.edges(), in.sharp, in.normal, in.adjust, out.surface,
                                                &piece_start, &piece_bary);
  }
  for (uint8_t f : in.adjust.flat) out.flat_triangles += f;
  out.shade = in.normal;
  out.turned_normals = bound_render_normals(in.adjust, out.shade, nullptr);
  return out;
}

SubVertices place_sub_vertices(const InputMesh& mesh, const InputSurface& in, const RestSurface& rest,
                               const ClipResult& clip) {
  const int V = (int)(mesh.positions.size() / 3), SV = clip.sub_vertices();
  SubVertices out{clip.flat, std::vector<double>(SV, 1.0)};
  // Each sub-vertex on its own: in parallel, the same values.
  parallel_for(SV, default_threads(), [&](long long vb, long long ve) {
    for (long long v = vb; v < ve; ++v) {
      if (v < V) {
        if (!mesh.vertex_weight.empty()) out.weight[v] = mesh.vertex_weight[v];
        continue;
      }
      int t = clip.origin_tri[v];
      const double* b = &clip.origin_bary[3 * (size_t)v];
      rest_surface_point(rest, mesh.positions, in.tv, in.edges(), t, b, &out.position[3 * (size_t)v]);
      if (!mesh.vertex_weight.empty()) {
        out.weight[v] = 0;
        for (int k = 0; k < 3; ++k) out.weight[v] += b[k] * mesh.vertex_weight[in.tv[3 * t + k]];
      }
    }
  });
  return out;
}

}  // namespace sffd
