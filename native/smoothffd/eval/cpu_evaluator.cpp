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

// fn(b, e) on ranges covering the elements of [0, n) (runs null), or only those of runs
// (an incremental frame), the threads sharing the elements evenly either way.
template <class Fn>
void for_elements(long long n, const ChangedRuns* runs, int threads, Fn&& fn) {
  if (!runs) {
    parallel_for(n, threads, fn);
    return;
  }
  parallel_for(runs->count(), threads, [&](long long b, long long e) {
    size_t r = std::upper_bound(runs->before.begin(), runs->before.end(), b) - runs->before.begin() - 1;
    for (; b < e; ++r) {
      const long long off = b - runs->before[r];
      const long long len = std::min(runs->end[r] - runs->begin[r] - off, e - b);
      fn(runs->begin[r] + off, runs->begin[r] + off + len);
      b += len;
    }
  });
}

// Per-thread scratch of at least n floats (the loops' tessellation grids and centre blocks):
// the pool's threads keep theirs, so a frame of many short ranges allocates nothing.
float* scratch(size_t n) {
  thread_local std::vector<float> s;
  if (s.size() < n) s.resize(n);
  return s.data();
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

// The tables an evaluator leaves in its pool: those that depend on the plan's samples (their
// batches) and on its output topology (the points each patch writes), with the plan's names of
// what they were made from.
struct CpuEvaluator::Carried {
  uint64_t samples_id = 0, topology_id = 0;
  SampleBatches batches;
  std::vector<int> slot;  // repiece_sample_batches's
  OwnedPoints output_owned, render_owned;
};

CpuEvaluator::CpuEvaluator(std::shared_ptr<const Plan> plan, int threads, const std::string& isa,
                           std::shared_ptr<BufferPool> pool)
    : plan_(std::move(plan)), pool_(std::move(pool)), threads_(threads > 0 ? threads : default_threads()),
      kernels_(kernels_for(isa)),
      positions_batches_(positions_only_batches(*plan_)),
      fit_columns_(make_fit_columns(*plan_)),
      grid_lanes_(make_grid_basis_lanes(*plan_)),
      end_normals_(make_edge_end_normals(*plan_)) {
  const Plan& p = *plan_;
  std::shared_ptr<Carried> carried = pool_ ? std::static_pointer_cast<Carried>(pool_->take_tables()) : nullptr;
  // The batches of the same samples, or of the plan this one followed with the samples that
  // changed pieces batched again (repiece_sample_batches).
  took_owned_ = carried && carried->topology_id == p.topology_id;
  if (carried && (carried->samples_id == p.samples_id ||
                  (p.samples_base_id != 0 && carried->samples_id == p.samples_base_id))) {
    batches_ = std::move(carried->batches);
    batch_slot_ = std::move(carried->slot);
    took_batches_ = carried->samples_id == p.samples_id || repiece_sample_batches(p, batches_, batch_slot_);
  }
  if (!took_batches_) {
    batches_ = make_sample_batches(p);
    batch_slot_.clear();
  }
  if (took_owned_) {
    output_owned_ = std::move(carried->output_owned);
    render_owned_ = std::move(carried->render_owned);
  } else {
    output_owned_ = owned_output_vertices(p);
    render_owned_ = owned_render_vertices(p);
  }
  for (size_t i = 0; i + 1 < p.centre_start.size(); ++i)
    centre_widest_ = std::max(centre_widest_, p.centre_start[i + 1] - p.centre_start[i]);
  auto buffer = [&](std::vector<float>& v, size_t n) {
    if (pool_)
      v = pool_->take(n);
    else
      v.resize(n);
  };
  buffer(sample_value_, 3 * (size_t)p.samples);
  buffer(sample_jacobian_, 9 * (size_t)p.samples);
  buffer(end_normal_, 3 * (size_t)end_normals_.count());
  buffer(edge_control_, 6 * (size_t)p.edges);
  buffer(patch_control_, 30 * (size_t)p.patches);
  buffer(patch_normal_, 30 * (size_t)p.patches);
}

CpuEvaluator::~CpuEvaluator() {
  if (!pool_) return;
  auto carried = std::make_shared<Carried>();
  carried->samples_id = plan_->samples_id;
  carried->topology_id = plan_->topology_id;
  carried->batches = std::move(batches_);
  carried->slot = std::move(batch_slot_);
  carried->output_owned = std::move(output_owned_);
  carried->render_owned = std::move(render_owned_);
  pool_->leave_tables(std::move(carried));
  for (auto* v : {&sample_value_, &sample_jacobian_, &end_normal_, &edge_control_, &patch_control_, &patch_normal_})
    pool_->give(std::move(*v));
}

// Stage 4a: the sub-vertices' positions are their samples (exact images of the input and clip
// vertices); every other output vertex is tessellated by the patch that owns it.
void CpuEvaluator::tessellate_positions(const PlanView& pv, const FrameView& fv, const ChangedRuns* runs) {
  parallel_for(pv.sub_vertices, threads_, [&](long long b, long long e) {
    std::memcpy(fv.positions + 3 * b, fv.sample_value + 3 * b, 12 * (size_t)(e - b));
  });
  for_elements(pv.patches, runs, threads_, [&](long long b, long long e) {
    kernels_->tessellate_positions(pv, fv, grid_lanes_, output_owned_, b, e, scratch(3 * (size_t)grid_lanes_.padded));
  });
}

std::string CpuEvaluator::isa() const { return kernels_->isa; }

StageTimes CpuEvaluator::evaluate(const float* D, float* positions, float* corner_normals, Frame frame) {
  return run(D, positions, corner_normals, nullptr, frame);
}

StageTimes CpuEvaluator::evaluate_compact(const float* D, float* positions, float* render_normals, Frame frame) {
  return run(D, positions, nullptr, render_normals, frame);
}

StageTimes CpuEvaluator::evaluate_positions(const float* D, float* positions, Frame frame) {
  return run(D, positions, nullptr, nullptr, frame);
}

// The whole frame; the normals tessellated per triangle corner (corner_normals), once per
// render vertex by its owner (render_normals), or not at all (both null: positions only).
// Positions only, each stage runs the variant its own home has: sample_batch with jacobian ==
// null (values only), and with centre rows only the samples the geometry reads, or else
// fit_patch_lanes with out_n == null (geometry only); each is bitwise the full variant's
// values (test_cpu_lanes.cpp), and with centre rows both frames make the geometry patches
// with the same code, so the positions are bitwise the same
// (PositionsOnlyMatchesEvaluateBitwise, test_cpu_evaluator.cpp).
StageTimes CpuEvaluator::run(const float* D, float* positions, float* corner_normals, float* render_normals,
                             Frame frame) {
  using Clock = std::chrono::steady_clock;
  const bool normals = corner_normals || render_normals;
  const Plan& plan = *plan_;
  const PlanView pv = host_view(plan);
  FrameView fv{sample_value_.data(), sample_jacobian_.data(), edge_control_.data(),
               patch_control_.data(), normals ? patch_normal_.data() : nullptr, positions, corner_normals};
  StageTimes times;
  auto t0 = Clock::now();
  auto lap = [&](const char* name) {
    auto t1 = Clock::now();
    times.emplace_back(name, std::chrono::duration<double, std::milli>(t1 - t0).count());
    t0 = t1;
  };
  // An incremental frame continues the previous one: same kind, same arrays. The
  // state is cleared first, so that a frame that throws (Cancelled) leaves none to continue.
  const Kind kind = render_normals ? Kind::compact : corner_normals ? Kind::corners : Kind::positions;
  const float* out_normals = corner_normals ? corner_normals : render_normals;
  const long long points = (long long)plan.dims[0] * plan.dims[1] * plan.dims[2];
  bool incremental = frame == Frame::incremental && last_kind_ == kind && last_out_[0] == positions &&
                     last_out_[1] == out_normals;
  last_kind_ = Kind::none;
  last_counts_ = {points, plan.patches};
  if (incremental) {
    last_counts_.changed_points = changed_.compare(plan.dims, plan.components, D, last_D_.data());
    incremental = last_counts_.changed_points < points;  // all moved: a whole frame, no tests
  }
  const bool rows = pv.centre_row != nullptr;
  const SampleBatches& sb = rows && !normals ? positions_batches_ : batches_;
  // Per stage, the elements this frame runs: null, all of them; else the runs that read a
  // changed point (none when nothing changed: the output is already this frame's).
  const ChangedRuns *samples = nullptr, *ends = nullptr, *edges = nullptr, *patches = nullptr;
  if (incremental) {
    if (!reach_)
      reach_ = std::make_unique<UpdateReach>(
          make_update_reach(plan, batches_, positions_batches_, end_normals_, threads_));
    hit_.resize(reach_->blocks.size());
    for (size_t i = 0; i < hit_.size(); ++i) hit_[i] = changed_.any_in(reach_->blocks[i]);
    sample_runs_.collect(&sb == &batches_ ? reach_->batches : reach_->positions_batches, hit_, threads_);
    end_runs_.collect(reach_->end_normals, hit_, threads_);
    edge_runs_.collect(reach_->edges, hit_, threads_);
    patch_runs_.collect(reach_->patches, hit_, threads_);
    samples = &sample_runs_, ends = &end_runs_, edges = &edge_runs_, patches = &patch_runs_;
    last_counts_.patches = patch_runs_.count();
    lap("changes");
  }
  // Without normals the geometry reads Jacobians at the edge ends only (adjust_edge), i.e. at
  // the sub-vertex samples, numbered [0, sub_vertices) (plan.cpp): a batch holding one of them
  // runs with Jacobians, every other batch values only. Batches keep plan order within a
  // lattice box, so the sub-vertices fill batches of their own, and at most one batch a box
  // is mixed.
  // With centre rows (plan/centre_rows.hpp) the geometry patches need the sub-vertex and
  // edge-constraint samples only and no fitting: positions only, the other samples are not
  // evaluated (positions_batches_); with normals the fit makes the normal patches alone.
  const int jacobian_below = normals ? INT_MAX : pv.sub_vertices;
  const CpuFrameKernels& k = *kernels_;
  for_elements(sb.count(), samples, threads_, [&](long long b, long long e) {
    k.sample(pv, D, sb, b, e, fv.sample_value, fv.sample_jacobian, jacobian_below);
  });
  lap("sampling");
  for_elements(end_normals_.count(), ends, threads_, [&](long long b, long long e) {
    k.end_normals(fv, end_normals_, b, e, end_normal_.data());
  });
  for_elements(pv.edges, edges, threads_, [&](long long b, long long e) {
    k.adjust_edges(pv, fv, end_normals_, end_normal_.data(), b, e);
  });
  lap("edge_adjustment");
  if (normals || !rows) {
    FrameView fit = fv;
    if (rows) fit.patch_control = nullptr;
    for_elements(pv.patches, patches, threads_, [&](long long b, long long e) {
      k.fit_patches(pv, fit, fit_columns_, b, e);  // geometry only when fit.patch_normal is null
    });
  }
  if (rows)
    for_elements(pv.patches, patches, threads_, [&](long long b, long long e) {
      k.row_patches(pv, fv, D, b, e, scratch(3 * (size_t)centre_widest_));
    });
  lap("fitting");
  tessellate_positions(pv, fv, patches);
  lap("tessellate_positions");
  if (normals) {
    for_elements(pv.patches, patches, threads_, [&](long long b, long long e) {
      float* grid = scratch(3 * (size_t)grid_lanes_.padded);
      if (render_normals)
        k.tessellate_render_normals(pv, fv, grid_lanes_, render_owned_, b, e, grid, render_normals);
      else
        k.tessellate_normals(pv, fv, grid_lanes_, b, e, grid);
    });
    lap("tessellate_normals");
  }
  last_D_.assign(D, D + points * plan.components);
  last_out_[0] = positions;
  last_out_[1] = out_normals;
  last_kind_ = kind;
  return times;
}

}  // namespace sffd
