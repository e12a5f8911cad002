// The paper's uniform upsampling baseline (bench_native.hpp): one thread a point,
// sample_point_fixed with the plan's term count at compile time (as the CUDA evaluator's own
// sampling) and the cofactor normal of eval/stages.hpp.
#include <cuda_runtime.h>

#include <stdexcept>

#include "bench_native.hpp"
#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {
namespace bench {

using namespace cuda_impl;

namespace {

// C terms an axis (kernel_terms of the plan's largest count): the generic sample_point's
// run-time loop over kMaxTerms took 1.76x as long on W1 (H100, 2026-11-24).
template <int C>
__global__ void __launch_bounds__(256) k_baseline(PlanView pv, const float* __restrict__ D,
                                                  const float* __restrict__ rest_normal, float* __restrict__ pos,
                                                  float* __restrict__ nrm) {
  int s = blockIdx.x * blockDim.x + threadIdx.x;
  if (s >= pv.samples) return;
  float F[3], J[9];
  sample_point_fixed<C>(pv, D, s, F, J);
  V3 n0 = load3(rest_normal + 3 * (long long)s);
  store3(pos + 3 * (long long)s, load3(F));
  store3(nrm + 3 * (long long)s, normalized_or(cofactor_apply(J, n0), n0));
}

}  // namespace

struct UpsamplingBaseline::Impl {
  DeviceArena arena;
  PlanView pv{};
  float *D = nullptr, *rest_normal = nullptr, *pos = nullptr, *nrm = nullptr;
  size_t nD = 0;
  int terms = kMaxTerms;
  cudaStream_t stream = nullptr;
  Events events;
  ~Impl() {
    if (stream) cudaStreamDestroy(stream);
  }
  void launch() {
    if (pv.samples == 0) return;
    const unsigned grid = blocks_for(pv.samples, 256);
    switch (terms) {
      case 2: k_baseline<2><<<grid, 256, 0, stream>>>(pv, D, rest_normal, pos, nrm); break;
      case 3: k_baseline<3><<<grid, 256, 0, stream>>>(pv, D, rest_normal, pos, nrm); break;
      case 4: k_baseline<4><<<grid, 256, 0, stream>>>(pv, D, rest_normal, pos, nrm); break;
      case 5: k_baseline<5><<<grid, 256, 0, stream>>>(pv, D, rest_normal, pos, nrm); break;
      default: k_baseline<kMaxTerms><<<grid, 256, 0, stream>>>(pv, D, rest_normal, pos, nrm); break;
    }
    CK_LAUNCH(k_baseline);
  }
};

UpsamplingBaseline::UpsamplingBaseline(std::shared_ptr<const Plan> plan, const std::vector<float>& points,
                                       const std::vector<float>& normals, const std::vector<uint32_t>& pieces)
    : plan_(std::move(plan)), impl_(new Impl) {
  init_device();
  const Plan& p = *plan_;
  const size_t M = pieces.size();
  if (points.size() != 3 * M || normals.size() != 3 * M)
    throw std::invalid_argument("baseline: points, normals (M x 3) and pieces (M) disagree");
  int axis_count[3];
  for (int a = 0; a < 3; ++a) axis_count[a] = (a < 2 ? p.axis_offset[a + 1] : (int)p.pieces.size()) - p.axis_offset[a];
  for (uint32_t pk : pieces)
    for (int a = 0; a < 3; ++a)
      if ((int)((pk >> (10 * a)) & 1023u) >= axis_count[a]) throw std::invalid_argument("baseline: piece index out of range");
  count_ = (int)M;
  Impl& m = *impl_;
  CK(cudaStreamCreateWithFlags(&m.stream, cudaStreamNonBlocking));
  m.events.ensure(4);
  PlanView& v = m.pv;
  v = PlanView{};
  v.samples = (int)M;
  for (int a = 0; a < 3; ++a) {
    v.axis_offset[a] = p.axis_offset[a];
    v.dims[a] = p.dims[a];
  }
  for (int i = 0; i < 12; ++i) v.param_map[i] = p.param_map[i];
  DeviceArena& a = m.arena;
  v.pieces = a.upload(p.pieces);
  v.sample_position = a.upload(points);
  v.sample_piece = a.upload(pieces);
  v.sample_weight = a.upload(std::vector<float>(M, 1.0f));
  m.rest_normal = a.upload(normals);
  m.nD = 3 * (size_t)p.dims[0] * p.dims[1] * p.dims[2];
  m.terms = kernel_terms(plan_max_terms(p));
  m.D = a.alloc<float>(m.nD);
  m.pos = a.alloc<float>(3 * M);
  m.nrm = a.alloc<float>(3 * M);
  CK(cudaDeviceSynchronize());
}

UpsamplingBaseline::~UpsamplingBaseline() = default;

size_t UpsamplingBaseline::control_values() const { return impl_->nD; }

void UpsamplingBaseline::evaluate(const float* D, float* positions, float* normals) {
  Impl& m = *impl_;
  CK(cudaMemcpy(m.D, D, m.nD * sizeof(float), cudaMemcpyHostToDevice));
  m.launch();
  CK(cudaStreamSynchronize(m.stream));
  CK(cudaMemcpy(positions, m.pos, 12 * (size_t)count_, cudaMemcpyDeviceToHost));
  CK(cudaMemcpy(normals, m.nrm, 12 * (size_t)count_, cudaMemcpyDeviceToHost));
}

StageTimes UpsamplingBaseline::benchmark(const float* D, int iters) {
  Impl& m = *impl_;
  iters = std::max(iters, 3);
  CK(cudaMemcpy(m.D, D, m.nD * sizeof(float), cudaMemcpyHostToDevice));
  for (int i = 0; i < 5; ++i) m.launch();
  std::vector<double> ms_all;
  for (int i = 0; i < iters; ++i) {
    CK(cudaEventRecord(m.events.ev[0], m.stream));
    m.launch();
    CK(cudaEventRecord(m.events.ev[1], m.stream));
    CK(cudaEventSynchronize(m.events.ev[1]));
    ms_all.push_back(elapsed_ms(m.events.ev[0], m.events.ev[1]));
  }
  StageTimes t;
  t.emplace_back("deform_samples", median(ms_all));
  t.emplace_back("output_bytes", (double)output_bytes());
  return t;
}

}  // namespace bench
}  // namespace sffd
