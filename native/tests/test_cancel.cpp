// Unit tests of cancellation (core/cancel.hpp): a check installed in the calling thread stops
// build_plan, a CPU frame and parallel_for; nothing is left half-done (the same objects give
// the uncancelled results afterwards); without a check nothing changes.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/core/parallel.hpp"
#include "test_util.hpp"

using namespace sffd;
using namespace sffd_test;

namespace {

// Stops at the n-th check; records the threads the check ran in.
struct CountingCheck {
  int stop_at;
  int calls = 0;
  std::set<std::thread::id> threads;
  std::mutex mutex;
  bool operator()() {
    std::lock_guard<std::mutex> lock(mutex);
    threads.insert(std::this_thread::get_id());
    return ++calls >= stop_at;
  }
};

}  // namespace

TEST(Cancel, NoScopeNoCheck) {
  EXPECT_EQ(CancelScope::current(), nullptr);
  poll_cancel();  // nothing installed: returns
  int calls = 0;
  {
    CancelScope outer([&] { ++calls; return false; }, std::chrono::milliseconds(0));
    {
      CancelScope inner([] { return true; }, std::chrono::milliseconds(0));
      EXPECT_THROW(poll_cancel(), Cancelled);
    }
    poll_cancel();  // the outer scope is back
    EXPECT_EQ(calls, 1);
  }
  EXPECT_EQ(CancelScope::current(), nullptr);
}

TEST(Cancel, IntervalLimitsTheChecks) {
  int calls = 0;
  CancelScope scope([&] { ++calls; return false; }, std::chrono::hours(1));
  for (int i = 0; i < 100000; ++i) poll_cancel();
  EXPECT_EQ(calls, 0);  // the first check waits for one interval too
}

// Without a scope every chunk is one call; with one, slices of the same chunk in the same
// thread, every element exactly once; a cancel stops every thread at its next slice.
TEST(Cancel, ParallelForSlicesOnlyUnderAScope) {
  const long long n = 1 << 20;
  std::atomic<int> calls{0};
  parallel_for(n, 4, [&](long long, long long) { ++calls; });
  EXPECT_EQ(calls.load(), 4);

  std::vector<int> seen(n, 0);
  calls = 0;
  {
    CancelScope scope([] { return false; }, std::chrono::milliseconds(0));
    parallel_for(n, 4, [&](long long b, long long e) {
      ++calls;
      for (long long i = b; i < e; ++i) seen[i]++;
      EXPECT_TRUE(b / (n / 4) == (e - 1) / (n / 4)) << "a slice crosses chunks";
    });
  }
  EXPECT_EQ(calls.load(), 4 * 64);
  for (long long i = 0; i < n; ++i) ASSERT_EQ(seen[i], 1) << i;

  std::atomic<long long> done{0};
  CountingCheck check{3};
  {
    CancelScope scope(std::ref(check), std::chrono::milliseconds(0));
    EXPECT_THROW(parallel_for(n, 4, [&](long long b, long long e) {
                   done += e - b;
                   std::this_thread::sleep_for(std::chrono::microseconds(200));
                 }),
                 Cancelled);
  }
  EXPECT_LT(done.load(), n);
  EXPECT_EQ(check.threads.size(), 1u);
  EXPECT_EQ(*check.threads.begin(), std::this_thread::get_id());
}

// parallel_for's chunks run on persistent workers (core/parallel.hpp, detail::WorkerPool):
// over 40 loops of 4 chunks the threads that run chunks other than the caller are at most the
// pool's workers (a thread a loop would be 120 new threads). A loop started inside a chunk, or
// by another thread while the pool is busy, starts threads of its own; an exception of any
// chunk reaches the caller, and the pool works on.
TEST(Cancel, ParallelForKeepsItsWorkers) {
  static std::atomic<int> threads_seen{0};
  struct Seen {
    Seen() { ++threads_seen; }
  };
  const long long n = 1 << 16;
  const auto caller = std::this_thread::get_id();
  std::atomic<int> others{0};
  for (int loop = 0; loop < 40; ++loop)
    parallel_for(n, 4, [&](long long, long long) {
      // Every chunk takes a while, so the caller cannot take them all before a worker wakes.
      std::this_thread::sleep_for(std::chrono::microseconds(200));
      if (std::this_thread::get_id() == caller) return;
      static thread_local Seen seen;  // constructed once in each new thread
      (void)seen;
      ++others;
    });
  EXPECT_GT(others.load(), 0);
  EXPECT_GT(threads_seen.load(), 0);
  EXPECT_LE(threads_seen.load(), detail::WorkerPool::instance().workers());

  std::vector<std::atomic<int>> seen(n);
  auto count = [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) seen[i]++;
  };
  parallel_for(2048, 2, [&](long long, long long) { parallel_for(n, 4, count); });  // 2 chunks, 2 nested loops
  std::thread other([&] { parallel_for(n, 4, count); });
  parallel_for(n, 4, count);
  other.join();
  for (long long i = 0; i < n; ++i) ASSERT_EQ(seen[i].load(), 4) << i;

  EXPECT_THROW(parallel_for(n, 4, [&](long long b, long long) {
                 if (b > 0) throw std::runtime_error("a worker's chunk");
               }),
               std::runtime_error);
  std::atomic<long long> total{0};
  parallel_for(n, 4, [&](long long b, long long e) { total += e - b; });
  EXPECT_EQ(total.load(), n);
}

// build_plan stops at a check; the next build gives the same plan as an uncancelled one.
TEST(Cancel, BuildPlanStopsAndLeavesNothingBehind) {
  InputMesh mesh = flat_grid(40);
  LatticeSpec spec = bspline_box(3, 7);
  PlanOptions opt;
  opt.level = 6;
  Plan want = build_plan(mesh, spec, opt);
  for (int stop_at : {1, 2, 5, 20}) {
    CountingCheck check{stop_at};
    {
      CancelScope scope(std::ref(check), std::chrono::milliseconds(0));
      EXPECT_THROW(build_plan(mesh, spec, opt), Cancelled) << stop_at;
    }
    EXPECT_EQ(check.calls, stop_at);
    EXPECT_EQ(check.threads.size(), 1u);
  }
  int calls = 0;
  Plan again;
  {
    CancelScope scope([&] { ++calls; return false; }, std::chrono::milliseconds(0));
    again = build_plan(mesh, spec, opt);  // polled, never stopped
  }
  EXPECT_GT(calls, 20);
  EXPECT_EQ(again.triangles, want.triangles);
  EXPECT_EQ(again.rest_positions, want.rest_positions);
  EXPECT_EQ(again.fit_matrix, want.fit_matrix);
  EXPECT_EQ(again.patch_samples, want.patch_samples);
  EXPECT_EQ(again.render_triangles, want.render_triangles);
}

// A CPU frame stops at a check; the same evaluator then gives the uncancelled frame bitwise.
TEST(Cancel, CpuFrameStopsAndTheEvaluatorStaysUsable) {
  InputMesh mesh = flat_grid(30);
  LatticeSpec spec = bspline_box(2, 5);
  auto plan = plan_of(mesh, spec, 8);
  std::vector<float> D(3 * (size_t)spec.count());
  for (size_t i = 0; i < D.size(); ++i) D[i] = 0.01f * float(i % 7) - 0.03f;
  CpuOut want = run_cpu(plan, D, 2);
  CpuEvaluator ev(plan, 2);
  std::vector<float> pos(want.pos.size(), -1.0f), nrm(want.nrm.size(), -1.0f);
  for (int stop_at : {1, 3}) {
    CountingCheck check{stop_at};
    CancelScope scope(std::ref(check), std::chrono::milliseconds(0));
    EXPECT_THROW(ev.evaluate(D.data(), pos.data(), nrm.data(), Frame::whole), Cancelled);
  }
  ev.evaluate(D.data(), pos.data(), nrm.data(), Frame::whole);
  EXPECT_EQ(pos, want.pos);
  EXPECT_EQ(nrm, want.nrm);
  {
    CancelScope scope([] { return false; }, std::chrono::milliseconds(0));  // sliced, same bits
    std::fill(pos.begin(), pos.end(), -1.0f);
    ev.evaluate(D.data(), pos.data(), nrm.data(), Frame::whole);
  }
  EXPECT_EQ(pos, want.pos);
  EXPECT_EQ(nrm, want.nrm);
}
