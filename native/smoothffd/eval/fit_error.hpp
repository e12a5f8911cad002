// The fit error estimate of one frame (plan/fit_error.hpp), on the CPU from the plan and the
// frame's control values, whichever backend evaluates the frame itself: the exact FFD and its
// Jacobian at every sample (the frame's first stage, once more), then for each patch Q times
// its samples and its sampled unit normals, the largest coefficient of each.
#pragma once

#include "smoothffd/plan/plan.hpp"

namespace sffd {

// geometry: P values, max |exact FFD image - fitted cubic| over patch p (object units);
// normal_degrees: P values, the normal patch's angle from the interpolated deformed normal
// field (degrees). D: the control values (nu*nv*nw x plan.components). threads: 0 = all.
void estimate_fit_errors(const Plan& plan, const float* D, int threads, float* geometry, float* normal_degrees);

}  // namespace sffd
