// Adaptive tessellation to a tolerance (docs/algorithm.md, "Adaptive tessellation"): instead of
// L^2 triangles on every patch, each sub-edge gets its own segment count and each patch an
// interior level, from bounds on the distance between the cubic patch and the triangles that
// approximate it, so that every output triangle is within the tolerance of its patch.
//
// Per frame, because the counts follow the deformed patches:
//   1. reference patches   every sample, edge and patch of the frame by the shared scalar
//                          stages (stages.hpp: sample_point, adjust_edge, fit_patch_into),
//                          compiled without floating-point contraction: the same floats on
//                          every CPU, so the integer decisions below are too
//   2. edge counts         each sub-edge's count from its own cubic (its ends and its two
//                          adjusted control points), the same for both patches on it
//   3. patch patterns      each patch's interior level m: the uniform level-m grid when all
//                          three edges have m segments, else the interior points of that grid
//                          with a strip along each edge that zips its points to the grid's
//                          first inner row; m grows until every strip triangle's bound holds
//   4. scans               output vertex and triangle offsets (sub-vertices, then each edge's
//                          inner points, then each patch's interior points)
//   5. emit                positions (edge points once, from the edge's own cubic), triangles,
//                          per-corner unit normals from each patch's normal patch, the input
//                          face, UVs and rest positions
// The output is watertight: an edge's points depend only on that edge's data and are emitted
// once, as the uniform output's are.
#pragma once

#include <vector>

#include "smoothffd/eval/evaluator.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

struct AdaptiveOptions {
  double tolerance = 0;        // object units, > 0: every triangle within it of its patch
  int max_level = kMaxLevel;   // the most segments an edge and the highest interior level
  int threads = 0;             // 0: all cores
  bool normals = true;         // per-corner normals (else corner_normals stays empty)
  bool details = false;        // also patch_control and corner_bary (tests)
  // Held counts (E and P values, or null): each edge gets at least min_edge_segments[e]
  // segments and each patch exactly the level max(its uniform level, min_patch_level[p]), no
  // higher (its pattern the uniform grid when its edges all have that many segments): with
  // the largest counts of several frames (a motion-blur shutter, a frame range) every one of
  // those frames gets the same topology, and a frame's own counts give its own mesh. A held
  // frame's bound may exceed the tolerance where a strip would have needed a higher level
  // (counted in AdaptiveMesh::capped).
  const int* min_edge_segments = nullptr;
  const int* min_patch_level = nullptr;
  bool counts_only = false;    // decide the counts, emit nothing (edge_segments, patch_level)
};

struct AdaptiveMesh {
  std::vector<float> positions;       // N x 3: [0, sub_vertices) the sub-vertices, as uniform
  std::vector<int> triangles;         // T x 3
  std::vector<int> face_index;        // T: input face
  std::vector<int> triangle_patch;    // T: patch
  std::vector<float> corner_normals;  // T x 3 x 3, unit (empty without options.normals)
  std::vector<float> uvs;             // T x 3 x 2 (empty without corner UVs)
  std::vector<float> rest_positions;  // N x 3: each vertex's preimage on the flat input
  std::vector<int> sharp_edges;       // K x 2: output edges along sub-edges whose normals split
  std::vector<int> edge_segments;     // E: segments of each sub-edge
  std::vector<int> patch_level;       // P: interior level m of each patch
  std::vector<unsigned char> patch_uniform;  // P: 1 where the patch is the uniform level-m grid
  std::vector<float> patch_control;   // details: P x 10 x 3, the patches the triangles approximate
  std::vector<float> corner_bary;     // details: T x 3 x 3, each corner's barycentric point on its patch
  double max_bound = 0;               // the largest triangle bound of the output
  long long capped = 0;               // edges and patches held at max_level above the tolerance
  StageTimes times;

  // The mesh arrays for N vertices and T triangles (the options' normals and details, UVs
  // with corner_uv), as both backends fill them.
  void allocate(long long N, long long T, const AdaptiveOptions& options, bool uvs) {
    positions.resize(3 * (size_t)N);
    rest_positions.resize(3 * (size_t)N);
    triangles.resize(3 * (size_t)T);
    face_index.resize(T);
    triangle_patch.resize(T);
    if (options.normals) corner_normals.resize(9 * (size_t)T);
    if (uvs) this->uvs.resize(6 * (size_t)T);
    if (options.details) corner_bary.resize(9 * (size_t)T);
  }
};

// One adaptive frame of `plan` (any level: its uniform tables are not used) for control values
// D (nu*nv*nw x plan.components). corner_uv: the input's C x 2 corner UVs (the corners the plan
// was built from), or null. Deterministic: the same D gives bitwise the same mesh for every
// thread count and CPU.
AdaptiveMesh adaptive_frame(const Plan& plan, const float* D, const float* corner_uv, const AdaptiveOptions& options);

// The output edges along sub-edges whose normals split (K x 2 output vertices), for edge counts
// `segments` (E values) numbered as adaptive_frame numbers its output vertices.
std::vector<int> adaptive_sharp_edges(const Plan& plan, const int* segments);

// The triangles of a patch's pattern for edge counts n[0..2] and interior level m (the uniform
// grid when all three are m; else m >= 3), as barycentric points, T x 3 corners x 3, in the
// order adaptive_frame emits them (tests).
std::vector<double> adaptive_pattern(const int n[3], int m);

// The bounds the decisions use, exposed for tests (cp: 10 x 3 control points of a cubic patch
// in the bezier.hpp order; st: a triangle's three parameter points (s, t) = (b1, b2)):
// the largest distance between the patch and the linear interpolant of its values at the
// triangle's corners, over the triangle.
double triangle_bound(const float* cp, const double st[3][2]);
// The same for a uniform level-m grid's triangles over the whole patch.
double uniform_bound(const float* cp, int m);
// The largest distance between a cubic curve (4 control points, 3 floats each) and its chord
// polygon of n equal parameter steps.
double edge_bound(const float* b0, const float* b1, const float* b2, const float* b3, int n);

}  // namespace sffd
