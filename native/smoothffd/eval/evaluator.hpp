// The seam between the plan and the backends (OpenSubdiv's evaluators): every backend takes
// the same plan and, per frame, the control values D only.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/plan/plan.hpp"

namespace sffd {

using StageTimes = std::vector<std::pair<std::string, double>>;  // (stage, ms)

class Evaluator {
 public:
  virtual ~Evaluator() = default;
  virtual std::string name() const = 0;
  virtual const Plan& plan() const = 0;
  // D: nu*nv*nw x 3 control values. Writes positions (N x 3) and corner normals (T x 3 x 3)
  // to host memory and returns per-stage timings.
  virtual StageTimes evaluate(const float* D, float* positions, float* corner_normals) = 0;
  // The compact layout (Plan's render vertices): positions (N x 3) and unit normals per render
  // vertex (R x 3; an output vertex duplicated only where normals split), each render
  // vertex's normal from its owner (Plan::render_owner), the same on every backend up to
  // float rounding. render_normals null: positions only.
  virtual StageTimes evaluate_compact(const float* D, float* positions, float* render_normals) = 0;
};

}  // namespace sffd
