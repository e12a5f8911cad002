#include "smoothffd/plan/adjacency.hpp"

namespace sffd {

void build_adjacency(Plan& plan, const std::vector<int>& patch_vertex, const EdgeTable& sub,
                     const std::vector<uint8_t>& sharp, const std::vector<int>& patch_tri,
                     const std::vector<uint8_t>& tri_flat) {
  const int E = sub.count(), P = (int)(patch_vertex.size() / 3);
  plan.patch_vertex = patch_vertex;
  plan.edges = E;
  plan.edge_vertex = sub.vertex;
  plan.edge_patch = sub.side;
  plan.edge_flags.resize(E);
  plan.edge_slot.assign(4 * (size_t)E, 0);
  for (int e = 0; e < E; ++e) {
    uint8_t f = sharp[e];
    if (sub.face_count[e] == 1) f |= kBoundary;
    if (sub.face_count[e] > 2) f |= kNonManifold;
    // A flat face's edges (docs/algorithm.md, "Flat faces"): its patches are the accurate FFD
    // of its triangles, edges included, so the edge a smooth face shares with it follows the
    // flat one, straight at rest.
    for (int s = 0; s < 2; ++s) {
      const int p = sub.side[2 * e + s];
      if (p >= 0 && tri_flat[patch_tri[p]]) f |= kFlatFace;
    }
    plan.edge_flags[e] = f;
    for (int s = 0; s < 2; ++s) {
      int p = sub.side[2 * e + s];
      if (p < 0) continue;
      plan.edge_slot[4 * (size_t)e + 2 * s] = (uint8_t)slot_of(patch_vertex, p, sub.vertex[2 * e]);
      plan.edge_slot[4 * (size_t)e + 2 * s + 1] = (uint8_t)slot_of(patch_vertex, p, sub.vertex[2 * e + 1]);
    }
  }
  plan.patch_edge = sub.tri_edge;
  plan.patch_edge_reversed.resize(3 * (size_t)P);
  for (int p = 0; p < P; ++p)
    for (int k = 0; k < 3; ++k)
      plan.patch_edge_reversed[3 * p + k] = sub.vertex[2 * sub.tri_edge[3 * p + k]] != patch_vertex[3 * p + k];
}

}  // namespace sffd
