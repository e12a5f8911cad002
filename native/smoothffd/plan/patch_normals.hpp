// The normals at the patch corners (paper sec. 4.3.2): for shading, and for the geometry
// adjustment, then bounded on the sub-mesh so that no patch the evaluators make at rest folds.
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/plan/clip.hpp"
#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/input_surface.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

struct PatchNormals {
  std::vector<double> render;  // P x 3 x 3: the shading normals interpolated (barycentric,
                               // normalized) at the corners from the triangle's `shade`
  std::vector<double> adjust;  // P x 3 x 3: the input's adjustment normal at an input vertex,
                               // the PN quadratic normal field of the triangle at a clip vertex
};

// X: the input positions; in: after bound_rest_surface (its adjust.corner); shade: the
// shading normals (#T x 3 x 3, BoundedRest::shade).
PatchNormals patch_corner_normals(const std::vector<double>& X, const InputSurface& in, const ClipResult& clip,
                                  const std::vector<double>& shade);

// The bound on the sub-mesh (patches clip.patch_vertex, edges sub, corners at `position`, the
// rest surface points of the sub-vertices): the same as on the input (bound_adjust_normals,
// then bound_render_normals), repeated until no shading normal turns, at most 8 rounds (a
// turn can split a vertex's normals: sharp ends). A patch that is a whole input triangle is
// that triangle's rest patch, already checked: only pieces are checked at first. Fills
// plan.patch_render_normal, patch_adjust_normal (float), bounded_sub_vertices and
// turned_sub_normals; returns the sub-edges' sharp ends (classify_sharp_ends of the final
// shading normals).
std::vector<uint8_t> bound_patch_normals(Plan& plan, PatchNormals normals, const EdgeTable& sub,
                                         const std::vector<double>& position, const ClipResult& clip,
                                         const std::vector<uint8_t>& tri_flat, double cos_tol);

}  // namespace sffd
