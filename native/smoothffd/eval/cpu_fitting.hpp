// Stage 3 (constrained fitting, Eq. 13) on the CPU, with the centre row's long sum vectorized.
//
// In fit_patch_into (eval/stages.hpp) almost all the time goes to the centre row: every
// fitting column needs its sample and its deformed render normal (cofactor of the Jacobian,
// two normalizations). Here kLanes columns of one patch run together on Lanes; the 9
// constraint columns, which feed every row, and finish_patch stay the shared scalar code. The
// result equals fit_patch_into's up to float rounding (the centre sum is added in another
// order); the CUDA evaluator runs fit_patch_into itself.
#pragma once

#include <vector>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {

// The fitting columns in a lane-friendly layout, built once per plan.
struct FitColumns {
  int centre = 0;            // columns feeding only the centre row: the first K - 9
  int padded = 0;            // centre rounded up to a multiple of kLanes
  std::vector<float> bary;   // 3 x padded: column_bary transposed ((1, 0, 0) in the padding)
  std::vector<float> weight; // padded: M_r's centre row (0 in the padding)
};

FitColumns make_fit_columns(const Plan& plan);

SFFD_ISA_BEGIN  // one copy per ISA (core/isa.hpp)

// The geometry patch (10 x 3 floats) of patch p into out_g and, when out_n is not null, its
// normal patch into out_n; reads fv.sample_value, fv.sample_jacobian (only for normals: the
// adjusted edges already used the corner Jacobians) and fv.edge_control.
void fit_patch_lanes(const PlanView& pv, const FrameView& fv, const FitColumns& fc, int p,
                     float* out_g, float* out_n);

SFFD_ISA_END

}  // namespace sffd
