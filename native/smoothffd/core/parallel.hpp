// Static-chunked parallel loop over [0, n) with plain std::threads.
//
// Every element is computed independently from the same inputs, so results are bitwise
// identical for any thread count (tests/test_determinism.py).
#pragma once

#include <algorithm>
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
  long long chunks = std::min<long long>(std::max(threads, 1), (n + 1023) / 1024);
  if (chunks <= 1) {
    fn(0LL, n);
    return;
  }
  std::vector<std::thread> pool;
  pool.reserve(chunks - 1);
  for (long long c = 1; c < chunks; ++c)
    pool.emplace_back([&, c] { fn(n * c / chunks, n * (c + 1) / chunks); });
  fn(0LL, n / chunks);
  for (auto& t : pool) t.join();
}

}  // namespace sffd
