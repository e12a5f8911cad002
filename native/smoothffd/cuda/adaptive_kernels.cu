// The adaptive tessellation's kernels (adaptive_device.hpp): each calls the per-element
// function of eval/adaptive_stages.hpp (or of eval/stages.hpp) that the CPU driver calls.
// Compiled without --use_fast_math and with -fmad=false (native/CMakeLists.txt): every float
// operation rounds as the CPU's does, so the counts and the points are the CPU's.
#include <cuda_runtime.h>
#include <thrust/execution_policy.h>
#include <thrust/functional.h>
#include <thrust/reduce.h>
#include <thrust/scan.h>
#include <thrust/transform_reduce.h>

#include <chrono>
#include <cstring>
#include <string>
#include <vector>

#include "smoothffd/cuda/adaptive_device.hpp"
#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/eval/adaptive_stages.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

using namespace adapt;

constexpr int kThreads = 128;

// A device array grown on demand.
template <class T>
struct DeviceVec {
  T* p = nullptr;
  size_t n = 0;
  T* ensure(size_t count) {
    if (count == 0) count = 1;
    if (count > n) {
      if (p) cudaFree(p);
      p = nullptr;
      n = 0;
      CK(cudaMalloc(&p, count * sizeof(T)));
      n = count;
    }
    return p;
  }
  DeviceVec() = default;
  DeviceVec(const DeviceVec&) = delete;
  DeviceVec& operator=(const DeviceVec&) = delete;
  ~DeviceVec() {
    if (p) cudaFree(p);
  }
};

template <class T>
void upload(DeviceVec<T>& d, const T* h, size_t count, cudaStream_t s) {
  d.ensure(count);
  if (count) CK(cudaMemcpyAsync(d.p, h, count * sizeof(T), cudaMemcpyHostToDevice, s));
}

__global__ void k_samples(PlanView pv, const float* __restrict__ D, float* value, float* jacobian) {
  const int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s < pv.samples) sample_point(pv, D, s, value + 3 * (long long)s, jacobian + 9 * (long long)s);
}
__global__ void k_edges(PlanView pv, FrameView fv) {
  const int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e < pv.edges) adjust_edge(pv, fv, e);
}
__global__ void k_patches(PlanView pv, FrameView fv) {
  const int p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p < pv.patches) fit_patch_into(pv, fv, p, fv.patch_control + 30 * (long long)p, fv.patch_normal + 30 * (long long)p);
}
__global__ void k_levels(PlanView pv, AdaptiveView av) {
  const int p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p < pv.patches) decide_level(av, p);
}
__global__ void k_edge_counts(PlanView pv, AdaptiveView av, int* points) {
  const int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e >= pv.edges) return;
  decide_edge(pv, av, e);
  points[e] = av.segments[e] - 1;
}
__global__ void k_patterns(PlanView pv, AdaptiveView av, int* points, int* tris) {
  const int p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p >= pv.patches) return;
  decide_pattern(pv, av, p);
  const PatchShape sh = shape_of(pv, av, p);
  points[p] = (int)interior_points(sh.m);
  tris[p] = (int)triangle_count(sh);
}
__global__ void k_sub_vertices(PlanView pv, AdaptiveView av) {
  const int v = blockIdx.x * blockDim.x + threadIdx.x;
  if (v >= pv.sub_vertices) return;
  for (int r = 0; r < 3; ++r) {
    av.positions[3 * (long long)v + r] = av.value[3 * (long long)v + r];
    av.rest_positions[3 * (long long)v + r] = av.rest[3 * (long long)v + r];
  }
}
__global__ void k_emit_edges(PlanView pv, AdaptiveView av) {
  const int e = blockIdx.x * blockDim.x + threadIdx.x;
  if (e < pv.edges) emit_edge(pv, av, e);
}
__global__ void k_emit_patches(PlanView pv, AdaptiveView av) {
  const int p = blockIdx.x * blockDim.x + threadIdx.x;
  if (p < pv.patches) emit_patch(pv, av, p);
}

struct Above {
  double limit;
  __host__ __device__ int operator()(double b) const { return b > limit ? 1 : 0; }
};

}  // namespace

struct AdaptiveDevice::Impl {
  PlanView pv{};
  int S = 0, E = 0, P = 0, SV = 0, C = 0;
  // the emission's plan tables
  DeviceVec<float> rest;
  DeviceVec<int> patch_face, patch_triangle, input_triangle_corner;
  DeviceVec<double> patch_bary;
  // per frame
  DeviceVec<float> value, jacobian, edge_control, patch_control, patch_normal, corner_uv;
  DeviceVec<int> level0, segments, patch_m, min_edge, min_patch, edge_points, patch_points, patch_tris;
  DeviceVec<unsigned char> patch_uniform;
  DeviceVec<double> edge_bound, patch_bound;
  DeviceVec<long long> edge_base, patch_base, tri_base;
  DeviceVec<float> positions, rest_positions, corner_normals, uvs;
  DeviceVec<int> triangles, face_index, triangle_patch;
  AdaptiveSizes last;
  bool has_normals = false, has_uvs = false;
};

AdaptiveDevice::AdaptiveDevice(const Plan& plan, const PlanView& device_view) : impl_(new Impl) {
  Impl& m = *impl_;
  m.pv = device_view;
  m.S = plan.samples;
  m.E = plan.edges;
  m.P = plan.patches;
  m.SV = plan.sub_vertices;
  m.C = plan.input_corners;
  upload(m.rest, plan.rest_positions.data(), 3 * (size_t)m.SV, nullptr);
  upload(m.patch_face, plan.patch_face.data(), plan.patch_face.size(), nullptr);
  upload(m.patch_triangle, plan.patch_triangle.data(), plan.patch_triangle.size(), nullptr);
  upload(m.input_triangle_corner, plan.input_triangle_corner.data(), plan.input_triangle_corner.size(), nullptr);
  upload(m.patch_bary, plan.patch_bary.data(), plan.patch_bary.size(), nullptr);
  CK(cudaDeviceSynchronize());
}

AdaptiveDevice::~AdaptiveDevice() = default;

AdaptiveSizes AdaptiveDevice::run(const float* D, const AdaptiveOptions& o, const float* corner_uv, cudaStream_t s,
                                  StageTimes& times) {
  using Clock = std::chrono::steady_clock;
  Impl& m = *impl_;
  const int S = m.S, E = m.E, P = m.P;
  const PlanView& pv = m.pv;
  auto t0 = Clock::now();
  auto stage = [&](const char* name) {
    CK(cudaStreamSynchronize(s));
    times.emplace_back(name, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    t0 = Clock::now();
  };
  // 1. Reference patches.
  FrameView fv{};
  fv.sample_value = m.value.ensure(3 * (size_t)S);
  fv.sample_jacobian = m.jacobian.ensure(9 * (size_t)S);
  fv.edge_control = m.edge_control.ensure(6 * (size_t)E);
  fv.patch_control = m.patch_control.ensure(30 * (size_t)P);
  fv.patch_normal = m.patch_normal.ensure(30 * (size_t)P);
  if (S) k_samples<<<blocks_for(S, kThreads), kThreads, 0, s>>>(pv, D, fv.sample_value, fv.sample_jacobian);
  CK_LAUNCH("k_samples");
  if (E) k_edges<<<blocks_for(E, kThreads), kThreads, 0, s>>>(pv, fv);
  CK_LAUNCH("k_edges");
  if (P) k_patches<<<blocks_for(P, kThreads), kThreads, 0, s>>>(pv, fv);
  CK_LAUNCH("k_patches");
  stage("reference patches");
  // 2.-3. Decisions (count).
  AdaptiveView av{};
  av.value = fv.sample_value;
  av.edge_control = fv.edge_control;
  av.patch_control = fv.patch_control;
  av.patch_normal = fv.patch_normal;
  av.level0 = m.level0.ensure(P);
  av.segments = m.segments.ensure(E);
  av.patch_m = m.patch_m.ensure(P);
  av.patch_uniform = m.patch_uniform.ensure(P);
  av.edge_bound = m.edge_bound.ensure(E);
  av.patch_bound = m.patch_bound.ensure(P);
  av.tolerance = o.tolerance;
  av.max_level = o.max_level;
  if (o.min_edge_segments) {
    upload(m.min_edge, o.min_edge_segments, E, s);
    upload(m.min_patch, o.min_patch_level, P, s);
    av.min_edge_segments = m.min_edge.p;
    av.min_patch_level = m.min_patch.p;
  }
  int* edge_points = m.edge_points.ensure(E);
  int* patch_points = m.patch_points.ensure(P);
  int* patch_tris = m.patch_tris.ensure(P);
  if (P) k_levels<<<blocks_for(P, kThreads), kThreads, 0, s>>>(pv, av);
  CK_LAUNCH("k_levels");
  if (E) k_edge_counts<<<blocks_for(E, kThreads), kThreads, 0, s>>>(pv, av, edge_points);
  CK_LAUNCH("k_edge_counts");
  if (P) k_patterns<<<blocks_for(P, kThreads), kThreads, 0, s>>>(pv, av, patch_points, patch_tris);
  CK_LAUNCH("k_patterns");
  stage("decisions");
  // 4. Offsets (scan).
  auto policy = thrust::cuda::par.on(s);
  long long* edge_base = m.edge_base.ensure(E + 1);
  long long* patch_base = m.patch_base.ensure(P + 1);
  long long* tri_base = m.tri_base.ensure(P + 1);
  AdaptiveSizes z;
  long long edge_total = 0, point_total = 0;
  if (E) {
    thrust::exclusive_scan(policy, edge_points, edge_points + E, edge_base, (long long)m.SV);
    long long last_base = 0;
    int last_points = 0;
    CK(cudaMemcpyAsync(&last_base, edge_base + E - 1, sizeof(long long), cudaMemcpyDeviceToHost, s));
    CK(cudaMemcpyAsync(&last_points, edge_points + E - 1, sizeof(int), cudaMemcpyDeviceToHost, s));
    CK(cudaStreamSynchronize(s));
    edge_total = last_base + last_points;
  } else {
    edge_total = m.SV;
  }
  if (P) {
    thrust::exclusive_scan(policy, patch_points, patch_points + P, patch_base, edge_total);
    thrust::exclusive_scan(policy, patch_tris, patch_tris + P, tri_base, 0LL);
    long long lb = 0, lt = 0;
    int lp = 0, ltr = 0;
    CK(cudaMemcpyAsync(&lb, patch_base + P - 1, sizeof(long long), cudaMemcpyDeviceToHost, s));
    CK(cudaMemcpyAsync(&lp, patch_points + P - 1, sizeof(int), cudaMemcpyDeviceToHost, s));
    CK(cudaMemcpyAsync(&lt, tri_base + P - 1, sizeof(long long), cudaMemcpyDeviceToHost, s));
    CK(cudaMemcpyAsync(&ltr, patch_tris + P - 1, sizeof(int), cudaMemcpyDeviceToHost, s));
    CK(cudaStreamSynchronize(s));
    point_total = lb + lp;
    z.triangles = lt + ltr;
  } else {
    point_total = edge_total;
  }
  z.vertices = point_total;
  if (E) {
    z.max_bound = thrust::reduce(policy, av.edge_bound, av.edge_bound + E, 0.0, thrust::maximum<double>());
    z.capped += thrust::transform_reduce(policy, av.edge_bound, av.edge_bound + E, Above{kEdgeShare * o.tolerance}, 0LL,
                                         thrust::plus<long long>());
  }
  if (P) {
    z.max_bound = fmax(z.max_bound, thrust::reduce(policy, av.patch_bound, av.patch_bound + P, 0.0,
                                                   thrust::maximum<double>()));
    z.capped += thrust::transform_reduce(policy, av.patch_bound, av.patch_bound + P, Above{o.tolerance}, 0LL,
                                         thrust::plus<long long>());
  }
  if (z.vertices > 2000000000LL || 3 * z.triangles > 2000000000LL)
    throw std::invalid_argument("tolerance: output too large (" + std::to_string(z.triangles) + " triangles)");
  stage("offsets");
  // 5. Emit.
  const long long N = z.vertices, T = z.triangles;
  av.edge_base = edge_base;
  av.patch_base = patch_base;
  av.tri_base = tri_base;
  av.positions = m.positions.ensure(3 * (size_t)N);
  av.rest_positions = m.rest_positions.ensure(3 * (size_t)N);
  av.triangles = m.triangles.ensure(3 * (size_t)T);
  av.face_index = m.face_index.ensure(T);
  av.triangle_patch = m.triangle_patch.ensure(T);
  av.corner_normals = o.normals ? m.corner_normals.ensure(9 * (size_t)T) : nullptr;
  m.has_normals = o.normals;
  m.has_uvs = corner_uv != nullptr;
  if (corner_uv) {
    upload(m.corner_uv, corner_uv, 2 * (size_t)m.C, s);
    av.corner_uv = m.corner_uv.p;
    av.uvs = m.uvs.ensure(6 * (size_t)T);
  }
  av.rest = m.rest.p;
  av.patch_face = m.patch_face.p;
  av.patch_triangle = m.patch_triangle.p;
  av.patch_bary = m.patch_bary.p;
  av.input_triangle_corner = m.input_triangle_corner.p;
  if (m.SV) k_sub_vertices<<<blocks_for(m.SV, kThreads), kThreads, 0, s>>>(pv, av);
  CK_LAUNCH("k_sub_vertices");
  if (E) k_emit_edges<<<blocks_for(E, kThreads), kThreads, 0, s>>>(pv, av);
  CK_LAUNCH("k_emit_edges");
  if (P) k_emit_patches<<<blocks_for(P, 64), 64, 0, s>>>(pv, av);
  CK_LAUNCH("k_emit_patches");
  stage("emit");
  m.last = z;
  return z;
}

void AdaptiveDevice::copy(float* positions, float* rest_positions, int* triangles, int* face_index,
                          int* triangle_patch, float* corner_normals, float* uvs, int* edge_segments,
                          int* patch_level, cudaStream_t s) {
  Impl& m = *impl_;
  const size_t N = m.last.vertices, T = m.last.triangles;
  auto get = [&](void* dst, const void* src, size_t bytes) {
    if (dst && bytes) CK(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, s));
  };
  get(positions, m.positions.p, 12 * N);
  get(rest_positions, m.rest_positions.p, 12 * N);
  get(triangles, m.triangles.p, 12 * T);
  get(face_index, m.face_index.p, 4 * T);
  get(triangle_patch, m.triangle_patch.p, 4 * T);
  if (m.has_normals) get(corner_normals, m.corner_normals.p, 36 * T);
  if (m.has_uvs) get(uvs, m.uvs.p, 24 * T);
  get(edge_segments, m.segments.p, 4 * (size_t)m.E);
  get(patch_level, m.patch_m.p, 4 * (size_t)m.P);
  CK(cudaStreamSynchronize(s));
}

}  // namespace cuda_impl
}  // namespace sffd
