// The seam between the plan and the backends (OpenSubdiv's evaluators): every backend takes
// the same plan and, per frame, the control values D only. Callers (the Python bindings)
// use this interface alone: every kind of frame below exists on every backend.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/plan/plan.hpp"

namespace sffd {

using StageTimes = std::vector<std::pair<std::string, double>>;  // (stage, ms)

// How much of a frame a backend recomputes.
//   whole:       everything.
//   incremental: only what reads a control point whose values differ (bitwise) from the
//                previous frame's. The output arrays must be the previous frame's, of the
//                same kind (positions only, corner normals or render normals), holding its
//                output untouched: what no changed point reaches is left as it is there.
//                When the previous frame was of another kind or wrote other arrays, or there
//                was none (or it failed), a whole frame. Bitwise the whole frame's output
//                either way. A backend without an incremental path (CUDA) runs a whole frame.
enum class Frame { whole, incremental };

// What a backend's last frame recomputed.
struct FrameCounts {
  long long changed_points = 0;  // control points that differ from the frame before (all: a whole frame)
  long long patches = 0;         // patches recomputed (all: a whole frame)
};

class Evaluator {
 public:
  virtual ~Evaluator() = default;
  virtual std::string name() const = 0;
  virtual const Plan& plan() const = 0;
  // D: nu*nv*nw x 3 control values. Writes positions (N x 3) and corner normals (T x 3 x 3)
  // to host memory and returns per-stage timings. corner_normals null: positions only.
  virtual StageTimes evaluate(const float* D, float* positions, float* corner_normals, Frame frame) = 0;
  // The compact layout (Plan's render vertices): positions (N x 3) and unit normals per render
  // vertex (R x 3; an output vertex duplicated only where normals split), each render
  // vertex's normal from its owner (Plan::render_owner), the same on every backend up to
  // float rounding. render_normals null: positions only.
  virtual StageTimes evaluate_compact(const float* D, float* positions, float* render_normals, Frame frame) = 0;
  // Positions only (N x 3), bitwise the same as evaluate's, for callers that compute normals
  // from the dense geometry themselves (the Blender add-on's viewport). What a backend saves
  // by it is its own (the CPU skips the normal half of the work, CUDA only the normals' copy
  // back).
  virtual StageTimes evaluate_positions(const float* D, float* positions, Frame frame) = 0;
  // What the last frame recomputed (zeros before the first).
  virtual FrameCounts last_frame() const = 0;
};

}  // namespace sffd
