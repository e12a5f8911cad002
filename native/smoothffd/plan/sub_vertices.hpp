// The rest surface bounded against the knot-box pieces, and the sub-vertices placed on it
// (paper sec. 4.3.1): the stages between the clipping (plan/clip.hpp) and the patches.
#pragma once

#include <vector>

#include "smoothffd/plan/clip.hpp"
#include "smoothffd/plan/input_surface.hpp"
#include "smoothffd/plan/rest_surface.hpp"

namespace sffd {

struct BoundedRest {
  RestSurface surface;        // the crease-aware PN rest surface of the bounded adjustment normals
  std::vector<double> shade;  // #T x 3 x 3: the shading normals, turned where the geometry
                              // cannot follow them (bound_render_normals)
  int bounded_vertices = 0;   // Plan::bounded_vertices
  int flat_triangles = 0;     // Plan::flat_triangles
  int turned_normals = 0;     // Plan::turned_normals
};

// Bounds in.adjust (bound_adjust_normals over the input, with the clip's pieces: no patch, nor
// the flat triangle through any piece's corners on the rest surface, folds), builds the rest
// surface from it and turns the shading normals (in.normal) the geometry cannot follow.
BoundedRest bound_rest_surface(const std::vector<double>& X, InputSurface& in, const ClipResult& clip);

struct SubVertices {
  std::vector<double> position;  // #SV x 3: input vertices as given, clip vertices moved onto
                                 // the rest surface (where the patches start from)
  std::vector<double> weight;    // #SV: deformation factor: the input's vertex weight (1 where
                                 // none is given), barycentric in the clip vertex's triangle
};

SubVertices place_sub_vertices(const InputMesh& mesh, const InputSurface& in, const RestSurface& rest,
                               const ClipResult& clip);

}  // namespace sffd
