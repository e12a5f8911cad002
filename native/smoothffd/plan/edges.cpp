#include "smoothffd/plan/edges.hpp"

#include <algorithm>
#include <cstdint>

#include "smoothffd/core/parallel.hpp"

namespace sffd {

EdgeTable build_edges(const std::vector<int>& tv) {
  size_t T = tv.size() / 3;
  // The half-edges in (key, index) order, key = (lower end, higher end): a counting sort by the
  // lower end (stable: indices ascending), then each vertex's few half-edges sorted by the
  // higher end. O(#T + #V), where a comparison sort of every half-edge was most of this
  // function's time.
  uint32_t V = 0;
  for (int v : tv) V = std::max(V, (uint32_t)v + 1);
  std::vector<uint32_t> start(V + 1, 0);
  for (size_t t = 0; t < T; ++t)
    for (int k = 0; k < 3; ++k) start[std::min(tv[3 * t + k], tv[3 * t + (k + 1) % 3]) + 1]++;
  for (uint32_t v = 0; v < V; ++v) start[v + 1] += start[v];
  std::vector<std::pair<uint64_t, int>> half(3 * T);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (size_t t = 0; t < T; ++t)
      for (int k = 0; k < 3; ++k) {
        uint32_t a = tv[3 * t + k], b = tv[3 * t + (k + 1) % 3];
        if (a > b) std::swap(a, b);
        half[fill[a]++] = {(uint64_t(a) << 32) | b, int(3 * t + k)};
      }
  }
  for (uint32_t v = 0; v < V; ++v)
    if (start[v + 1] - start[v] > 1) std::sort(half.begin() + start[v], half.begin() + start[v + 1]);
  EdgeTable e;
  e.tri_edge.assign(3 * T, -1);
  for (size_t i = 0; i < half.size(); ++i) {
    if (i == 0 || half[i].first != half[i - 1].first) {
      e.vertex.push_back(int(half[i].first >> 32));
      e.vertex.push_back(int(half[i].first & 0xffffffffu));
      e.side.push_back(-1);
      e.side.push_back(-1);
      e.face_count.push_back(0);
    }
    int id = e.count() - 1;
    int t = half[i].second / 3;
    if (e.face_count[id] < 2) e.side[2 * id + e.face_count[id]] = t;
    e.face_count[id]++;
    e.tri_edge[half[i].second] = id;
  }
  return e;
}

std::shared_ptr<const TriangleEdges> edges_of(const std::vector<int>& tri_vertex,
                                              const std::shared_ptr<const TriangleEdges>& kept) {
  if (kept && kept->tri_vertex == tri_vertex) return kept;
  return std::make_shared<const TriangleEdges>(TriangleEdges{tri_vertex, build_edges(tri_vertex)});
}

std::vector<uint8_t> classify_sharp_ends(const EdgeTable& e, const std::vector<int>& tv,
                                         const std::vector<double>& cn, double cos_tol) {
  std::vector<uint8_t> flags(e.count(), 0);
  // Each edge on its own: in parallel, the same values.
  parallel_for(e.count(), default_threads(), [&](long long b, long long end_id) {
    for (long long id = b; id < end_id; ++id) {
      if (e.face_count[id] != 2) continue;
      int t0 = e.side[2 * id], t1 = e.side[2 * id + 1];
      for (int end = 0; end < 2; ++end) {
        int v = e.vertex[2 * id + end];
        const double* n0 = &cn[9 * (size_t)t0 + 3 * slot_of(tv, t0, v)];
        const double* n1 = &cn[9 * (size_t)t1 + 3 * slot_of(tv, t1, v)];
        double d = n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2];
        if (!(d >= cos_tol)) flags[id] |= uint8_t(1u << end);
      }
    }
  });
  return flags;
}

}  // namespace sffd
