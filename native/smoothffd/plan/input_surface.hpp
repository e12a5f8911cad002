// The input as a triangle mesh with the normals the plan starts from (the plan build's first
// geometric stage): its polygons triangulated, the normals at the triangle corners, the edges
// and which of their ends split the normals, and which triangles belong to flat faces.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/rest_surface.hpp"

namespace sffd {

struct InputSurface {
  Triangulation triangulation;  // #T triangles of input corners, and their faces
  std::vector<int> tv;          // #T x 3: the triangles' vertices
  std::vector<double> normal;   // #T x 3 x 3: unit normals at the corners (triangle_corner_normals)
  std::shared_ptr<const TriangleEdges> edge_table;  // of tv (a plan keeps it: Plan::input_edges)
  const EdgeTable& edges() const { return edge_table->edges; }
  std::vector<uint8_t> sharp;   // #E: classify_sharp_ends of `normal` at the sharp angle
  AdjustNormals adjust;         // the normals the geometry follows: `normal`, the triangles' own
                                // on flat faces (flat_triangles); bounded by a later stage
};

// cos_tol: the cosine of the sharp angle (PlanOptions::sharp_angle_degrees). triangulation:
// the input's polygons as these triangles (a plan's input_triangle_corner and
// input_triangle_face, checked against the mesh), or null: triangulate_polygons of the mesh's
// own shape.
// kept_edges: an earlier plan's edge table of its input triangles (Plan::input_edges), taken
// where it is of the same triangles.
InputSurface build_input_surface(const InputMesh& mesh, double cos_tol, const Triangulation* triangulation = nullptr,
                                 const std::shared_ptr<const TriangleEdges>& kept_edges = nullptr);

}  // namespace sffd
