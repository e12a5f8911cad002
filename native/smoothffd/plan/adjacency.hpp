// The sub-mesh's adjacency as the evaluators read it (plan.hpp: patches, edges): each patch's
// corners and edges, each edge's ends, patches and corner slots, and its flags.
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// patch_vertex: P x 3 sub-vertices; sub: build_edges(patch_vertex); sharp: its edges' sharp
// ends (kSharpAtA | kSharpAtB); patch_flat(p) is tri_flat[patch_tri[p]]: the patch is a flat
// face's. Fills plan.patch_vertex, patch_edge, patch_edge_reversed, edge_vertex, edge_patch,
// edge_slot, edge_flags and edges. An edge's flags: its sharp ends, kBoundary (one patch),
// kNonManifold (three or more), kFlatFace (a flat face's patch on either of its first two sides).
void build_adjacency(Plan& plan, const std::vector<int>& patch_vertex, const EdgeTable& sub,
                     const std::vector<uint8_t>& sharp, const std::vector<int>& patch_tri,
                     const std::vector<uint8_t>& tri_flat);

}  // namespace sffd
