// The rest surface that knot-box clip vertices are moved onto (paper sec. 4.3.1) and the PN
// quadratic normal field that gives them adjustment normals (sec. 4.3.2).
//
// The paper uses the PN triangle of each input triangle. PN edge curves depend on the corner
// normals of *one* face, so across a sharp edge the two faces' curves differ and a clip point
// placed on one of them cracks away from the other. We therefore build the edge control
// points once per edge, from the normals of both faces, with the same rule as the geometry
// adjustment of sec. 4.2: at a smooth end, (2a + b)/3 projected onto the tangent plane of the
// shared normal (exactly PN's b210); at a sharp end, projected onto the crease line n0 x n1.
// The centre follows PN: b111 = E + (E - V)/2. The surface is watertight by construction.
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/plan/edges.hpp"

namespace sffd {

struct RestSurface {
  std::vector<double> edge_cp;  // #E x 2 x 3: control point near end a, near end b
};

// X: #V x 3 positions; tv: #T x 3; corner_normal: #T x 3 x 3 unit; sharp: per edge flags from
// classify_sharp_ends.
RestSurface build_rest_surface(const std::vector<double>& X, const std::vector<int>& tv,
                               const EdgeTable& edges, const std::vector<uint8_t>& sharp,
                               const std::vector<double>& corner_normal);

// Point of triangle t's rest patch at barycentric coordinates b (of its corners 0, 1, 2).
void rest_surface_point(const RestSurface& rs, const std::vector<double>& X,
                        const std::vector<int>& tv, const EdgeTable& edges, int t,
                        const double b[3], double out[3]);

// PN quadratic normal field of a triangle with corners P (3 x 3) and unit normals N (3 x 3),
// at barycentric b; unit length.
void pn_quadratic_normal(const double P[9], const double N[9], const double b[3], double out[3]);

}  // namespace sffd
