// Float buffers, and the tables an evaluator derives from its plan, handed from one evaluator
// to the next of the same owner. A Deformer whose plan follows a moving input (follow_plan)
// gets a new evaluator every frame; taking the old one's buffers, whose memory is already
// mapped, spares the new one the page faults of fresh memory (at W1 level 4 tens of MB a
// frame), and taking its tables where the plan kept what they are made from spares their
// building (eval/cpu_evaluator.cpp). Thread-safe.
#pragma once

#include <algorithm>
#include <cstddef>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "smoothffd/core/parallel.hpp"

namespace sffd {

class BufferPool {
 public:
  // n floats, all 0: the smallest kept buffer that holds them, else a new one.
  std::vector<float> take(size_t n) {
    std::vector<float> v;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      auto best = kept_.end();
      for (auto it = kept_.begin(); it != kept_.end(); ++it)
        if (it->capacity() >= n && (best == kept_.end() || it->capacity() < best->capacity())) best = it;
      if (best != kept_.end()) {
        v = std::move(*best);
        kept_.erase(best);
      }
    }
    // Zeroed by the workers (tens of MB per evaluator at W1 level 4: one thread's memset was
    // a fifth of a new evaluator's time).
    v.resize(n);
    parallel_for((long long)n, default_threads(), [&](long long b, long long e) {
      std::fill(v.begin() + b, v.begin() + e, 0.0f);
    });
    return v;
  }

  // Keeps v's memory for a later take (at most kKept buffers, the largest).
  void give(std::vector<float>&& v) {
    if (v.capacity() == 0) return;
    std::lock_guard<std::mutex> lock(mutex_);
    kept_.push_back(std::move(v));
    if (kept_.size() > kKept) {
      auto smallest = std::min_element(kept_.begin(), kept_.end(), [](const std::vector<float>& a, const std::vector<float>& b) {
        return a.capacity() < b.capacity();
      });
      kept_.erase(smallest);
    }
  }

  // The tables an evaluator leaves for the next (one set at a time; the evaluator that takes
  // them checks that they were made from what its plan has, and knows their type).
  void leave_tables(std::shared_ptr<void> tables) {
    std::lock_guard<std::mutex> lock(mutex_);
    tables_ = std::move(tables);
  }
  std::shared_ptr<void> take_tables() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::move(tables_);
  }

  size_t bytes() const {
    std::lock_guard<std::mutex> lock(mutex_);
    size_t b = 0;
    for (const auto& v : kept_) b += v.capacity() * sizeof(float);
    return b;
  }

 private:
  static constexpr size_t kKept = 8;
  mutable std::mutex mutex_;
  std::vector<std::vector<float>> kept_;
  std::shared_ptr<void> tables_;
};

}  // namespace sffd
