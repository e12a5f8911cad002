// Where the output lies on the input faces (Plan: input_triangle_corner, patch_triangle,
// patch_bary): what a caller needs to carry data the core does not interpolate itself (more UV
// maps, vertex groups, colours) onto the output, the way the core interpolates its UVs.
#pragma once

#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/clip.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// The plan build's stage that records them: fills plan.input_corners, input_triangle_corner,
// input_triangle_face (the triangulation tr of mesh), patch_triangle, patch_bary (the clip's
// pieces) and patch_face (the input face of each patch).
void build_patch_sources(Plan& plan, const InputMesh& mesh, const Triangulation& tr, const ClipResult& clip);

// values: C x k floats per input corner (k >= 1) -> out: T x 3 x k at the output corners. The
// values at each patch's corners are interpolated in its input triangle (double, rounded to
// float), then across the tessellation grid (double, rounded to float): the arithmetic of
// Plan::uvs, which build_plan computes with this function. threads: 0 = all cores.
void interpolate_corners(const Plan& plan, const float* values, int k, float* out, int threads = 0);

// Per output vertex (N): the input triangle it lies in (index into input_triangle_corner; -1 for
// an input vertex that no triangle uses) and its barycentric point there (N x 3). Input vertices
// get exactly one-hot coordinates, points on an input triangle's edge exactly 0 for the opposite
// corner; a vertex on patches of several triangles takes its lowest patch's.
void vertex_sources(const Plan& plan, int* triangle, float* bary);

}  // namespace sffd
