// The timing harness of bench_native.hpp: CUDA events, a holding kernel and CUDA graphs
// around the evaluator's frames (CudaEvaluator::enqueue_frame on its stream).
#include <cuda_runtime.h>

#include <algorithm>
#include <vector>

#include "bench_native.hpp"
#include "smoothffd/cuda/device_memory.hpp"

namespace sffd {
namespace bench {

using cuda_impl::Events;
using cuda_impl::elapsed_ms;
using cuda_impl::median;

namespace {

// Holds its stream for ns nanoseconds of the device's global timer (the frame behind it is
// queued in full before the device reaches it).
__global__ void k_hold(long long ns) {
  long long t0, t;
  asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t0));
  do {
    asm volatile("mov.u64 %0, %%globaltimer;" : "=l"(t));
  } while (t - t0 < ns);
}

}  // namespace

StageTimes benchmark(cuda_impl::CudaEvaluator& ev, const float* D, int iters) {
  iters = std::max(iters, 3);
  cudaStream_t stream = static_cast<cudaStream_t>(ev.stream());
  Events events;
  events.ensure(32);
  std::vector<const char*> names;
  // One frame; with events recorded before each stage and after the last when `record`.
  auto frame = [&](bool record) {
    names.clear();
    size_t e = 0;
    ev.enqueue_frame(D, [&](const char* name) {
      if (!record) return;
      if (name) names.push_back(name);
      events.ensure(e + 1);
      CK(cudaEventRecord(events.ev[e++], stream));
    });
  };
  for (int i = 0; i < 5; ++i) frame(false);
  CK(cudaStreamSynchronize(stream));
  // Per-stage events, one frame at a time.
  std::vector<std::vector<double>> per;
  std::vector<double> totals;
  for (int it = 0; it < iters; ++it) {
    frame(true);
    CK(cudaEventSynchronize(events.ev[names.size()]));
    if (per.empty()) per.resize(names.size());
    for (size_t i = 0; i < names.size(); ++i) per[i].push_back(elapsed_ms(events.ev[i], events.ev[i + 1]));
    totals.push_back(elapsed_ms(events.ev[0], events.ev[names.size()]));
  }
  StageTimes t;
  const std::vector<const char*> stages = names;
  for (size_t i = 0; i < stages.size(); ++i) t.emplace_back(stages[i], median(per[i]));
  t.emplace_back("total_events", median(totals));

  // The same frames with the device time alone between the events: each frame queued behind
  // a kernel that holds the stream for 50 us, so that its first event and its launches are
  // already waiting when the device reaches them. Above, the host enqueues the event and then
  // the launch while the device idles: the events time the launch's host latency too (about
  // 5 us a frame on the H100 machine).
  {
    std::vector<double> queued;
    for (int it = 0; it < iters; ++it) {
      k_hold<<<1, 1, 0, stream>>>(50000);
      CK_LAUNCH(k_hold);
      frame(true);
      CK(cudaEventSynchronize(events.ev[names.size()]));
      queued.push_back(elapsed_ms(events.ev[0], events.ev[names.size()]));
    }
    t.emplace_back("total_events_queued", median(queued));
  }

  // The whole frame (D upload + stages) as a CUDA graph, replayed back to back.
  cudaGraph_t graph = nullptr;
  cudaGraphExec_t exec = nullptr;
  CK(cudaStreamBeginCapture(stream, cudaStreamCaptureModeThreadLocal));
  try {
    frame(false);
  } catch (...) {
    cudaStreamEndCapture(stream, &graph);
    if (graph) cudaGraphDestroy(graph);
    throw;
  }
  CK(cudaStreamEndCapture(stream, &graph));
  CK(cudaGraphInstantiate(&exec, graph, 0));
  for (int i = 0; i < 3; ++i) CK(cudaGraphLaunch(exec, stream));
  std::vector<double> graph_ms;
  const int reps = 10, per_rep = std::max(iters / reps, 1);
  for (int r = 0; r < reps; ++r) {
    CK(cudaEventRecord(events.ev[0], stream));
    for (int i = 0; i < per_rep; ++i) CK(cudaGraphLaunch(exec, stream));
    CK(cudaEventRecord(events.ev[1], stream));
    CK(cudaEventSynchronize(events.ev[1]));
    graph_ms.push_back(elapsed_ms(events.ev[0], events.ev[1]) / per_rep);
  }
  cudaGraphExecDestroy(exec);
  cudaGraphDestroy(graph);
  t.emplace_back("total_graph", median(graph_ms));

  // Floor: output bytes at the device-to-device copy bandwidth measured now.
  const size_t bytes = ev.output_bytes();
  void *src = nullptr, *dst = nullptr;
  CK(cudaMalloc(&src, bytes));
  cudaError_t err = cudaMalloc(&dst, bytes);
  if (err != cudaSuccess) {
    cudaFree(src);
    CK(err);
  }
  std::vector<double> copy_ms;
  for (int i = 0; i < iters + 3; ++i) {
    CK(cudaEventRecord(events.ev[0], stream));
    CK(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToDevice, stream));
    CK(cudaEventRecord(events.ev[1], stream));
    CK(cudaEventSynchronize(events.ev[1]));
    if (i >= 3) copy_ms.push_back(elapsed_ms(events.ev[0], events.ev[1]));
  }
  cudaFree(src);
  cudaFree(dst);
  const double cms = median(copy_ms);
  const double bw = 2.0 * bytes / (cms * 1e-3);  // bytes read + written per second
  t.emplace_back("d2d_copy_ms", cms);
  t.emplace_back("d2d_bandwidth_GBps", bw * 1e-9);
  t.emplace_back("floor_ms", bytes / bw * 1e3);
  t.emplace_back("output_bytes", (double)bytes);
  CK(cudaGetLastError());
  return t;
}

}  // namespace bench
}  // namespace sffd
