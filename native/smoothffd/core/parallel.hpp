// Static-chunked parallel loop over [0, n), its chunks run by a pool of persistent worker
// threads (std::threads started once and kept, asleep between frames).
//
// Every element is computed independently from the same inputs, so results are bitwise
// identical for any thread count (tests/test_deform_basics.py), for any number of threads
// the system actually grants, and whichever thread runs a chunk: a refused thread's chunk runs
// in the calling thread.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <system_error>
#include <thread>
#include <vector>
#if defined(__unix__) || defined(__APPLE__)
#include <unistd.h>
#endif

#include "smoothffd/core/cancel.hpp"

namespace sffd {

inline int default_threads() {
  unsigned n = std::thread::hardware_concurrency();
  return n == 0 ? 1 : (int)n;
}

namespace detail {

// The workers parallel_for hands its chunks to. A frame runs several short stages (about a
// millisecond each at the add-on's sizes), and starting a std::thread for each cost about 35 us
// on the development machine, the late start of its chunk included; the workers instead spin
// for a short while after a job (the next stage follows within microseconds) and then sleep.
// One job at a time: a second caller (another thread, a nested loop) or a forked child, whose
// copy has no workers, gets false from run() and starts threads of its own as before.
class WorkerPool {
 public:
  static WorkerPool& instance() {
    static WorkerPool* pool = new WorkerPool();  // never destroyed: workers sleep at exit
    return *pool;
  }

  // Runs task(c) for every c in [0, n), in the calling thread and in up to n - 1 workers, and
  // returns when all are done, rethrowing the first exception of a task; false (nothing run)
  // when the pool is busy or belongs to another process.
  bool run(long long n, const std::function<void(long long)>& task) {
    bool expected = false;
    if (!busy_.compare_exchange_strong(expected, true)) return false;
    struct Release {
      std::atomic<bool>& busy;
      ~Release() { busy.store(false); }
    } release{busy_};
#if defined(__unix__) || defined(__APPLE__)
    if (getpid() != pid_) return false;
#endif
    add_workers(n - 1);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      task_ = &task;
      n_ = n;
      next_.store(0);
      done_.store(0);
      error_ = nullptr;
      generation_.store(generation_.load() + 1);
    }
    wake_.notify_all();
    work(task, n);
    spin_while([&] { return done_.load() < n; }, std::chrono::microseconds(200));
    std::unique_lock<std::mutex> lock(mutex_);
    wait(finished_, lock, [&] { return done_.load() == n && active_ == 0; });
    task_ = nullptr;
    if (error_) std::rethrow_exception(error_);
    return true;
  }

  // The workers started so far (tests).
  int workers() const { return workers_; }

 private:
  WorkerPool() {
#if defined(__unix__) || defined(__APPLE__)
    pid_ = getpid();
#endif
  }

  // Busy-waits while pending() holds, for at most `limit`.
  template <class Pending>
  static void spin_while(const Pending& pending, std::chrono::microseconds limit) {
    const auto end = std::chrono::steady_clock::now() + limit;
    for (int i = 1; pending(); ++i) {
#if defined(__x86_64__) || defined(__i386__)
      __builtin_ia32_pause();
#elif defined(__aarch64__)
      __asm__ __volatile__("yield");
#endif
      if (i % 64 == 0 && std::chrono::steady_clock::now() > end) return;
    }
  }

  // Sleeps until ready(). What ready() reads changes under the mutex (or, done_, before a
  // change under it) and is then notified, so no wake-up is lost. A plain wait: no clock is
  // read (a timed wait would need glibc 2.30's pthread_cond_clockwait, newer than the
  // libraries' glibc 2.28).
  template <class Ready>
  static void wait(std::condition_variable& cv, std::unique_lock<std::mutex>& lock, const Ready& ready) {
    cv.wait(lock, ready);
  }

  // Takes chunks until none is left.
  void work(const std::function<void(long long)>& task, long long n) {
    for (long long c; (c = next_.fetch_add(1)) < n;) {
      try {
        task(c);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!error_) error_ = std::current_exception();
      }
      done_.fetch_add(1);
    }
  }

  void add_workers(long long want) {
    while ((long long)workers_ < want) {
      try {
        std::thread(&WorkerPool::loop, this).detach();
      } catch (const std::system_error&) {
        return;  // refused: the calling thread takes the chunks no worker takes
      }
      ++workers_;
    }
  }

  void loop() {
    uint64_t seen = generation_.load();
    for (;;) {
      spin_while([&] { return generation_.load() == seen; }, std::chrono::microseconds(100));
      const std::function<void(long long)>* task;
      long long n;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wait(wake_, lock, [&] { return generation_.load() != seen; });
        seen = generation_.load();
        if (!task_) continue;  // woke after that job had ended
        task = task_;
        n = n_;
        ++active_;
      }
      work(*task, n);
      std::lock_guard<std::mutex> lock(mutex_);
      if (--active_ == 0) finished_.notify_all();
    }
  }

  std::atomic<bool> busy_{false};
  std::mutex mutex_;
  std::condition_variable wake_, finished_;
  std::atomic<uint64_t> generation_{0};
  const std::function<void(long long)>* task_ = nullptr;  // the job, while one runs
  long long n_ = 0;
  std::atomic<long long> next_{0}, done_{0};
  int active_ = 0;  // workers inside the job
  std::exception_ptr error_;
  int workers_ = 0;
#if defined(__unix__) || defined(__APPLE__)
  pid_t pid_ = 0;
#endif
};

}  // namespace detail

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
  if (detail::WorkerPool::instance().run(chunks, chunk)) return;
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
