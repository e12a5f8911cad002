#include "smoothffd/eval/cpu_evaluator.hpp"

#include <chrono>
#include <climits>
#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/core/platform.hpp"

namespace sffd {

namespace {

bool cpu_runs_v3() {
#if defined(SFFD_HAVE_ISA_V3)
  return platform::cpu_runs_x86_64_v3();
#else
  return false;
#endif
}

const CpuFrameKernels* best_kernels() {
#if defined(SFFD_HAVE_ISA_V3)
  static const bool v3 = cpu_runs_v3();
  if (v3) return &cpu_frame_kernels_v3;
#endif
  return &cpu_frame_kernels_baseline;
}

const CpuFrameKernels* kernels_for(const std::string& isa) {
  if (isa == "auto" || isa.empty()) return best_kernels();
  if (isa == cpu_frame_kernels_baseline.isa) return &cpu_frame_kernels_baseline;
#if defined(SFFD_HAVE_ISA_V3)
  if (isa == cpu_frame_kernels_v3.isa) {
    if (!cpu_runs_v3()) throw std::invalid_argument("CpuEvaluator: this CPU cannot run " + isa + " code (no AVX2/FMA)");
    return &cpu_frame_kernels_v3;
  }
#endif
  std::string have;
  for (const std::string& name : cpu_isas()) have += (have.empty() ? "" : ", ") + name;
  throw std::invalid_argument("CpuEvaluator: unknown or unavailable isa '" + isa +
                              "' (this build and CPU run: auto, " + have + ")");
}

// The samples a frame of positions only reads when the plan has centre rows: the
// sub-vertices (corners, the edge adjustment's ends) and the edges' constraint samples.
SampleBatches positions_only_batches(const Plan& p) {
  if (p.centre_row.empty()) return {};
  std::vector<int> ids(p.sub_vertices);
  for (int v = 0; v < p.sub_vertices; ++v) ids[v] = v;
  ids.insert(ids.end(), p.edge_constraint.begin(), p.edge_constraint.end());
  std::sort(ids.begin() + p.sub_vertices, ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return make_sample_batches(p, &ids);
}

}  // namespace

std::string cpu_isa() { return best_kernels()->isa; }

std::vector<std::string> cpu_isas() {
  std::vector<std::string> out{cpu_frame_kernels_baseline.isa};
#if defined(SFFD_HAVE_ISA_V3)
  if (best_kernels() == &cpu_frame_kernels_v3) out.push_back(cpu_frame_kernels_v3.isa);
#endif
  return out;
}

CpuEvaluator::CpuEvaluator(std::shared_ptr<const Plan> plan, int threads, const std::string& isa)
    : plan_(std::move(plan)), threads_(threads > 0 ? threads : default_threads()),
      kernels_(kernels_for(isa)),
      batches_(make_sample_batches(*plan_)),
      positions_batches_(positions_only_batches(*plan_)),
      fit_columns_(make_fit_columns(*plan_)),
      grid_lanes_(make_grid_basis_lanes(*plan_)),
      output_owned_(owned_output_vertices(*plan_)),
      render_owned_(owned_render_vertices(*plan_)),
      end_normals_(make_edge_end_normals(*plan_)) {
  const Plan& p = *plan_;
  for (size_t i = 0; i + 1 < p.centre_start.size(); ++i)
    centre_widest_ = std::max(centre_widest_, p.centre_start[i + 1] - p.centre_start[i]);
  sample_value_.resize(3 * (size_t)p.samples);
  sample_jacobian_.resize(9 * (size_t)p.samples);
  end_normal_.resize(3 * (size_t)end_normals_.count());
  edge_control_.resize(6 * (size_t)p.edges);
  patch_control_.resize(30 * (size_t)p.patches);
  patch_normal_.resize(30 * (size_t)p.patches);
}

// Stage 4a: the sub-vertices' positions are their samples (exact images of the input and clip
// vertices); every other output vertex is tessellated by the patch that owns it.
void CpuEvaluator::tessellate_positions(const PlanView& pv, const FrameView& fv) {
  parallel_for(pv.sub_vertices, threads_, [&](long long b, long long e) {
    std::memcpy(fv.positions + 3 * b, fv.sample_value + 3 * b, 12 * (size_t)(e - b));
  });
  parallel_for(pv.patches, threads_, [&](long long b, long long e) {
    std::vector<float> points(3 * (size_t)grid_lanes_.padded);
    kernels_->tessellate_positions(pv, fv, grid_lanes_, output_owned_, b, e, points.data());
  });
}

std::string CpuEvaluator::isa() const { return kernels_->isa; }

StageTimes CpuEvaluator::evaluate(const float* D, float* positions, float* corner_normals) {
  return run(D, positions, corner_normals, nullptr);
}

StageTimes CpuEvaluator::evaluate_compact(const float* D, float* positions, float* render_normals) {
  return run(D, positions, nullptr, render_normals);
}

StageTimes CpuEvaluator::evaluate_positions(const float* D, float* positions) {
  return run(D, positions, nullptr, nullptr);
}

// The whole frame; the normals tessellated per triangle corner (corner_normals), once per
// render vertex by its owner (render_normals), or not at all (both null: positions only).
// Positions only, each stage runs the variant its own home has: sample_batch with jacobian ==
// null (values only), and with centre rows only the samples the geometry reads, or else
// fit_patch_lanes with out_n == null (geometry only); each is bitwise the full variant's
// values (test_cpu_lanes.cpp), and with centre rows both frames make the geometry patches
// with the same code, so the positions are bitwise the same
// (PositionsOnlyMatchesEvaluateBitwise, test_cpu_evaluator.cpp).
StageTimes CpuEvaluator::run(const float* D, float* positions, float* corner_normals, float* render_normals) {
  using Clock = std::chrono::steady_clock;
  const bool normals = corner_normals || render_normals;
  const PlanView pv = host_view(*plan_);
  FrameView fv{sample_value_.data(), sample_jacobian_.data(), edge_control_.data(),
               patch_control_.data(), normals ? patch_normal_.data() : nullptr, positions, corner_normals};
  StageTimes times;
  auto t0 = Clock::now();
  auto lap = [&](const char* name) {
    auto t1 = Clock::now();
    times.emplace_back(name, std::chrono::duration<double, std::milli>(t1 - t0).count());
    t0 = t1;
  };
  // Without normals the geometry reads Jacobians at the edge ends only (adjust_edge), i.e. at
  // the sub-vertex samples, numbered [0, sub_vertices) (plan.cpp): a batch holding one of them
  // runs with Jacobians, every other batch values only. Batches keep plan order within a
  // lattice box, so the sub-vertices fill batches of their own, and at most one batch a box
  // is mixed.
  // With centre rows (plan/centre_rows.hpp) the geometry patches need the sub-vertex and
  // edge-constraint samples only and no fitting: positions only, the other samples are not
  // evaluated (positions_batches_); with normals the fit makes the normal patches alone.
  const int jacobian_below = normals ? INT_MAX : pv.sub_vertices;
  const bool rows = pv.centre_row != nullptr;
  const SampleBatches& sb = rows && !normals ? positions_batches_ : batches_;
  const CpuFrameKernels& k = *kernels_;
  parallel_for(sb.count(), threads_, [&](long long b, long long e) {
    k.sample(pv, D, sb, b, e, fv.sample_value, fv.sample_jacobian, jacobian_below);
  });
  lap("sampling");
  parallel_for(end_normals_.count(), threads_, [&](long long b, long long e) {
    k.end_normals(fv, end_normals_, b, e, end_normal_.data());
  });
  parallel_for(pv.edges, threads_, [&](long long b, long long e) {
    k.adjust_edges(pv, fv, end_normals_, end_normal_.data(), b, e);
  });
  lap("edge_adjustment");
  if (normals || !rows) {
    FrameView fit = fv;
    if (rows) fit.patch_control = nullptr;
    parallel_for(pv.patches, threads_, [&](long long b, long long e) {
      k.fit_patches(pv, fit, fit_columns_, b, e);  // geometry only when fit.patch_normal is null
    });
  }
  if (rows)
    parallel_for(pv.patches, threads_, [&](long long b, long long e) {
      std::vector<float> block(3 * (size_t)centre_widest_);
      k.row_patches(pv, fv, D, b, e, block.data());
    });
  lap("fitting");
  tessellate_positions(pv, fv);
  lap("tessellate_positions");
  if (!normals) return times;
  parallel_for(pv.patches, threads_, [&](long long b, long long e) {
    std::vector<float> scratch(3 * (size_t)grid_lanes_.padded);
    if (render_normals)
      k.tessellate_render_normals(pv, fv, grid_lanes_, render_owned_, b, e, scratch.data(), render_normals);
    else
      k.tessellate_normals(pv, fv, grid_lanes_, b, e, scratch.data());
  });
  lap("tessellate_normals");
  return times;
}

}  // namespace sffd
