// The centre rows of a plan: each geometry patch's centre control point as an affine function
// of the control values, built once in double (Plan::centre_row).
//
// Everything before the edge adjustment is linear in the control values D: with D as plain
// displacements (components 3), a sample is F(s) = p_s + w_s sum_j W_j(s) D_j, and the fit
// is M_r times the samples. The adjustment then replaces the corners and the six edge control
// points (finish_patch, eval/stages.hpp), so of the whole fit only the centre survives, moved
// by a quarter of the adjusted edge points' sum minus the fitted ones':
//   b111 = sum_k m_k F(s_k) + 0.25 sum(adjusted),  m_k = M_r[centre][k] - 0.25 sum_edge-rows M_r[r][k]
//        = c_p + sum_j a_pj D_j + 0.25 sum(adjusted).
// c_p and a_pj (over the control points of the patch's lattice box) are the centre row. With
// it, a frame that needs positions only samples the sub-vertices and the edges' two
// constraint samples (about 3.5 of the K ~ 40 samples a patch) and fits nothing.
//
// Point weights (components 4: F = p + w^2 s d) are not linear in the control values: such
// plans have no centre rows, and their evaluators fit the centre every frame.
#pragma once

#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/plan/fit_matrix.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// The most control points along one axis a row may span (Plan::centre_box's 5-bit extents).
constexpr int kCentreMaxExtent = 31;

// Fills plan.centre_* from the plan's samples (patch_samples, sample_piece, sample_weight),
// sample_exact (S x 3: the samples' positions in double) and the fit. A patch's row runs over
// the control points its samples' pieces weigh: its lattice box, or a few boxes where the rest
// surface carries corner or edge samples across a knot plane (each sample is weighed with its
// own pieces, as the samplers weigh it). Leaves them empty with point weights.
void build_centre_rows(Plan& plan, const LatticeSpec& lattice, const FitTables& fit,
                       const std::vector<double>& sample_exact);

}  // namespace sffd
