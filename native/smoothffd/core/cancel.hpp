// Cancelling long native work (a plan build, a CPU frame) from the thread that started it.
//
// The caller installs a check for its own thread (CancelScope); the core's long loops call
// poll_cancel() every few thousand elements, and parallel_for calls it before and between the
// calling thread's chunks. poll_cancel() runs the check at most once an interval and throws
// sffd::Cancelled when the check returns true. The check is per thread: threads that
// parallel_for starts never see it, and the work they share stops at the calling thread's next
// poll. Everything under way is dropped whole (a plan is built in locals and returned at the
// end; an evaluator's buffers are rewritten by every frame), so nothing half-built is left
// behind and the same objects can be used again. Without a scope, poll_cancel() is one
// thread-local load.
//
// The Python module installs a check that takes the GIL and runs Python's signal handlers:
// Ctrl-C becomes KeyboardInterrupt within an interval (native/python/bindings.cpp).
#pragma once

#include <chrono>
#include <functional>
#include <stdexcept>
#include <utility>

namespace sffd {

// What poll_cancel() throws when the installed check asks to stop.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

class CancelScope {
 public:
  using Clock = std::chrono::steady_clock;

  // Installs `check` for the calling thread until the scope ends (scopes nest: the innermost
  // one is polled). Polls run the check once `interval` has passed since the scope began or
  // since the last check: work shorter than that never runs it.
  explicit CancelScope(std::function<bool()> check,
                       Clock::duration interval = std::chrono::milliseconds(100))
      : check_(std::move(check)), interval_(interval), next_(Clock::now() + interval), outer_(current()) {
    current() = this;
  }
  ~CancelScope() { current() = outer_; }
  CancelScope(const CancelScope&) = delete;
  CancelScope& operator=(const CancelScope&) = delete;

  void poll() {
    const Clock::time_point now = Clock::now();
    if (now < next_) return;
    next_ = now + interval_;
    if (check_()) throw Cancelled();
  }

  // The calling thread's innermost scope, or null.
  static CancelScope*& current() {
    static thread_local CancelScope* scope = nullptr;
    return scope;
  }

 private:
  std::function<bool()> check_;
  Clock::duration interval_;
  Clock::time_point next_;
  CancelScope* outer_;
};

// Throws Cancelled when the calling thread's check (if any) asks to stop; rate-limited.
inline void poll_cancel() {
  if (CancelScope* s = CancelScope::current()) s->poll();
}

// poll_cancel() every `every` calls of tick(): for loops whose iterations are cheap.
class CancelPoller {
 public:
  explicit CancelPoller(unsigned every = 4096) : every_(every) {}
  void tick() {
    if (++count_ >= every_) {
      count_ = 0;
      poll_cancel();
    }
  }

 private:
  unsigned every_, count_ = 0;
};

}  // namespace sffd
