#include "smoothffd/eval/cpu_update.hpp"

#include <algorithm>
#include <array>
#include <cstring>
#include <mutex>
#include <unordered_map>
#include <utility>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {

namespace {

constexpr ControlBlock kNothing{{0xffff, 0xffff, 0xffff}, {0, 0, 0}};

void join(ControlBlock& into, const ControlBlock& b) {
  for (int a = 0; a < 3; ++a) {
    into.lo[a] = std::min(into.lo[a], b.lo[a]);
    into.hi[a] = std::max(into.hi[a], b.hi[a]);
  }
}

// The block of each sample, from its three pieces' control indices.
class SampleBlocks {
 public:
  explicit SampleBlocks(const Plan& plan) : plan_(plan), piece_(plan.pieces.size(), kNothing) {
    for (int a = 0; a < 3; ++a) {
      const int end = a < 2 ? plan.axis_offset[a + 1] : (int)plan.pieces.size();
      for (int i = plan.axis_offset[a]; i < end; ++i) {
        const AxisPieceF& pc = plan.pieces[i];
        for (int k = 0; k < pc.count; ++k) {
          const int c = std::min(std::max(pc.index[k], 0), plan.dims[a] - 1);
          piece_[i].lo[0] = std::min<int>(piece_[i].lo[0], c);
          piece_[i].hi[0] = std::max<int>(piece_[i].hi[0], c);
        }
      }
    }
  }
  ControlBlock operator()(int s) const {
    ControlBlock b;
    const uint32_t packed = plan_.sample_piece[s];
    for (int a = 0; a < 3; ++a) {
      const ControlBlock& pc = piece_[plan_.axis_offset[a] + ((packed >> (10 * a)) & 1023u)];
      b.lo[a] = pc.lo[0];
      b.hi[a] = pc.hi[0];
    }
    return b;
  }
  void add(ControlBlock& into, int s) const {
    if (s >= 0) join(into, (*this)(s));
  }

 private:
  const Plan& plan_;
  std::vector<ControlBlock> piece_;  // per piece, its indices in lo[0] .. hi[0]
};

// Numbers each distinct block once.
class BlockTable {
 public:
  explicit BlockTable(std::vector<ControlBlock>& blocks) : blocks_(blocks) {}
  uint32_t id(const ControlBlock& b) {
    Key k{};
    std::memcpy(k.data(), &b, sizeof b);
    if (k == last_) return last_id_;
    auto it = ids_.emplace(k, (uint32_t)blocks_.size());
    if (it.second) blocks_.push_back(b);
    last_ = k;
    return last_id_ = it.first->second;
  }
  std::vector<uint32_t> ids(const std::vector<ControlBlock>& bs) {
    std::vector<uint32_t> out(bs.size());
    for (size_t i = 0; i < bs.size(); ++i) out[i] = id(bs[i]);
    return out;
  }

 private:
  using Key = std::array<uint16_t, 6>;
  struct Hash {
    size_t operator()(const Key& k) const {
      uint64_t h = 1469598103934665603ull;
      for (uint16_t v : k) h = (h ^ v) * 1099511628211ull;
      return (size_t)h;
    }
  };
  std::vector<ControlBlock>& blocks_;
  std::unordered_map<Key, uint32_t, Hash> ids_;
  Key last_{{1, 0, 0, 0, 0, 0}};  // lo 1 > hi 0: no element's block
  uint32_t last_id_ = 0;
};

// A batch's samples share one box (make_sample_batches): its first sample's.
std::vector<ControlBlock> batch_blocks(const SampleBatches& sb, const SampleBlocks& blocks) {
  std::vector<ControlBlock> out(sb.count(), kNothing);
  for (long long b = 0; b < sb.count(); ++b)
    if (sb.size[b] > 0) out[b] = blocks(sb.order[sb.start[b]]);
  return out;
}

}  // namespace

size_t UpdateReach::bytes() const {
  return sizeof(ControlBlock) * blocks.size() +
         sizeof(uint32_t) * (batches.size() + positions_batches.size() + end_normals.size() + edges.size() +
                             patches.size());
}

UpdateReach make_update_reach(const Plan& plan, const SampleBatches& batches,
                              const SampleBatches& positions_batches, const EdgeEndNormals& en,
                              int threads) {
  const SampleBlocks blocks(plan);
  UpdateReach r;
  BlockTable table(r.blocks);
  r.batches = table.ids(batch_blocks(batches, blocks));
  r.positions_batches = table.ids(batch_blocks(positions_batches, blocks));
  std::vector<ControlBlock> b(en.count());
  for (long long i = 0; i < en.count(); ++i) b[i] = blocks(en.sample[i]);
  r.end_normals = table.ids(b);
  std::vector<ControlBlock> edges(plan.edges, kNothing);
  parallel_for(plan.edges, threads, [&](long long eb, long long ee) {
    for (long long e = eb; e < ee; ++e)
      for (int k = 0; k < 2; ++k) {
        blocks.add(edges[e], plan.edge_vertex[2 * (size_t)e + k]);
        blocks.add(edges[e], plan.edge_constraint[2 * (size_t)e + k]);
      }
  });
  r.edges = table.ids(edges);
  // A patch: its columns' samples (neighbouring columns mostly in one box: each distinct box
  // once), its corners, its edges and its centre row's block.
  std::vector<ControlBlock> patches(plan.patches, kNothing);
  const int K = plan.columns;
  parallel_for(plan.patches, threads, [&](long long pb, long long pe) {
    for (long long p = pb; p < pe; ++p) {
      ControlBlock& block = patches[p];
      uint32_t last = 0xffffffffu;
      for (int c = 0; c < K; ++c) {
        const int s = plan.patch_samples[(size_t)K * p + c];
        if (s < 0 || plan.sample_piece[s] == last) continue;
        last = plan.sample_piece[s];
        blocks.add(block, s);
      }
      for (int k = 0; k < 3; ++k) blocks.add(block, plan.patch_vertex[3 * (size_t)p + k]);
      for (int k = 0; k < 3; ++k) join(block, edges[plan.patch_edge[3 * (size_t)p + k]]);
      if (!plan.centre_box.empty()) {
        int lo[3], ext[3];
        unpack_centre_box(plan.centre_box[p], lo, ext);
        for (int a = 0; a < 3; ++a) {
          if (ext[a] == 0) continue;
          block.lo[a] = std::min<int>(block.lo[a], lo[a]);
          block.hi[a] = std::max<int>(block.hi[a], std::min(lo[a] + ext[a] - 1, plan.dims[a] - 1));
        }
      }
    }
  });
  r.patches = table.ids(patches);
  return r;
}

long long ChangedPoints::compare(const int dims[3], int components, const float* D, const float* previous) {
  n1_ = dims[1] + 1;
  n2_ = dims[2] + 1;
  sum_.assign((size_t)(dims[0] + 1) * n1_ * n2_, 0);
  auto at = [&](int i, int j, int k) -> int& { return sum_[((size_t)i * n1_ + j) * n2_ + k]; };
  long long changed = 0;
  for (int i = 0; i < dims[0]; ++i)
    for (int j = 0; j < dims[1]; ++j)
      for (int k = 0; k < dims[2]; ++k) {
        const size_t o = (((size_t)i * dims[1] + j) * dims[2] + k) * components;
        const int c = std::memcmp(D + o, previous + o, sizeof(float) * components) != 0;
        changed += c;
        at(i + 1, j + 1, k + 1) = c + at(i, j + 1, k + 1) + at(i + 1, j, k + 1) + at(i + 1, j + 1, k) -
                                  at(i, j, k + 1) - at(i, j + 1, k) - at(i + 1, j, k) + at(i, j, k);
      }
  return changed;
}

bool ChangedPoints::any_in(const ControlBlock& b) const {
  if (b.lo[0] > b.hi[0] || b.lo[1] > b.hi[1] || b.lo[2] > b.hi[2]) return false;
  auto at = [&](int i, int j, int k) { return sum_[((size_t)i * n1_ + j) * n2_ + k]; };
  const int i0 = b.lo[0], j0 = b.lo[1], k0 = b.lo[2];
  const int i1 = b.hi[0] + 1, j1 = b.hi[1] + 1, k1 = b.hi[2] + 1;
  return at(i1, j1, k1) - at(i0, j1, k1) - at(i1, j0, k1) - at(i1, j1, k0) + at(i0, j0, k1) +
             at(i0, j1, k0) + at(i1, j0, k0) - at(i0, j0, k0) > 0;
}

void ChangedRuns::collect(const std::vector<uint32_t>& ids, const std::vector<uint8_t>& hit, int threads) {
  // Each thread's share of [0, n) into runs of its own, then the shares in order.
  const long long n = (long long)ids.size();
  std::mutex mutex;
  std::vector<std::pair<long long, std::vector<long long>>> parts;  // (share start, b0 e0 b1 e1 ...)
  parallel_for(n, threads, [&](long long b, long long e) {
    std::vector<long long> runs;
    for (long long i = b; i < e;) {
      if (!hit[ids[i]]) {
        ++i;
        continue;
      }
      runs.push_back(i);
      while (i < e && hit[ids[i]]) ++i;
      runs.push_back(i);
    }
    std::lock_guard<std::mutex> lock(mutex);
    parts.emplace_back(b, std::move(runs));
  });
  std::sort(parts.begin(), parts.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  begin.clear();
  end.clear();
  before.assign(1, 0);
  for (const auto& part : parts)
    for (size_t k = 0; k < part.second.size(); k += 2) {
      begin.push_back(part.second[k]);
      end.push_back(part.second[k + 1]);
      before.push_back(before.back() + part.second[k + 1] - part.second[k]);
    }
}

}  // namespace sffd
