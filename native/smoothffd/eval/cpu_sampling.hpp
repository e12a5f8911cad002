// Stage 1 (sampling, sec. 5.1) on the CPU, kLanes samples at a time.
//
// Samples in the same lattice box (the same three axis pieces, Plan::sample_piece) weigh the
// same control values with the same polynomials. So kLanes of them run sample_point's
// arithmetic (sample_weights, tensor_eval_fixed, compose_deformation: the same templates) as
// vector operations, each control value loaded once and broadcast to every lane: one
// instruction does the work of kLanes scalar ones. The batches depend on the plan only and
// are built once, next to it (a counting sort by box; plan order within a box).
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {

struct SampleBatches {
  std::vector<int> order;      // sample ids grouped by box (-1: a place a sample has left)
  std::vector<int> start;      // batch b is order[start[b] .. start[b] + size[b]): one box;
                               // start[count()] = order.size()
  std::vector<uint8_t> size;   // per batch: its samples, at most kLanes (start[b + 1] - start[b]
                               // as made; fewer, or none, once repiece_sample_batches took
                               // samples out)
  std::vector<uint8_t> terms;  // per batch: terms an axis the contraction runs with (1-4, 6)
  long long appended = 0;      // batches repiece_sample_batches added
  long long count() const { return (long long)terms.size(); }
};

// only: the samples to batch, in plan order (null: all of them).
SampleBatches make_sample_batches(const Plan& plan, const std::vector<int>* only = nullptr);

// The batches of `plan` from those of all the samples of the plan it followed
// (plan.samples_base_id), which sb holds: each of plan.repieced_samples is taken out of its
// batch (the batch's last sample moves into its place) and batched again after the others,
// with the samples of its new box. A sample's value does not depend on the others in its
// batch, so a frame gives the same bits as with make_sample_batches(plan). slot: each sample's
// place in sb.order, made here when empty and kept up to date. Returns false, leaving sb and
// slot to be made anew, where the batches added since sb was made would be more than an
// eighth of those it was made with, and 64 (each further frame would pay for the half-empty
// ones).
bool repiece_sample_batches(const Plan& plan, SampleBatches& sb, std::vector<int>& slot);

SFFD_ISA_BEGIN  // one copy per ISA (core/isa.hpp)

// F (3 floats) and J (9 floats) of every sample of batch b into value + 3 s, jacobian + 9 s.
// D: pv.components values a control point.
// jacobian == nullptr: values only (the derivative sums are skipped).
void sample_batch(const PlanView& pv, const float* D, const SampleBatches& sb, long long b,
                  float* value, float* jacobian);

SFFD_ISA_END

}  // namespace sffd
