// Stage 4 (tessellation, Eq. 14) on the CPU, kLanes grid points at a time: each patch's G grid
// points from its cubic geometry patch and its G unit normals from its cubic normal patch (the
// grid basis transposed once per plan), then written where the patch owns them: the output
// vertices it owns (Plan::output_owner), the render vertices it owns (Plan::render_owner), or
// all of its L^2 x 3 corners. Equals tessellate_position / tessellate_normal (eval/stages.hpp)
// up to float rounding; normal lanes outside normalized_or's plain range redo the shared
// scalar code.
#pragma once

#include <vector>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {

struct GridBasisLanes {
  int padded = 0;            // G rounded up to a multiple of kLanes
  std::vector<float> basis;  // 10 x padded: grid_basis transposed (0 in the padding)
};

GridBasisLanes make_grid_basis_lanes(const Plan& plan);

// Per patch p, the (grid point, index) pairs whose value p writes:
// pairs[2 * start[p], 2 * start[p + 1]).
struct OwnedPoints {
  std::vector<int> start;  // P + 1
  std::vector<int> pairs;
};
// The output vertices past the sub-vertices (edge and interior points), by Plan::output_owner.
OwnedPoints owned_output_vertices(const Plan& plan);
// Every render vertex, by Plan::render_owner.
OwnedPoints owned_render_vertices(const Plan& plan);

SFFD_ISA_BEGIN  // one copy per ISA (core/isa.hpp)

// Unit normals of patch p at its G grid points into normals (padded floats x 3, SoA).
void patch_grid_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                        float* normals);
// Points of patch p at its G grid points into points (padded floats x 3, SoA).
void patch_grid_points(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                       float* points);

SFFD_ISA_END

}  // namespace sffd
