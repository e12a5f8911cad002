// Triangulation of input polygons (convex or concave n-gons) into triangles of corners.
#pragma once

#include <vector>

namespace sffd {

struct Triangulation {
  std::vector<int> corners;  // #T x 3: indices into the input corner arrays
  std::vector<int> face;     // #T: input face of each triangle
};

// positions: #V x 3 (row-major); corner_vertex: #C; face_offset: #F + 1.
// Ear clipping in the plane of the Newell normal, choosing the ear with the largest smallest
// angle (no slivers where the polygon allows it). Consecutive repeated vertices are skipped and
// triangles whose corners repeat a vertex are dropped: they cover no surface.
Triangulation triangulate_polygons(const std::vector<double>& positions,
                                   const std::vector<int>& corner_vertex,
                                   const std::vector<int>& face_offset);

}  // namespace sffd
