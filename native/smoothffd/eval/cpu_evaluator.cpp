#include "smoothffd/eval/cpu_evaluator.hpp"

#include <chrono>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/eval/cpu_fitting.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/eval/cpu_tessellation.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {

CpuEvaluator::CpuEvaluator(std::shared_ptr<const Plan> plan, int threads)
    : plan_(std::move(plan)), threads_(threads > 0 ? threads : default_threads()),
      batches_(make_sample_batches(*plan_)),
      fit_columns_(make_fit_columns(*plan_)),
      grid_lanes_(make_grid_basis_lanes(*plan_)) {
  const Plan& p = *plan_;
  sample_value_.resize(3 * (size_t)p.samples);
  sample_jacobian_.resize(9 * (size_t)p.samples);
  edge_control_.resize(6 * (size_t)p.edges);
  patch_control_.resize(30 * (size_t)p.patches);
  patch_normal_.resize(30 * (size_t)p.patches);
}

StageTimes CpuEvaluator::evaluate(const float* D, float* positions, float* corner_normals) {
  using Clock = std::chrono::steady_clock;
  const PlanView pv = host_view(*plan_);
  FrameView fv{sample_value_.data(), sample_jacobian_.data(), edge_control_.data(),
               patch_control_.data(), patch_normal_.data(), positions, corner_normals};
  StageTimes times;
  auto t0 = Clock::now();
  auto lap = [&](const char* name) {
    auto t1 = Clock::now();
    times.emplace_back(name, std::chrono::duration<double, std::milli>(t1 - t0).count());
    t0 = t1;
  };
  parallel_for(batches_.count(), threads_, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) sample_batch(pv, D, batches_, i, fv.sample_value, fv.sample_jacobian);
  });
  lap("sampling");
  parallel_for(pv.edges, threads_, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) adjust_edge(pv, fv, (int)i);
  });
  lap("edge_adjustment");
  parallel_for(pv.patches, threads_, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p)
      fit_patch_lanes(pv, fv, fit_columns_, (int)p, fv.patch_control + 30 * p, fv.patch_normal + 30 * p);
  });
  lap("fitting");
  parallel_for(pv.output_vertices, threads_, [&](long long b, long long e) {
    for (long long o = b; o < e; ++o) tessellate_position(pv, fv, (int)o);
  });
  lap("tessellate_positions");
  const int LL = pv.level * pv.level;
  parallel_for(pv.patches, threads_, [&](long long b, long long e) {
    const int P = grid_lanes_.padded;
    std::vector<float> normals(3 * (size_t)P);
    for (long long p = b; p < e; ++p) {
      patch_grid_normals(pv, fv, grid_lanes_, (int)p, normals.data());
      float* out = corner_normals + 9 * p * LL;
      for (int i = 0; i < 3 * LL; ++i) {
        const int g = pv.local_triangles[i];
        out[3 * i] = normals[g];
        out[3 * i + 1] = normals[P + g];
        out[3 * i + 2] = normals[2 * P + g];
      }
    }
  });
  lap("tessellate_normals");
  return times;
}

// evaluate() without the normal half, each stage with the variant its own home already has:
// sample_batch with jacobian == null (values only) and fit_patch_lanes with out_n == null
// (geometry only), both bitwise the full variant's values (test_cpu_lanes.cpp). Kept a
// separate method: when evaluate's stages change, this one must follow, or
// PositionsOnlyMatchesEvaluateBitwise (test_cpu_evaluator.cpp) fails.
StageTimes CpuEvaluator::evaluate_positions(const float* D, float* positions) {
  using Clock = std::chrono::steady_clock;
  const PlanView pv = host_view(*plan_);
  FrameView fv{sample_value_.data(), sample_jacobian_.data(), edge_control_.data(),
               patch_control_.data(), nullptr, positions, nullptr};
  StageTimes times;
  auto t0 = Clock::now();
  auto lap = [&](const char* name) {
    auto t1 = Clock::now();
    times.emplace_back(name, std::chrono::duration<double, std::milli>(t1 - t0).count());
    t0 = t1;
  };
  // The geometry reads Jacobians at the edge ends only (adjust_edge), i.e. at the sub-vertex
  // samples, numbered [0, sub_vertices) (plan.cpp). A batch holding one of them runs with
  // Jacobians, every other batch values only. Batches keep plan order within a lattice box,
  // so the sub-vertices fill batches of their own, and at most one batch a box is mixed.
  const int corners = pv.sub_vertices;
  parallel_for(batches_.count(), threads_, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) {
      bool jacobian = false;
      for (int k = batches_.start[i]; k < batches_.start[i + 1]; ++k) jacobian |= batches_.order[k] < corners;
      sample_batch(pv, D, batches_, i, fv.sample_value, jacobian ? fv.sample_jacobian : nullptr);
    }
  });
  lap("sampling");
  parallel_for(pv.edges, threads_, [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) adjust_edge(pv, fv, (int)i);
  });
  lap("edge_adjustment");
  parallel_for(pv.patches, threads_, [&](long long b, long long e) {
    for (long long p = b; p < e; ++p)
      fit_patch_lanes(pv, fv, fit_columns_, (int)p, fv.patch_control + 30 * p, nullptr);
  });
  lap("fitting");
  parallel_for(pv.output_vertices, threads_, [&](long long b, long long e) {
    for (long long o = b; o < e; ++o) tessellate_position(pv, fv, (int)o);
  });
  lap("tessellate_positions");
  return times;
}

}  // namespace sffd
