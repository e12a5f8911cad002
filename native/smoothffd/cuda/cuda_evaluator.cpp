// The CUDA evaluator's host side (cuda_evaluator.hpp): device memory, the plan's tables up
// once, the path and the inline kernel's mode, a frame's launches (kernels.hpp), the copy
// back. No kernel is defined here.
#include "smoothffd/cuda/cuda_evaluator.hpp"

#include <cuda_runtime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/cuda/cublas_gemm.hpp"
#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/cuda/host_copy.hpp"
#include "smoothffd/cuda/kernels.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

enum Path { kFused = 0, kCublas = 1 };

Path parse_path(const std::string& v) {
  if (v.empty() || v == "fused") return kFused;
  if (v == "cublas") return kCublas;
  throw std::invalid_argument("CUDA path: expected 'fused' or 'cublas', got '" + v + "'");
}

}  // namespace

struct CudaEvaluator::Impl {
  Path path = kFused;
  DeviceArena arena;
  PlanView pv{};
  FrameView fv{};
  // Both paths' tessellation tables (device copies of DeviceTables').
  GridInfo* grid_info = nullptr;
  uint8_t* owns = nullptr;
  PatchRender* prender = nullptr;  // P
  long long render_shift = 0;      // R - N
  int terms = 0;                   // kernel_terms of the plan
  // The inline kernel: its mode (kInlineNone: the fused path runs the reference kernels), its
  // launch arguments, dynamic shared memory and persistent grid (0 before the first launch).
  InlineMode inline_mode = kInlineNone;
  std::string no_inline;
  InlineArgs inline_args{};
  size_t inline_smem = 0;
  int inline_grid = 0;
  int* loose = nullptr;  // sub-vertices in no patch
  int loose_count = 0;
  float* D = nullptr;
  float* normals = nullptr;  // R x 3 (render vertices)
  // The reference path's buffers (ensure_reference): the frame's samples, Jacobians and edge
  // control points (fv), and the products' matrices.
  std::unique_ptr<CublasGemm> gemm;
  std::unique_ptr<AdaptiveDevice> adaptive;  // made by the first adaptive frame
  float* X = nullptr;  // K x 6P
  float* F = nullptr;  // 10 x 6P
  float* C = nullptr;  // 10 x 6P
  float* Q = nullptr;  // G x 6P
  PinnedBuffer h_D, h_out;
  cudaStream_t stream = nullptr;
  Events events;
  size_t nD = 0;
  // Shared-memory limits the launches are planned with (plan_limits): the device's own, or
  // those of the smaller device emulated (shared_memory_limit > 0).
  int64_t shared_memory_limit = 0;
  DeviceLimits lim{};
  size_t inline_dyn_max = 0;     // largest dynamic table of the inline kernel on this device
  size_t inline_dyn_device = 0;  // the same on the real device (the kernel's opt-in attribute)

  ~Impl() {
    gemm.reset();
    adaptive.reset();
    if (stream) cudaStreamDestroy(stream);
  }

  // The device's limits (or the emulated device's) and the inline kernel's dynamic budget:
  // static + dynamic within what a block may opt in to, and one block (plus the memory the
  // system reserves a block) within a multiprocessor. Consumer GPUs give a block far less than
  // an H100 (227 KB): 99 KB on sm_86 / sm_89, 64 KB on sm_75, 163 KB on sm_80.
  void plan_limits() {
    int dev = 0, optin = 0, per_sm = 0, reserved = 0, sms = 0, regs = 0, major = 0, minor = 0;
    CK(cudaGetDevice(&dev));
    CK(cudaDeviceGetAttribute(&optin, cudaDevAttrMaxSharedMemoryPerBlockOptin, dev));
    CK(cudaDeviceGetAttribute(&per_sm, cudaDevAttrMaxSharedMemoryPerMultiprocessor, dev));
    CK(cudaDeviceGetAttribute(&reserved, cudaDevAttrReservedSharedMemoryPerBlock, dev));
    CK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, dev));
    CK(cudaDeviceGetAttribute(&regs, cudaDevAttrMaxRegistersPerMultiprocessor, dev));
    CK(cudaDeviceGetAttribute(&major, cudaDevAttrComputeCapabilityMajor, dev));
    CK(cudaDeviceGetAttribute(&minor, cudaDevAttrComputeCapabilityMinor, dev));
    lim = DeviceLimits{};
    lim.per_block = optin;
    lim.per_multiprocessor = per_sm;
    if (shared_memory_limit > 0) {
      lim.per_block = std::min<int64_t>(optin, shared_memory_limit);
      lim.per_multiprocessor = std::min<int64_t>(per_sm, shared_memory_limit + reserved);
    }
    lim.reserved_per_block = reserved;
    lim.multiprocessors = sms;
    lim.registers_per_multiprocessor = regs;
    lim.compute_capability = 10 * major + minor;
    // The static tables are the same in every mode; the largest, to be safe.
    size_t st = inline_static_shared(terms, kInlineGlobal);
    if (terms <= 4)
      st = std::max({st, inline_static_shared(terms, kInlineBoxes), inline_static_shared(terms, kInlineWeights)});
    lim.inline_static = (int64_t)st;
    auto budget = [&](int64_t block, int64_t sm) {
      const int64_t room = std::min(block, sm - reserved) - (int64_t)st;
      return (size_t)std::max<int64_t>(0, std::min<int64_t>(room, (int64_t)kInlineSharedBytes));
    };
    inline_dyn_max = budget(lim.per_block, lim.per_multiprocessor);
    inline_dyn_device = budget(optin, per_sm);
    lim.inline_dynamic_max = (int64_t)inline_dyn_max;
  }

  // The plan's arrays the kernels read, on the device.
  void upload_plan(const Plan& p) {
    PlanView& v = pv;
    v = host_view(p);
    DeviceArena& a = arena;
    v.pieces = a.upload(p.pieces);
    v.sample_position = a.upload(p.sample_position);
    v.sample_piece = a.upload(p.sample_piece);
    v.sample_weight = a.upload(p.sample_weight);
    v.sample_local = p.sample_local.empty() ? nullptr : a.upload(p.sample_local);
    v.fit_matrix = a.upload(p.fit_matrix);
    v.column_bary = a.upload(p.column_bary);
    v.patch_samples = a.upload(p.patch_samples);
    v.patch_vertex = a.upload(p.patch_vertex);
    v.patch_edge = a.upload(p.patch_edge);
    v.patch_edge_reversed = a.upload(p.patch_edge_reversed);
    v.patch_render_normal = a.upload(p.patch_render_normal);
    v.patch_adjust_normal = a.upload(p.patch_adjust_normal);
    v.edge_vertex = a.upload(p.edge_vertex);
    v.edge_constraint = a.upload(p.edge_constraint);
    v.edge_patch = a.upload(p.edge_patch);
    v.edge_slot = a.upload(p.edge_slot);
    v.edge_flags = a.upload(p.edge_flags);
    v.grid_basis = a.upload(p.grid_basis);
    v.local_triangles = a.upload(p.local_triangles);
    v.output_owner = a.upload(p.output_owner);
    // Render-vertex tables stay on the host (the per-corner copy back gathers there); the
    // kernels use the per-patch PatchRender.
    v.render_owner = v.render_position = v.patch_grid_render = v.render_triangles = nullptr;
  }

  // The device tables (device_tables.hpp) and the inline kernel's mode for the budget.
  void upload_tables(const Plan& p) {
    DeviceTables t = build_device_tables(p, build_tessellation(p.level));
    grid_info = arena.upload(t.grid_info);
    owns = arena.upload(t.owns);
    prender = arena.upload(t.render);
    render_shift = t.render_shift;
    inline_mode = choose_inline_mode(t, inline_dyn_max);
    no_inline = t.no_inline;
    if (inline_mode == kInlineNone) return;
    InlineArgs& ia = inline_args;
    ia = InlineArgs{};
    ia.points = t.points;
    ia.n_pieces = t.n_pieces;
    ia.column = arena.upload(t.column);
    ia.column_map = arena.upload(std::vector<ColumnMap>{t.column_map});
    std::memcpy(ia.mrow, t.mrow, sizeof(ia.mrow));
    ia.walk_boundary = t.walk_boundary;
    ia.st_interior = t.st_interior;
    ia.st_count = t.st_count;
    ia.grid_st = arena.upload(t.grid_st);
    ia.grid_walk = arena.upload(t.grid_walk);
    loose_count = (int)t.loose.size();
    if (loose_count) loose = arena.upload(t.loose);
    if (inline_mode == kInlineGlobal) {
      ia.pieces_wide = arena.upload(t.pieces_wide);
    } else {
      ia.pieces = arena.upload(t.pieces);
      ia.box_count = (int)t.box_list.size();
      ia.boxes = inline_mode == kInlineBoxes ? ia.box_count : 0;
      ia.box_list = arena.upload(t.box_list);
      ia.list_stride = t.list_stride();
      ia.boundary_list = arena.upload(build_boundary_lists(t));  // also sets the records' items
      inline_smem = t.shared_bytes(inline_mode == kInlineBoxes);
    }
    ia.patch_rec = arena.upload(t.patch_rec);
  }

  // The reference path's frame buffers, matrices and cuBLAS (CudaError when it cannot load).
  void ensure_reference() {
    if (gemm) return;
    const long long P = pv.patches, K = pv.columns, G = pv.grid, S = pv.samples, E = pv.edges;
    if (!X) {
      fv.sample_value = arena.alloc<float>(3 * S);
      fv.sample_jacobian = arena.alloc<float>(9 * S);
      fv.edge_control = arena.alloc<float>(6 * E);
      X = arena.alloc<float>(K * 6 * P);
      F = arena.alloc<float>(10 * 6 * P);
      C = arena.alloc<float>(10 * 6 * P);
      Q = arena.alloc<float>(G * 6 * P);
    }
    gemm = std::make_unique<CublasGemm>(stream);
  }

  void stage_D(const float* Dh) { std::memcpy(h_D.ptr, Dh, nD * sizeof(float)); }

  // Whether this frame runs the inline kernel (else the reference kernels).
  bool inline_path() const { return path == kFused && inline_mode != kInlineNone; }
  // Whether a frame of the inline path passes the control values as launch parameters
  // (InlineControls) instead of copying them to the device first.
  bool inline_params() const {
    return inline_mode != kInlineGlobal && nD <= 3 * (size_t)kParamPoints && loose_count == 0;
  }

  // The inline kernel: a persistent grid of as many blocks as fit on the device at once
  // (asked at the first launch), each taking groups of 32 patches until none is left; first,
  // the loose vertices' launch when the mesh has any.
  template <class Mark>
  void run_inline(Mark& mark) {
    InlineControls dp;
    if (inline_params()) std::memcpy(dp.v, h_D.ptr, nD * sizeof(float));
    if (loose_count > 0) {
      mark("loose_vertices");
      launch_loose_vertices(terms, pv, fv, D, loose, loose_count, stream);
    }
    mark("sample_fit_tessellate");
    if (pv.patches > 0) {
      if (inline_grid == 0) {
        int per_sm = inline_blocks_per_multiprocessor(terms, inline_mode, inline_smem, inline_dyn_device);
        if (shared_memory_limit > 0) {  // the emulated device's multiprocessor holds fewer
          const int64_t block = lim.inline_static + (int64_t)inline_smem + lim.reserved_per_block;
          per_sm = std::min<int>(per_sm, (int)(lim.per_multiprocessor / block));
        }
        lim.inline_blocks_per_multiprocessor = std::max(1, per_sm);
        inline_grid = std::max(1, per_sm) * std::max(1, lim.multiprocessors);
      }
      InlineArgs ia = inline_args;
      ia.groups = (int)blocks_for(pv.patches, 32);
      ia.D = inline_params() ? nullptr : D;
      launch_inline(terms, inline_mode, std::min(ia.groups, inline_grid), inline_smem, pv, fv, ia, dp, render_shift,
                    normals, stream);
    }
    mark(nullptr);
  }

  // The reference path (the paper's formulation): sampling and edge kernels, then the two
  // products with cuBLAS around a finishing kernel, then the scatter.
  template <class Mark>
  void run_reference(Mark& mark) {
    mark("sampling");
    launch_sample(terms, pv, fv, D, stream);
    mark("edge_adjustment");
    launch_edges(pv, fv, stream);
    if (pv.patches > 0) {
      const int P = pv.patches, K = pv.columns, G = pv.grid;
      mark("gather");
      launch_gather(pv, fv, X, stream);
      mark("fit_gemm");
      // F (10 x 6P) = M (10 x K) X (K x 6P); M stored row-major = column-major K x 10.
      gemm->gemm_tn(10, 6 * P, K, pv.fit_matrix, K, X, K, F, 10);
      mark("fit_finish");
      launch_finish(pv, fv, F, C, stream);
      mark("tessellate_gemm");
      // Q (G x 6P) = B (G x 10) C (10 x 6P); grid_basis stored row-major = column-major 10 x G.
      gemm->gemm_tn(G, 6 * P, 10, pv.grid_basis, 10, C, 10, Q, G);
      mark("tessellate_scatter");
      launch_scatter(pv, fv, Q, C, grid_info, owns, prender, render_shift, normals, stream);
    }
    mark(nullptr);
  }

  // Enqueues a frame's device stages, D already staged; mark(name) before each stage,
  // mark(nullptr) at the end.
  template <class Mark>
  void run_stages(Mark& mark) {
    if (!(inline_path() && inline_params())) {  // else the control values ride in the launch
      mark("upload");
      CK(cudaMemcpyAsync(D, h_D.ptr, nD * sizeof(float), cudaMemcpyHostToDevice, stream));
    }
    if (inline_path())
      run_inline(mark);
    else
      run_reference(mark);
  }

  // Runs the stages recording events[i] before stage i; returns the stage names (events
  // 0 .. names.size() used).
  std::vector<const char*> run_recorded() {
    std::vector<const char*> names;
    size_t e = 0;
    auto mark = [&](const char* name) {
      if (name) names.push_back(name);
      events.ensure(e + 1);
      CK(cudaEventRecord(events.ev[e++], stream));
    };
    run_stages(mark);
    return names;
  }

  StageTimes times_from(const std::vector<const char*>& names) {
    StageTimes t;
    for (size_t i = 0; i < names.size(); ++i) t.emplace_back(names[i], elapsed_ms(events.ev[i], events.ev[i + 1]));
    return t;
  }
};

CudaEvaluator::CudaEvaluator(std::shared_ptr<const Plan> plan, const std::string& path, int64_t shared_memory_limit)
    : plan_(std::move(plan)), impl_(new Impl) {
  if (shared_memory_limit != 0 && shared_memory_limit < 48 * 1024)
    throw std::invalid_argument("shared_memory_limit: expected 0 (the device's own limits) or at least 49152 bytes "
                                "(48 KiB, what every CUDA device gives a block), got " +
                                std::to_string(shared_memory_limit));
  Impl& m = *impl_;
  m.path = parse_path(path);
  init_device();
  m.shared_memory_limit = shared_memory_limit;
  m.terms = kernel_terms(plan_max_terms(*plan_));
  const Plan& p = *plan_;
  CK(cudaStreamCreateWithFlags(&m.stream, cudaStreamNonBlocking));
  m.events.ensure(16);
  m.plan_limits();
  m.upload_plan(p);
  m.upload_tables(p);

  const long long N = p.output_vertices;
  m.nD = (size_t)p.components * p.dims[0] * p.dims[1] * p.dims[2];
  m.D = m.arena.alloc<float>(m.nD);
  m.h_D.ensure(m.nD * sizeof(float));
  // The interior's first output vertex (and its render vertex) on a 128-byte line: a warp's
  // run of interior points (64 points, 768 bytes a field) and a group's (32 patches) are whole
  // lines, so every run starts on one and its stores fill whole 32-byte sectors. The buffers
  // start 0-31 floats into their allocations (cudaMalloc's are 256-byte aligned). Against
  // 16-byte alignment, which left runs half a sector off on some plans and levels: W1 2.2-2.5%
  // faster at L = 12-16 (k_inline's store sectors -6%), 0.7% at L = 10 (H100, same call).
  const long long interior0 = p.sub_vertices + (long long)p.edges * (p.level - 1);
  auto lead = [](long long first) { return (int)((32 - (3 * first) % 32) % 32); };
  m.fv = FrameView{};
  m.fv.positions = m.arena.alloc<float>(3 * N + 32) + lead(interior0);
  m.normals = m.arena.alloc<float>(3 * (long long)p.render_vertices + 32) + lead(interior0 + m.render_shift);
  if (m.path == kCublas) {
    m.ensure_reference();
  } else if (m.inline_mode == kInlineNone) {  // the fused path runs the reference kernels
    try {
      m.ensure_reference();
    } catch (const CudaError& e) {
      throw CudaError("the inline kernel cannot run this plan (" + m.no_inline +
                      "), and the cuBLAS path that would serve it is unavailable: " + e.what());
    }
  }
  CK(cudaDeviceSynchronize());
}

CudaEvaluator::~CudaEvaluator() = default;

std::string CudaEvaluator::path() const { return impl_->path == kFused ? "fused" : "cublas"; }

const char* CudaEvaluator::kernel() const {
  const Impl& m = *impl_;
  if (!m.inline_path()) return "cublas";
  return m.inline_mode == kInlineBoxes ? "inline (boxes)" : m.inline_mode == kInlineWeights ? "inline (weights)"
                                                                                          : "inline (global)";
}

size_t CudaEvaluator::output_bytes() const {
  const Plan& p = *plan_;
  return 12 * ((size_t)p.output_vertices + (size_t)p.render_vertices);
}

size_t CudaEvaluator::device_bytes() const { return impl_->arena.bytes; }

DeviceLimits CudaEvaluator::limits() const {
  const Impl& m = *impl_;
  DeviceLimits l = m.lim;
  l.inline_dynamic = m.inline_path() ? (int64_t)m.inline_smem : 0;
  return l;
}

void CudaEvaluator::testing_poison() {
  Impl& m = *impl_;
  const Plan& p = *plan_;
  const long long S = p.samples, E = p.edges, P = p.patches;
  launch_fill_nan(m.fv.positions, 3LL * p.output_vertices, m.stream);
  launch_fill_nan(m.normals, 3LL * p.render_vertices, m.stream);
  if (m.X) {
    launch_fill_nan(m.fv.sample_value, 3 * S, m.stream);
    launch_fill_nan(m.fv.sample_jacobian, 9 * S, m.stream);
    launch_fill_nan(m.fv.edge_control, 6 * E, m.stream);
    launch_fill_nan(m.X, P * p.columns * 6, m.stream);
    launch_fill_nan(m.F, 60 * P, m.stream);
    launch_fill_nan(m.C, 60 * P, m.stream);
    launch_fill_nan(m.Q, 6 * P * p.grid, m.stream);
  }
  CK(cudaStreamSynchronize(m.stream));
}

void* CudaEvaluator::stream() const { return impl_->stream; }

void CudaEvaluator::enqueue_frame(const float* D, const std::function<void(const char*)>& mark) {
  impl_->stage_D(D);
  impl_->run_stages(mark);
}

StageTimes CudaEvaluator::evaluate_device(const float* D) {
  Impl& m = *impl_;
  m.stage_D(D);
  const std::vector<const char*> names = m.run_recorded();
  CK(cudaEventSynchronize(m.events.ev[names.size()]));
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names);
  double total = 0;
  for (auto& kv : t) total += kv.second;
  t.emplace_back("device_total", total);
  return t;
}

StageTimes CudaEvaluator::evaluate(const float* D, float* positions, float* corner_normals) {
  using Clock = std::chrono::steady_clock;
  Impl& m = *impl_;
  const Plan& p = *plan_;
  const size_t N = p.output_vertices, R = p.render_vertices, T = p.output_triangles;
  m.h_out.ensure(12 * (N + R));
  m.stage_D(D);
  const std::vector<const char*> names = m.run_recorded();
  const size_t e = names.size();  // event e marks the end of the device stages
  m.events.ensure(e + 2);
  // Only the compact output crosses the bus (positions N x 3, render normals R x 3); the
  // per-corner normals are gathered on the host, straight into the caller's buffer.
  float* hp = static_cast<float*>(m.h_out.ptr);
  float* hn = hp + 3 * N;
  CK(cudaMemcpyAsync(hp, m.fv.positions, 12 * N, cudaMemcpyDeviceToHost, m.stream));
  if (corner_normals)  // null: positions only (the device still computed the normals)
    CK(cudaMemcpyAsync(hn, m.normals, 12 * R, cudaMemcpyDeviceToHost, m.stream));
  CK(cudaEventRecord(m.events.ev[e + 1], m.stream));
  CK(cudaEventSynchronize(m.events.ev[e + 1]));
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names);
  t.emplace_back("copy_back", elapsed_ms(m.events.ev[e], m.events.ev[e + 1]));
  // Host side, split across threads: the first touch of fresh (numpy) pages dominates, and
  // page faults run in parallel.
  auto t0 = Clock::now();
  const int* rt = p.render_triangles.data();
  const int threads = default_threads();
  parallel_for((long long)(3 * N), threads, [&](long long b, long long en) {
    std::memcpy(positions + b, hp + b, 4 * (size_t)(en - b));
  });
  if (corner_normals) parallel_for((long long)(3 * T), threads, [&](long long b, long long en) {
    for (long long i = b; i < en; ++i) {
      const float* s = hn + 3 * (size_t)rt[i];
      float* d = corner_normals + 3 * i;
      d[0] = s[0];
      d[1] = s[1];
      d[2] = s[2];
    }
  });
  t.emplace_back("host_expand", std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  return t;
}

StageTimes CudaEvaluator::evaluate_compact(const float* D, float* positions, float* render_normals) {
  Impl& m = *impl_;
  const Plan& p = *plan_;
  m.stage_D(D);
  const std::vector<const char*> names = m.run_recorded();
  const size_t e = names.size();  // event e marks the end of the device stages
  const float ms = copy_to_host({{positions, m.fv.positions, 12 * (size_t)p.output_vertices},
                                 {render_normals, m.normals, render_normals ? 12 * (size_t)p.render_vertices : 0}},
                                m.stream, m.events, e, m.h_out);
  CK(cudaGetLastError());
  StageTimes t = m.times_from(names);
  t.emplace_back("copy_back", ms);
  return t;
}

AdaptiveSizes CudaEvaluator::adaptive_frame(const float* D, const AdaptiveOptions& options, const float* corner_uv,
                                           StageTimes& times) {
  Impl& m = *impl_;
  if (!(options.tolerance > 0) || !std::isfinite(options.tolerance))
    throw std::invalid_argument("tolerance: expected a positive finite distance, got " + std::to_string(options.tolerance));
  if (options.max_level < 1 || options.max_level > kMaxLevel)
    throw std::invalid_argument("max_level: expected 1.." + std::to_string(kMaxLevel) + ", got " +
                                std::to_string(options.max_level));
  if (!m.adaptive) m.adaptive.reset(new AdaptiveDevice(*plan_, m.pv));
  m.stage_D(D);
  CK(cudaMemcpyAsync(m.D, m.h_D.ptr, m.nD * sizeof(float), cudaMemcpyHostToDevice, m.stream));
  return m.adaptive->run(m.D, options, corner_uv, m.stream, times);
}

void CudaEvaluator::adaptive_copy(float* positions, float* rest_positions, int* triangles, int* face_index,
                                  int* triangle_patch, float* corner_normals, float* uvs, int* edge_segments,
                                  int* patch_level) {
  Impl& m = *impl_;
  if (!m.adaptive) throw std::logic_error("adaptive_copy before an adaptive frame");
  m.adaptive->copy(positions, rest_positions, triangles, face_index, triangle_patch, corner_normals, uvs,
                   edge_segments, patch_level, m.stream);
}

}  // namespace cuda_impl
}  // namespace sffd
