// Static-chunked parallel loop over [0, n) with plain std::threads.
//
// Every element is computed independently from the same inputs, so results are bitwise
// identical for any thread count (tests/test_deform_basics.py), and for any number of threads
// the system actually grants: a refused thread's chunk runs in the calling thread.
#pragma once

#include <algorithm>
#include <system_error>
#include <thread>
#include <vector>

namespace sffd {

inline int default_threads() {
  unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : (int)n;
}

template <class Fn>
void parallel_for(long long n, int threads, Fn&& fn) {
  if (n <= 0) return;
  const long long chunks = std::min<long long>(std::max(threads, 1), (n + 1023) / 1024);
  auto chunk = [&](long long c) { fn(n * c / chunks, n * (c + 1) / chunks); };
  if (chunks <= 1) {
    fn(0LL, n);
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
