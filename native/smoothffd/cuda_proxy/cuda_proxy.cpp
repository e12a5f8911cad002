// _core's side of the CUDA boundary (cuda_proxy.hpp, cuda/cuda_api.h): finds, loads and
// checks libsmoothffd_cuda.so, and turns its error codes back into exceptions. Compiled into
// the module with the host compiler; needs no CUDA header or library.
#include "smoothffd/cuda_proxy/cuda_proxy.hpp"

#include "smoothffd/core/platform.hpp"

#include <stdexcept>

namespace sffd {

namespace {

uint64_t plan_tail() {
  static const Plan p;
  return (uint64_t)(reinterpret_cast<const char*>(&p.build_ms) - reinterpret_cast<const char*>(&p));
}

struct Loaded {
  const sffd_cuda_api* api = nullptr;
  std::string why;  // when api is null
};

Loaded load() {
  Loaded l;
  const std::string path = cuda_library_path();
  if (path.empty()) {
    l.why = "the CUDA backend could not be looked for: the system names no file for the smoothffd module";
    return l;
  }
  if (!platform::file_exists(path)) {
    l.why = "the CUDA backend is not installed: " + path +
            " does not exist (this smoothffd was built without CUDA, or the library was not shipped)";
    return l;
  }
  std::string why;
  void* h = platform::open_library(path, &why);
  if (!h) {
    l.why = "the CUDA backend " + path + " failed to load: " + why;
    return l;
  }
  // Kept loaded for the life of the process (it holds the CUDA runtime's state).
  auto entry = reinterpret_cast<sffd_cuda_entry_fn>(platform::library_symbol(h, SFFD_CUDA_ENTRY));
  if (!entry) {
    l.why = path + " is not a smoothffd CUDA backend: it has no " SFFD_CUDA_ENTRY;
    return l;
  }
  const sffd_cuda_api* api = entry();
  if (!api || api->abi_version != SFFD_CUDA_ABI_VERSION || api->api_size < sizeof(sffd_cuda_api) ||
      api->plan_size != sizeof(Plan) || api->plan_tail != plan_tail()) {
    l.why = path + " was built from other smoothffd sources: " +
            (api ? "ABI version " + std::to_string(api->abi_version) + ", Plan of " + std::to_string(api->plan_size) +
                       " bytes"
                 : std::string("no API table")) +
            "; this module expects ABI version " + std::to_string(SFFD_CUDA_ABI_VERSION) + ", Plan of " +
            std::to_string(sizeof(Plan)) + " bytes (rebuild both together)";
    return l;
  }
  l.api = api;
  return l;
}

const Loaded& loaded() {
  static const Loaded l = load();
  return l;
}

const sffd_cuda_api* api_or_throw() {
  const Loaded& l = loaded();
  if (!l.api) throw CudaError("no usable CUDA backend: " + l.why);
  return l.api;
}

void check(int rc, const sffd_cuda_error& err) {
  if (rc == SFFD_CUDA_OK) return;
  std::string msg = err.message;
  switch (rc) {
    case SFFD_CUDA_OUT_OF_MEMORY: throw CudaOutOfMemory(msg);
    case SFFD_CUDA_INVALID_ARGUMENT: throw std::invalid_argument(msg);
    case SFFD_CUDA_INTERNAL: throw std::logic_error(msg);
    default: throw CudaError(msg.empty() ? "CUDA backend error" : msg);
  }
}

StageTimes to_times(const sffd_cuda_times& t) {
  StageTimes out;
  for (int i = 0; i < t.count && i < SFFD_CUDA_MAX_STAGES; ++i) out.emplace_back(t.name[i], t.ms[i]);
  return out;
}

}  // namespace

std::string cuda_library_path() {
  static const std::string path = [] {
    // The folder of this module's own file (the function's address names it).
    const std::string dir = platform::directory_of(reinterpret_cast<const void*>(&cuda_library_path));
    return dir.empty() ? std::string() : platform::path_join(dir, platform::library_file_name("smoothffd_cuda"));
  }();
  return path;
}

bool cuda_library_present() {
  const std::string p = cuda_library_path();
  return !p.empty() && platform::file_exists(p);
}

std::pair<bool, std::string> cuda_status() {
  const Loaded& l = loaded();
  if (!l.api) return {false, l.why};
  char msg[2048] = {0};
  const int ok = l.api->cuda_status(msg, sizeof(msg));
  return {ok != 0, std::string(msg)};
}

void* cuda_host_alloc(size_t bytes) {
  const sffd_cuda_api* api = api_or_throw();
  sffd_cuda_error err{};
  void* p = nullptr;
  check(api->host_alloc(bytes, &p, &err), err);
  return p;
}

void cuda_host_free(void* ptr) {
  if (ptr) api_or_throw()->host_free(ptr);
}

// ---------------------------------------------------------------- CudaEvaluator

CudaEvaluator::CudaEvaluator(std::shared_ptr<const Plan> plan, const std::string& path, int64_t shared_memory_limit)
    : plan_(std::move(plan)), api_(api_or_throw()) {
  sffd_cuda_error err{};
  check(api_->evaluator_create(plan_.get(), path.c_str(), shared_memory_limit, &handle_, &err), err);
}

CudaEvaluator::~CudaEvaluator() {
  if (handle_) api_->evaluator_destroy(handle_);
}

// As the CPU evaluator counts a whole frame, from its start.
void CudaEvaluator::count_whole_frame() {
  const Plan& p = *plan_;
  last_counts_.changed_points = (long long)p.dims[0] * p.dims[1] * p.dims[2];
  last_counts_.patches = p.patches;
}

StageTimes CudaEvaluator::evaluate(const float* D, float* positions, float* corner_normals, Frame) {
  count_whole_frame();
  sffd_cuda_error err{};
  sffd_cuda_times t{};
  check(api_->evaluate(handle_, D, positions, corner_normals, &t, &err), err);
  return to_times(t);
}

StageTimes CudaEvaluator::evaluate_compact(const float* D, float* positions, float* render_normals, Frame) {
  count_whole_frame();
  sffd_cuda_error err{};
  sffd_cuda_times t{};
  check(api_->evaluate_compact(handle_, D, positions, render_normals, &t, &err), err);
  return to_times(t);
}

AdaptiveMesh CudaEvaluator::adaptive_frame(const float* D, const float* corner_uv, const AdaptiveOptions& o) {
  if (o.details) throw std::invalid_argument("adaptive_frame: details are a CPU test hook");
  if ((o.min_edge_segments == nullptr) != (o.min_patch_level == nullptr))
    throw std::invalid_argument("hold: expected both edge_segments and patch_level");
  const Plan& p = *plan_;
  sffd_cuda_error err{};
  sffd_cuda_times t{};
  int64_t N = 0, T = 0, capped = 0;
  double max_bound = 0;
  check(api_->adaptive_frame(handle_, D, o.tolerance, o.max_level, o.min_edge_segments, o.min_patch_level, corner_uv,
                             o.normals ? 1 : 0, &N, &T, &max_bound, &capped, &t, &err),
        err);
  AdaptiveMesh a;
  a.max_bound = max_bound;
  a.capped = capped;
  a.times = to_times(t);
  a.edge_segments.resize(p.edges);
  a.patch_level.resize(p.patches);
  if (!o.counts_only) a.allocate(N, T, o, corner_uv != nullptr);
  auto ptr = [](auto& v) { return v.empty() ? nullptr : v.data(); };
  check(api_->adaptive_copy(handle_, ptr(a.positions), ptr(a.rest_positions), ptr(a.triangles), ptr(a.face_index),
                            ptr(a.triangle_patch), ptr(a.corner_normals), ptr(a.uvs), a.edge_segments.data(),
                            a.patch_level.data(), &err),
        err);
  if (!o.counts_only) a.sharp_edges = adaptive_sharp_edges(p, a.edge_segments.data());
  return a;
}

StageTimes CudaEvaluator::evaluate_positions(const float* D, float* positions, Frame frame) {
  return evaluate(D, positions, nullptr, frame);
}

StageTimes CudaEvaluator::evaluate_device(const float* D) {
  sffd_cuda_error err{};
  sffd_cuda_times t{};
  check(api_->evaluate_device(handle_, D, &t, &err), err);
  return to_times(t);
}

std::string CudaEvaluator::path() const { return api_->path(handle_); }

size_t CudaEvaluator::output_bytes() const { return (size_t)api_->output_bytes(handle_); }
size_t CudaEvaluator::device_bytes() const { return (size_t)api_->device_bytes(handle_); }
std::string CudaEvaluator::kernel() const { return api_->kernel(handle_); }

sffd_cuda_limits CudaEvaluator::limits() const {
  sffd_cuda_limits l{};
  api_->limits(handle_, &l);
  return l;
}

void CudaEvaluator::testing_poison() {
  sffd_cuda_error err{};
  check(api_->testing_poison(handle_, &err), err);
}

}  // namespace sffd
