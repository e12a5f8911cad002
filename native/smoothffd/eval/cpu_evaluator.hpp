// Multithreaded CPU evaluator: runs the stages of eval/stages.hpp over all elements.
#pragma once

#include "smoothffd/eval/evaluator.hpp"
#include "smoothffd/eval/cpu_fitting.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/eval/cpu_tessellation.hpp"

namespace sffd {

class CpuEvaluator : public Evaluator {
 public:
  CpuEvaluator(std::shared_ptr<const Plan> plan, int threads = 0);
  std::string name() const override { return "cpu"; }
  const Plan& plan() const override { return *plan_; }
  StageTimes evaluate(const float* D, float* positions, float* corner_normals) override;
  // Positions only (N x 3), bitwise the same as evaluate's, for callers that compute normals
  // from the dense geometry themselves (the Blender add-on's viewport): Jacobians only where
  // the edge adjustment reads them (the sub-vertex samples), geometry patches only, no normal
  // tessellation. Stage names as evaluate's, without "tessellate_normals".
  StageTimes evaluate_positions(const float* D, float* positions);
  int threads() const { return threads_; }

 private:
  std::shared_ptr<const Plan> plan_;
  int threads_;
  SampleBatches batches_;  // sampling: samples grouped by lattice box, kLanes at a time
  FitColumns fit_columns_; // fitting: the centre row's columns, kLanes at a time
  GridBasisLanes grid_lanes_;  // normal tessellation: grid points kLanes at a time
  std::vector<float> sample_value_, sample_jacobian_, edge_control_, patch_control_, patch_normal_;
};

}  // namespace sffd
