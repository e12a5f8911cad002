// Stage 4b (tessellation of the normal patches, Eq. 14) on the CPU, kLanes grid points at a
// time: each patch's G grid normals from its cubic normal patch (grid basis transposed once
// per plan), normalized on lanes, then copied to the patch's L^2 x 3 output corners. Equals
// tessellate_normal (eval/stages.hpp) up to float rounding; lanes outside normalized_or's
// plain range redo the shared scalar code.
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

SFFD_ISA_BEGIN  // one copy per ISA (core/isa.hpp)

// Unit normals of patch p at its G grid points into normals (padded floats x 3, SoA).
void patch_grid_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                        float* normals);

SFFD_ISA_END

}  // namespace sffd
