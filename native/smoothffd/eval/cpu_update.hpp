// Incremental frames of CpuEvaluator (Frame::incremental, eval/evaluator.hpp): a frame
// recomputes only the elements (sample batches, end normals, edges, patches) that read a
// control point that changed since the previous frame, and keeps the rest of the evaluator's
// buffers and of the output as they are.
//
// Every element reads the control values of a block of the lattice: a sample those of its
// box (its three axis pieces), an end normal its sample's, an edge its end and constraint
// samples', a patch its columns' samples', its edges' and its centre row's block. The tables
// here keep that block per element as an interval of control indices along each axis
// (ControlBlock: a superset where a piece's indices are not consecutive, as at Blender's
// clamped ends), built once per evaluator, on the first incremental frame. Elements share
// few distinct blocks (a lattice box, or the union of neighbouring boxes along a knot plane),
// so each element holds the number of its block in one table: a frame tests each distinct
// block once (a summed-volume table of the changed points: 8 reads, whatever moved), then
// finds each stage's changed elements by one table read each.
//
// Every element's arithmetic is the same whichever elements run beside it (the kernels are
// bitwise the same for every range and thread count), so an incremental frame's output is
// bitwise the whole frame's for the same control values (test_cpu_evaluator.cpp).
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/eval/cpu_frame.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// The control indices lo[a] .. hi[a] (inclusive) along axis a an element reads.
struct ControlBlock {
  uint16_t lo[3], hi[3];
};

// The block of every element a frame runs, in the stages' own numbering, as a number into
// `blocks`.
struct UpdateReach {
  std::vector<ControlBlock> blocks;          // the distinct blocks
  std::vector<uint32_t> batches;             // per batch of CpuEvaluator's batches_
  std::vector<uint32_t> positions_batches;   // per batch of its positions_batches_
  std::vector<uint32_t> end_normals;         // per EdgeEndNormals entry
  std::vector<uint32_t> edges;               // per edge
  std::vector<uint32_t> patches;             // per patch
  size_t bytes() const;
};

// threads: for the patches' pass (each patch's columns).
UpdateReach make_update_reach(const Plan& plan, const SampleBatches& batches,
                              const SampleBatches& positions_batches, const EdgeEndNormals& en,
                              int threads);

// The control points that differ (bitwise, any component) between two frames' values, as a
// summed-volume table: whether a block holds one is 8 reads.
class ChangedPoints {
 public:
  // D, previous: dims[0] * dims[1] * dims[2] points of `components` floats each.
  // Returns the number of changed points.
  long long compare(const int dims[3], int components, const float* D, const float* previous);
  bool any_in(const ControlBlock& b) const;

 private:
  int n1_ = 0, n2_ = 0;       // dims[1] + 1, dims[2] + 1: the table's strides
  std::vector<int> sum_;      // (dims[0] + 1) x n1_ x n2_: changed points in [0, i) x [0, j) x [0, k)
};

// The elements of [0, n) whose block holds a changed point, as runs of consecutive elements,
// so that each stage's kernel runs on ranges as in a whole frame, the threads sharing the
// elements (not the index range) evenly.
struct ChangedRuns {
  std::vector<long long> begin, end;  // run r: [begin[r], end[r])
  std::vector<long long> before;      // elements in the runs before r; before.back(): all
  long long count() const { return before.empty() ? 0 : before.back(); }
  // The runs of the elements whose block (ids: n of them, numbers into hit) is hit.
  void collect(const std::vector<uint32_t>& ids, const std::vector<uint8_t>& hit, int threads);
};

}  // namespace sffd
