#include "smoothffd/plan/input_surface.hpp"

#include <utility>

#include "smoothffd/plan/corner_normals.hpp"
#include "smoothffd/plan/validate.hpp"

namespace sffd {

InputSurface build_input_surface(const InputMesh& mesh, double cos_tol, const Triangulation* triangulation,
                                 const std::shared_ptr<const TriangleEdges>& kept_edges) {
  Triangulation tr;
  if (triangulation) {
    check_triangulation(mesh, *triangulation);
    tr = *triangulation;
  } else {
    tr = triangulate_polygons(mesh.positions, mesh.corner_vertex, mesh.face_offset);
  }
  std::vector<int> tv(tr.corners.size());
  for (size_t i = 0; i < tv.size(); ++i) tv[i] = mesh.corner_vertex[tr.corners[i]];
  std::vector<double> tcn = triangle_corner_normals(mesh, tr, tv);
  std::shared_ptr<const TriangleEdges> table = edges_of(tv, kept_edges);
  std::vector<uint8_t> sharp = classify_sharp_ends(table->edges, tv, tcn, cos_tol);
  AdjustNormals adjust(mesh.positions, tv, tcn, flat_triangles(mesh, tr, tcn, cos_tol));
  return InputSurface{std::move(tr), std::move(tv), std::move(tcn), std::move(table), std::move(sharp),
                      std::move(adjust)};
}

}  // namespace sffd
