#include "smoothffd/eval/cpu_sampling.hpp"

#include <algorithm>
#include <numeric>
#include <stdexcept>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/eval/lanes.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {

#if SFFD_ISA_PRIMARY  // plan-time part: the baseline copy only

namespace {

// Terms an axis the contraction of a box runs with: sample_point's dispatch on the largest
// count (tensor_eval), raised where a piece's polynomial has more powers than terms, since
// sample_weights<C> evaluates powers below C only.
int box_terms(const Plan& plan, uint32_t packed) {
  int need = 1;
  for (int a = 0; a < 3; ++a) {
    const AxisPieceF& pc = plan.pieces[plan.axis_offset[a] + ((packed >> (10 * a)) & 1023u)];
    need = std::max({need, pc.count, pc.degree + 1});
  }
  return need <= 4 ? need : kMaxTerms;
}

// Batches of sb.order[from, end), whose samples come grouped by box: each box's run cut into
// batches of at most kLanes (sb.start's closing entry is the caller's).
void cut_batches(const Plan& plan, SampleBatches& sb, int from, int end) {
  for (int i = from; i < end;) {
    const uint32_t key = plan.sample_piece[sb.order[i]];
    int j = i;
    while (j < end && j - i < kLanes && plan.sample_piece[sb.order[j]] == key) ++j;
    sb.start.push_back(i);
    sb.size.push_back((uint8_t)(j - i));
    sb.terms.push_back((uint8_t)box_terms(plan, key));
    i = j;
  }
}

}  // namespace

SampleBatches make_sample_batches(const Plan& plan, const std::vector<int>* only) {
  std::vector<int> all;
  if (!only) {
    all.resize(plan.samples);
    std::iota(all.begin(), all.end(), 0);
    only = &all;
  }
  const std::vector<int>& ids = *only;
  const int S = (int)ids.size();
  SampleBatches sb;
  sb.order.resize(S);
  // Dense box id from the three piece numbers; a counting sort keeps plan order in a box.
  int n[3];
  for (int a = 0; a < 3; ++a)
    n[a] = (a < 2 ? plan.axis_offset[a + 1] : (int)plan.pieces.size()) - plan.axis_offset[a];
  auto box = [&](uint32_t k) {
    return ((long long)((k >> 20) & 1023u) * n[1] + ((k >> 10) & 1023u)) * n[0] + (k & 1023u);
  };
  const long long boxes = (long long)n[0] * n[1] * n[2];
  if (boxes <= 4LL * S + 1024) {
    // A counting sort; then each box's samples, contiguous, cut into batches of kLanes (what
    // the general loop below gives, without reading the samples' pieces again).
    std::vector<int> first(boxes + 1, 0);
    std::vector<uint32_t> key_of(boxes);
    for (int s : ids) {
      const uint32_t k = plan.sample_piece[s];
      const long long b = box(k);
      ++first[b + 1];
      key_of[b] = k;
    }
    std::partial_sum(first.begin(), first.end(), first.begin());
    for (long long b = 0; b < boxes; ++b) {
      if (first[b] == first[b + 1]) continue;
      const uint8_t terms = (uint8_t)box_terms(plan, key_of[b]);
      for (int i = first[b]; i < first[b + 1]; i += kLanes) {
        sb.start.push_back(i);
        sb.size.push_back((uint8_t)std::min(kLanes, first[b + 1] - i));
        sb.terms.push_back(terms);
      }
    }
    for (int s : ids) sb.order[first[box(plan.sample_piece[s])]++] = s;
    sb.start.push_back(S);
    return sb;
  }
  // Very fine lattices: more boxes than samples.
  sb.order = ids;
  std::stable_sort(sb.order.begin(), sb.order.end(), [&](int x, int y) {
    return box(plan.sample_piece[x]) < box(plan.sample_piece[y]);
  });
  cut_batches(plan, sb, 0, S);
  sb.start.push_back(S);
  return sb;
}

bool repiece_sample_batches(const Plan& plan, SampleBatches& sb, std::vector<int>& slot) {
  const std::vector<int>& moved = plan.repieced_samples;
  if (moved.empty()) return true;
  if ((long long)sb.order.size() < plan.samples) return false;  // not all the samples' batches
  const long long made = sb.count() - sb.appended;
  // More samples to move than the batches still allowed (below) could hold: made anew.
  if ((long long)moved.size() > (long long)kLanes * (made / 8 + 64 - sb.appended)) return false;
  if (slot.empty()) {
    slot.assign(plan.samples, -1);
    const int* order = sb.order.data();
    parallel_for((long long)sb.order.size(), default_threads(), [&](long long b, long long e) {
      for (long long i = b; i < e; ++i)
        if (order[i] >= 0) slot[order[i]] = (int)i;
    });
  }
  // Out of their batches.
  for (int s : moved) {
    const int i = slot[s];
    if (i < 0) return false;
    const long long b = std::upper_bound(sb.start.begin(), sb.start.end(), i) - sb.start.begin() - 1;
    const int last = sb.start[b] + sb.size[b] - 1;
    sb.order[i] = sb.order[last];
    slot[sb.order[i]] = i;
    sb.order[last] = -1;
    --sb.size[b];
  }
  // Into new ones, by box (plan order within one).
  std::vector<int> by_box(moved);
  std::stable_sort(by_box.begin(), by_box.end(),
                   [&](int x, int y) { return plan.sample_piece[x] < plan.sample_piece[y]; });
  const int from = (int)sb.order.size();
  for (int s : by_box) {
    slot[s] = (int)sb.order.size();
    sb.order.push_back(s);
  }
  const long long before = sb.count();
  sb.start.pop_back();
  cut_batches(plan, sb, from, (int)sb.order.size());
  sb.start.push_back((int)sb.order.size());
  sb.appended += sb.count() - before;
  return sb.appended <= made / 8 + 64;
}

#endif  // SFFD_ISA_PRIMARY

SFFD_ISA_BEGIN  // per-frame part: one copy per ISA (core/isa.hpp)

namespace {

// kJacobian = false leaves J unused, and the compiler drops its sums (all locals, unrolled).
// NC: values a control point (pv.components; 4: Blender's lattice vertex group, stages.hpp).
template <int C, bool kJacobian, int NC>
void sample_lanes(const PlanView& pv, const float* D, const int* ids, int n, float* value,
                  float* jacobian) {
  Lanes p[3], weight, local[3];
  for (int l = 0; l < kLanes; ++l) {
    int s = ids[l < n ? l : n - 1];  // a short batch repeats its last sample
    for (int a = 0; a < 3; ++a) p[a].set(l, pv.sample_position[3 * (long long)s + a]);
    weight.set(l, pv.sample_weight[s]);
    if (pv.sample_local)
      for (int a = 0; a < 3; ++a) local[a].set(l, pv.sample_local[3 * (long long)s + a]);
  }
  int idx[3][C];
  Lanes w[3][C], dw[3][C], val[NC], grad[3 * NC], A[9], F[3], J[9];
  sample_weights<C, Lanes>(pv, p, pv.sample_piece[ids[0]], idx, w, dw, pv.sample_local ? local : nullptr);
  tensor_eval_fixed<Lanes, float, C, C, C, NC>(idx[0], w[0], dw[0], idx[1], w[1], dw[1], idx[2], w[2],
                                               dw[2], D, pv.dims[1], pv.dims[2], val, grad);
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) A[3 * r + c] = pv.param_map[4 * r + c];
  if constexpr (NC == 4)
    compose_weighted_deformation<Lanes>(p, weight, val, grad, A, F, J);
  else
    compose_deformation<Lanes>(p, weight, val, grad, A, F, J);
  for (int l = 0; l < n; ++l) {
    long long s = ids[l];
    for (int r = 0; r < 3; ++r) value[3 * s + r] = F[r][l];
    if (kJacobian)
      for (int r = 0; r < 9; ++r) jacobian[9 * s + r] = J[r][l];
  }
}

template <bool kJacobian, int NC>
void sample_box(int terms, const PlanView& pv, const float* D, const int* ids, int n,
                float* value, float* jacobian) {
  switch (terms) {
    case 1: return sample_lanes<1, kJacobian, NC>(pv, D, ids, n, value, jacobian);
    case 2: return sample_lanes<2, kJacobian, NC>(pv, D, ids, n, value, jacobian);
    case 3: return sample_lanes<3, kJacobian, NC>(pv, D, ids, n, value, jacobian);
    case 4: return sample_lanes<4, kJacobian, NC>(pv, D, ids, n, value, jacobian);
    default:
      // Point weights come only with Blender's lattices (at most 4 terms an axis): no
      // kMaxTerms copy with 4 components, whose fully unrolled contraction took minutes to
      // compile for the baseline ISA.
      if constexpr (NC == 4) throw std::logic_error("sample_box: point weights with more than 4 terms an axis");
      else return sample_lanes<kMaxTerms, kJacobian, NC>(pv, D, ids, n, value, jacobian);
  }
}

}  // namespace

void sample_batch(const PlanView& pv, const float* D, const SampleBatches& sb, long long b,
                  float* value, float* jacobian) {
  const int* ids = sb.order.data() + sb.start[b];
  const int n = sb.size[b];
  if (n == 0) return;
  if (pv.components == 4) {
    if (jacobian) return sample_box<true, 4>(sb.terms[b], pv, D, ids, n, value, jacobian);
    return sample_box<false, 4>(sb.terms[b], pv, D, ids, n, value, nullptr);
  }
  if (jacobian) return sample_box<true, 3>(sb.terms[b], pv, D, ids, n, value, jacobian);
  return sample_box<false, 3>(sb.terms[b], pv, D, ids, n, value, nullptr);
}

SFFD_ISA_END

}  // namespace sffd
