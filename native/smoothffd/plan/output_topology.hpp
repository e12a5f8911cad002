// The welded output topology of a plan (paper sec. 5.5; plan.hpp: tessellation, static
// outputs): every patch tessellated at level L, the grid points shared along the sub-mesh's
// edges and at its vertices, so that the output is as watertight as the sub-mesh.
//
// Output vertices: the sub-vertices [0, SV), then L - 1 inside each sub-edge e (step m from
// end a: SV + e (L - 1) + m - 1), then (L - 1)(L - 2) / 2 inside each patch p
// (SV + E (L - 1) + p (L - 1)(L - 2) / 2 + interior ordinal). Each output vertex past the
// sub-vertices is owned by the first (patch, grid point) that reaches it.
#pragma once

#include <vector>

#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {

// Needs plan.patch_vertex, patch_edge, patch_edge_reversed, patch_face, edge_vertex,
// edge_flags and sub_vertices. rest: the sub-vertices' rest positions (SV x 3, on the input's
// flat faces); corner_uv: the input's UVs (C x 2) or empty. Fills plan.grid_basis,
// local_triangles, patch_grid_vertex, output_owner, rest_positions (barycentric in the patch's
// flat triangle), triangles, face_index, uvs (interpolate_corners), sharp_edges (the output
// edges along each sub-edge sharp at either end), level, grid, output_vertices and
// output_triangles. Throws std::invalid_argument past 2e9 output vertices or indices.
void build_output_topology(Plan& plan, const TessellationTables& tess, const std::vector<double>& rest,
                           const std::vector<float>& corner_uv);

// The parts of the static output that depend on positions, from a plan's output topology
// (patch_vertex, output_owner, sub_vertices, output_vertices), each into `out` (resized; its
// storage reused): the rest positions (N x 3) of the sub-vertices at `rest` (SV x 3) ...
void output_rest_positions(const Plan& plan, const TessellationTables& tess, const std::vector<double>& rest,
                           std::vector<float>& out);
// ... and the UVs at the output corners (T x 3 x 2; empty without corner_uv), which follow
// the patches' corners on their input triangles (patch_bary; interpolate_corners).
void output_uvs(const Plan& plan, const std::vector<float>& corner_uv, std::vector<float>& out);

}  // namespace sffd
