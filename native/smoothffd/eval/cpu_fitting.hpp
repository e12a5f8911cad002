// Stage 3 (constrained fitting, Eq. 13) on the CPU, vectorized.
//
// Every fitting column needs its sample and its deformed render normal (cofactor of the
// Jacobian, two normalizations): here kLanes columns of one patch run together on Lanes,
// the K - 9 centre columns (which feed the centre row only) and then the 9 constraint
// columns, whose products with all 10 rows of M_r run with the rows on lanes. finish_patch
// stays the shared scalar code. The result equals fit_patch_into's (eval/stages.hpp) up to
// float rounding (the sums are added in another order).
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
  // The 9 constraint columns, padded to 2 kLanes: their barycentric points (3 x 16, (1, 0, 0)
  // in the padding) and M_r's entries in them with the rows on lanes (16 x 16: column c's 10
  // rows at 16 c, 0 in the padding).
  std::vector<float> cbary;
  std::vector<float> crows;
};

FitColumns make_fit_columns(const Plan& plan);

SFFD_ISA_BEGIN  // one copy per ISA (core/isa.hpp)

// The geometry patch (10 x 3 floats) of patch p into out_g and, when out_n is not null, its
// normal patch into out_n; reads fv.sample_value, fv.sample_jacobian (only for normals: the
// adjusted edges already used the corner Jacobians) and fv.edge_control.
// out_g null: the normal patch only.
void fit_patch_lanes(const PlanView& pv, const FrameView& fv, const FitColumns& fc, int p,
                     float* out_g, float* out_n);

// Plans with centre rows (plan/centre_rows.hpp). centre_block: the control values of the
// block `box` (a patch's Plan::centre_box) as its rows read them, 3 x stride floats (x, then
// y, then z; 0 in the padding); returns the stride (the row's length).
// geometry_patch_from_row: the geometry patch of p, whose block is `block`, from its corners,
// its adjusted edge control points and its centre row (patch_from_centre_row, the row's sum
// on lanes): fit_patch_lanes's patch up to float rounding, with no fitting.
int centre_block(const PlanView& pv, const float* D, uint64_t box, float* block);
void geometry_patch_from_row(const PlanView& pv, const FrameView& fv, const float* block, int stride, int p,
                             float* out_g);

SFFD_ISA_END

}  // namespace sffd
