// Knot-box clipping (paper sec. 3 and 4.3): split every triangle by the lattice's knot planes
// so that each piece lies in one knot box, and triangulate the convex pieces.
//
// Clipping runs in the lattice's parameter space s (an affine image of object space), where
// knot planes are axis-aligned. A clip vertex is keyed by the segment it splits (its two end
// vertices) and the plane, so the two triangles on a shared edge, and the two pieces on a
// shared cut, get the very same vertex: the sub-mesh stays watertight.
#pragma once

#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"

namespace sffd {

struct ClipResult {
  std::vector<double> flat;         // #SV x 3: positions; rows [0, V) are the input vertices
  std::vector<int> origin_tri;      // #SV: triangle that created the clip vertex (-1: input)
  std::vector<double> origin_bary;  // #SV x 3: its barycentric point in that triangle
  std::vector<int> patch_vertex;    // #P x 3 sub-vertices, same winding as the triangle
  std::vector<int> patch_tri;       // #P: triangle each piece lies in
  std::vector<double> patch_bary;   // #P x 3 x 3: barycentric points of its corners
  int sub_vertices() const { return (int)origin_tri.size(); }
  int patches() const { return (int)patch_tri.size(); }
};

// X: #V x 3 input positions; tv: #T x 3 triangles.
ClipResult clip_to_knot_boxes(const std::vector<double>& X, const std::vector<int>& tv,
                              const LatticeSpec& lattice);

}  // namespace sffd
