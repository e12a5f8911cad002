// The evaluators' copy back (host_copy.hpp).
#include "smoothffd/cuda/host_copy.hpp"

#include <atomic>
#include <cstring>
#include <system_error>
#include <thread>

#include "smoothffd/core/parallel.hpp"

namespace sffd {
namespace cuda_impl {

float copy_to_host(const std::vector<HostCopy>& segs, cudaStream_t stream, Events& events, size_t from,
                   PinnedBuffer& staging) {
  constexpr size_t kChunk = size_t(1) << 20;
  struct Chunk {
    char* dst;
    const char* src;
    char* stage;
    size_t bytes;
  };
  std::vector<Chunk> chunks;
  size_t staged = 0;
  std::vector<bool> direct(segs.size(), false);
  for (size_t i = 0; i < segs.size(); ++i) {
    if (!segs[i].bytes) continue;
    cudaPointerAttributes attr{};
    direct[i] = cudaPointerGetAttributes(&attr, segs[i].dst) == cudaSuccess && attr.type == cudaMemoryTypeHost;
    (void)cudaGetLastError();  // some drivers report unregistered host memory as an error
    if (!direct[i]) staged += segs[i].bytes;
  }
  if (staged) staging.ensure(staged);
  size_t at = 0;
  for (size_t i = 0; i < segs.size(); ++i) {
    if (!segs[i].bytes) continue;
    if (direct[i]) {
      CK(cudaMemcpyAsync(segs[i].dst, segs[i].src, segs[i].bytes, cudaMemcpyDeviceToHost, stream));
      continue;
    }
    for (size_t off = 0; off < segs[i].bytes; off += kChunk) {
      const size_t n = std::min(kChunk, segs[i].bytes - off);
      chunks.push_back({static_cast<char*>(segs[i].dst) + off, static_cast<const char*>(segs[i].src) + off,
                        static_cast<char*>(staging.ptr) + at, n});
      at += n;
    }
  }
  events.ensure(from + 2 + chunks.size());
  for (size_t c = 0; c < chunks.size(); ++c) {
    CK(cudaMemcpyAsync(chunks[c].stage, chunks[c].src, chunks[c].bytes, cudaMemcpyDeviceToHost, stream));
    CK(cudaEventRecord(events.ev[from + 2 + c], stream));
  }
  CK(cudaEventRecord(events.ev[from + 1], stream));
  // Chunk c to worker c % workers: each chunk is copied on as soon as it has arrived.
  const size_t workers = std::min<size_t>(chunks.size(), (size_t)std::min(default_threads(), 16));
  std::atomic<int> failed{0};
  auto work = [&](size_t w) {
    for (size_t c = w; c < chunks.size(); c += workers) {
      if (failed.load() || cudaEventSynchronize(events.ev[from + 2 + c]) != cudaSuccess) {
        failed = 1;
        return;
      }
      std::memcpy(chunks[c].dst, chunks[c].stage, chunks[c].bytes);
    }
  };
  {
    struct Pool {
      std::vector<std::thread> threads;
      ~Pool() {
        for (auto& t : threads) t.join();
      }
    } pool;
    size_t started = 1;
    try {
      for (; started < workers; ++started) pool.threads.emplace_back(work, started);
    } catch (const std::system_error&) {  // no thread granted: this thread does their share
    }
    if (workers) work(0);
    for (size_t w = started; w < workers; ++w) work(w);
  }
  CK(cudaEventSynchronize(events.ev[from + 1]));
  if (failed) throw CudaError("copy back: a transfer failed");
  float ms = 0;
  CK(cudaEventElapsedTime(&ms, events.ev[from], events.ev[from + 1]));
  return ms;
}


}  // namespace cuda_impl
}  // namespace sffd
