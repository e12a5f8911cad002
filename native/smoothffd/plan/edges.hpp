// Edge adjacency of a triangle list and the per-edge-end sharpness of split normals.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace sffd {

struct EdgeTable {
  std::vector<int> vertex;      // #E x 2: ends a < b
  std::vector<int> side;        // #E x 2: first two triangles on the edge (-1: none)
  std::vector<int> face_count;  // #E: triangles on the edge (> 2: non-manifold)
  std::vector<int> tri_edge;    // #T x 3: edge of triangle edge k (corner k -> k + 1)
  int count() const { return (int)face_count.size(); }
};

// tri_vertex: #T x 3. Sort-based, deterministic: edges numbered by (a, b).
EdgeTable build_edges(const std::vector<int>& tri_vertex);

// An edge table with the triangles it is of, which a plan keeps for the next pose of the same
// triangles (follow_plan: they depend on connectivity alone).
struct TriangleEdges {
  std::vector<int> tri_vertex;
  EdgeTable edges;
};

// kept where it is of these very triangles, else a new one of them.
std::shared_ptr<const TriangleEdges> edges_of(const std::vector<int>& tri_vertex,
                                              const std::shared_ptr<const TriangleEdges>& kept = nullptr);

// Slot (0..2) of vertex v in triangle t, or -1.
inline int slot_of(const std::vector<int>& tri_vertex, int t, int v) {
  for (int k = 0; k < 3; ++k)
    if (tri_vertex[3 * (size_t)t + k] == v) return k;
  return -1;
}

// Sharpness of each edge end: at end v of an edge with two triangles, the edge is smooth if
// both triangles carry (nearly) the same corner normal at v. Boundary edges are smooth;
// non-manifold edges get neither flag (the caller treats them apart). Returns per edge
// bit 0 = sharp at a, bit 1 = sharp at b. corner_normal: #T x 3 x 3 unit vectors.
std::vector<uint8_t> classify_sharp_ends(const EdgeTable& edges, const std::vector<int>& tri_vertex,
                                         const std::vector<double>& corner_normal,
                                         double cos_tolerance);

}  // namespace sffd
