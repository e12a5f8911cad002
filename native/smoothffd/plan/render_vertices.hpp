// Render vertices (plan.hpp's render_* tables): the output vertices duplicated only where
// their normals split, their owners, and the triangles in render-vertex indices.
#pragma once

#include <vector>

#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {

// Fills plan.render_owner, render_position, patch_grid_render, render_triangles and
// render_vertices. Needs the patches, edges, output topology and owners; SV: sub-vertices;
// face_count: the faces of each sub-edge.
void build_render_vertices(Plan& plan, int SV, const TessellationTables& tess, const std::vector<int>& face_count);

}  // namespace sffd
