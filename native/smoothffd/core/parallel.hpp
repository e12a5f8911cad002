// Static-chunked parallel loop over [0, n) with plain std::threads.
//
// Every element is computed independently from the same inputs, so results are bitwise
// identical for any thread count (tests/test_deform_basics.py), and for any number of threads
// the system actually grants: a refused thread's chunk runs in the calling thread.
#pragma once

#include <algorithm>
#include <atomic>
#include <system_error>
#include <thread>
#include <vector>

#include "smoothffd/core/cancel.hpp"

namespace sffd {

inline int default_threads() {
  unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : (int)n;
}

// With a cancel check installed in the calling thread (core/cancel.hpp), each chunk runs in
// slices of about 1/64 of it (at least 1024 elements): the same elements in the same threads,
// the calling thread polling the check between its slices, and the other threads stopping at
// their next slice once it throws. Without one, each chunk is one call of fn, as always.
template <class Fn>
void parallel_for(long long n, int threads, Fn&& fn) {
  poll_cancel();
  if (n <= 0) return;
  const long long chunks = std::min<long long>(std::max(threads, 1), (n + 1023) / 1024);
  const bool sliced = CancelScope::current() != nullptr;
  std::atomic<bool> stop{false};
  auto chunk = [&](long long c) {
    const long long b = n * c / chunks, e = n * (c + 1) / chunks;
    if (!sliced) {
      fn(b, e);
      return;
    }
    const long long step = std::max<long long>(1024, (e - b + 63) / 64);
    for (long long s = b; s < e; s += step) {
      if (stop.load(std::memory_order_relaxed)) return;
      try {
        poll_cancel();  // a no-op in the started threads: the check is the caller's
      } catch (...) {
        stop.store(true, std::memory_order_relaxed);
        throw;
      }
      fn(s, std::min(e, s + step));
    }
  };
  if (chunks <= 1) {
    chunk(0);
    return;
  }
  // Joins whatever was started, also when this thread's share throws.
  struct Pool {
    std::vector<std::thread> threads;
    ~Pool() {
      for (auto& t : threads) t.join();
    }
  } pool;
  pool.threads.reserve(chunks - 1);
  long long started = 1;
  try {
    for (; started < chunks; ++started) pool.threads.emplace_back([&chunk, started] { chunk(started); });
  } catch (const std::system_error&) {
    // The system refused another thread (memory or process limits): the chunks no thread was
    // started for run here, so the result is the same, only later.
  }
  chunk(0);
  for (long long c = started; c < chunks; ++c) chunk(c);
}

}  // namespace sffd
