// Multithreaded CPU evaluator: runs the stages of eval/stages.hpp over all elements.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "smoothffd/core/buffer_pool.hpp"
#include "smoothffd/eval/evaluator.hpp"
#include "smoothffd/eval/cpu_fitting.hpp"
#include "smoothffd/eval/cpu_frame.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/eval/cpu_tessellation.hpp"
#include "smoothffd/eval/cpu_update.hpp"

namespace sffd {

// The per-frame code path CpuEvaluator takes by default on this CPU: "x86-64-v3" when this
// build has the AVX2 + FMA copy (SMOOTHFFD_DISPATCH) and CPUID says the CPU runs it, else the
// baseline's name (SFFD_ISA_NAME: "x86-64-v2" for shipped builds). Decided once per process.
std::string cpu_isa();
// Every path this build has and this CPU can run, baseline first.
std::vector<std::string> cpu_isas();

class CpuEvaluator : public Evaluator {
 public:
  // isa: "auto" (cpu_isa()), or the name of one of the per-frame code paths (core/isa.hpp):
  // "x86-64-v2" (the baseline of shipped builds), "x86-64-v3" (AVX2 + FMA). Throws
  // std::invalid_argument for a path this build lacks or this CPU cannot run.
  // pool: where this evaluator takes its per-frame buffers from and gives them back to when it
  // is destroyed (core/buffer_pool.hpp), or null: its own. Its tables of the samples' batches
  // and of the points each patch writes go there too, and the next evaluator takes them over
  // where its plan has the same samples and output topology (Plan::samples_id, topology_id:
  // a plan that followed a pose holding its pieces, follow_plan), instead of making them again.
  CpuEvaluator(std::shared_ptr<const Plan> plan, int threads = 0, const std::string& isa = "auto",
               std::shared_ptr<BufferPool> pool = nullptr);
  ~CpuEvaluator() override;
  std::string name() const override { return "cpu"; }
  std::string isa() const;  // the path this evaluator runs
  const Plan& plan() const override { return *plan_; }
  // The frames of evaluator.hpp, incremental ones included (eval/cpu_update.hpp): an edit
  // that moves a few points of a large lattice costs the part of the mesh they reach.
  StageTimes evaluate(const float* D, float* positions, float* corner_normals, Frame frame) override;
  // The compact layout: evaluate's stages, the normals tessellated once per render vertex by
  // its owner instead of once per triangle corner. render_normals null: evaluate_positions.
  StageTimes evaluate_compact(const float* D, float* positions, float* render_normals, Frame frame) override;
  // Positions only, bitwise the same as evaluate's: Jacobians only where the edge adjustment
  // reads them (the sub-vertex samples), geometry patches only, no normal tessellation; with
  // centre rows (plan/centre_rows.hpp) only the sub-vertex and edge constraint samples and no
  // fitting. Stage names as evaluate's, without "tessellate_normals".
  StageTimes evaluate_positions(const float* D, float* positions, Frame frame) override;
  FrameCounts last_frame() const override { return last_counts_; }
  // Host memory of the incremental frames' tables (built on the first incremental frame; 0 before).
  size_t update_bytes() const { return reach_ ? reach_->bytes() : 0; }
  int threads() const { return threads_; }
  // Whether this evaluator took its sample batches (batching again only the samples whose
  // lattice pieces changed), and its tables of the output and render vertices each patch
  // writes, over from the evaluator before it (pool).
  bool took_sample_batches() const { return took_batches_; }
  bool took_output_tables() const { return took_owned_; }

 private:
  enum class Kind { none, positions, corners, compact };
  StageTimes run(const float* D, float* positions, float* corner_normals, float* render_normals, Frame frame);
  void tessellate_positions(const PlanView& pv, const FrameView& fv, const ChangedRuns* runs);
  struct Carried;  // the tables left to the next evaluator (cpu_evaluator.cpp)
  std::shared_ptr<const Plan> plan_;
  std::shared_ptr<BufferPool> pool_;
  bool took_batches_ = false, took_owned_ = false;
  int threads_;
  const CpuFrameKernels* kernels_;  // the per-ISA per-frame loops
  SampleBatches batches_;  // sampling: samples grouped by lattice box, kLanes at a time
  std::vector<int> batch_slot_;  // each sample's place in them, once a follow repieced them
  SampleBatches positions_batches_;  // the same for positions only with centre rows
  FitColumns fit_columns_; // fitting: the centre row's columns, kLanes at a time
  GridBasisLanes grid_lanes_;  // normal tessellation: grid points kLanes at a time
  OwnedPoints output_owned_;  // position tessellation: the output vertices each patch writes
  OwnedPoints render_owned_;  // compact normals: the render vertices each patch writes
  EdgeEndNormals end_normals_;  // edge adjustment: its distinct end normals
  long long centre_widest_ = 0;  // the plan's longest centre row (floats)
  std::vector<float> sample_value_, sample_jacobian_, end_normal_, edge_control_, patch_control_, patch_normal_;
  // Incremental frames: the previous frame's kind, output arrays and control values, and what
  // each element reads (built on the first incremental frame).
  Kind last_kind_ = Kind::none;
  const float* last_out_[2] = {nullptr, nullptr};
  std::vector<float> last_D_;
  FrameCounts last_counts_;
  std::unique_ptr<UpdateReach> reach_;
  ChangedPoints changed_;
  std::vector<uint8_t> hit_;  // per distinct block of reach_: whether a changed point is in it
  ChangedRuns sample_runs_, end_runs_, edge_runs_, patch_runs_;
};

}  // namespace sffd
