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

// The normals the geometry follows at the corners of a triangle mesh (corner: #T x 3 x 3,
// unit): the adjustment normals of sec. 4.2 and 4.3.2 and of the rest surface. Shading keeps
// the input's normals; these start from them (`base`) and differ in two ways:
//  * A flat triangle (flat[t]: every normal of its face equals the face's own) takes its own
//    geometric normal at every corner: its edges then stay straight at rest wherever the
//    neighbour is flat too (both sides' normals are perpendicular to them at a smooth end,
//    their cross product runs along them at a sharp one), and it deforms as the lattice does,
//    non-planar polygons included.
//  * Where the normals would fold a patch, they are blended toward the triangle's own normal:
//    corner (t, k) at vertex v is normalize(trust_v n + (1 - trust_v) own_t), with trust_v
//    lowered by bound_adjust_normals until no patch folds (0: every triangle at v follows
//    its own plane there, as flat triangles do).
struct AdjustNormals {
  AdjustNormals(const std::vector<double>& X, const std::vector<int>& tv, const std::vector<double>& base,
                const std::vector<uint8_t>& flat);
  void update(const std::vector<int>& tv, int t, int k);  // corner (t, k) from trust

  std::vector<double> base;      // #T x 3 x 3: the normals before bounding
  std::vector<uint8_t> flat;     // #T
  std::vector<double> own;       // #T x 3: each triangle's own unit normal
  std::vector<uint8_t> has_own;  // #T: 0 for a degenerate triangle
  std::vector<double> trust;     // #V: 1 = the base normals, 0 = each triangle's own
  std::vector<double> corner;    // #T x 3 x 3: the adjustment normals
};

// A patch folds where its normal turns more than acos(kFoldCos) (78 degrees) from the render
// normal field (the shading normals rn interpolated over the triangle), or where it collapses
// (its normal under kCollapse of the flat triangle's: a corner whose two edge tangents line
// up); checked on a grid of 15 points, corners and edges included, and on the flat triangles
// of the tessellations of level 1 and 2 (what the output is made of).
constexpr double kFoldCos = 0.2;
constexpr double kCollapse = 0.25;
bool rest_patch_folds(const double cp[10][3], const double rn[9]);

struct RestSurface {
  std::vector<double> edge_cp;  // #E x 2 x 3: control point near end a, near end b
};

// X: #V x 3 positions; tv: #T x 3; corner_normal: #T x 3 x 3 unit; sharp: per edge flags from
// classify_sharp_ends; flat: #T, triangles of flat faces (null: none), whose edges stay
// straight as the evaluators keep them (kFlatFace), like non-manifold edges.
RestSurface build_rest_surface(const std::vector<double>& X, const std::vector<int>& tv,
                               const EdgeTable& edges, const std::vector<uint8_t>& sharp,
                               const std::vector<double>& corner_normal,
                               const std::vector<uint8_t>* flat = nullptr);

// Control points of triangle t's rest patch (plan/bezier.hpp order).
void rest_patch(const RestSurface& rs, const std::vector<double>& X, const std::vector<int>& tv,
                const EdgeTable& edges, int t, double cp[10][3]);

// A cubic patch's point, and its geometric normal (not normalized: the cross product of the
// derivatives along corner 0 -> 1 and corner 0 -> 2), at barycentric coordinates b.
void cubic_point(const double cp[10][3], const double b[3], double out[3]);
void cubic_normal(const double cp[10][3], const double b[3], double out[3]);

// The patches the evaluators make at rest from positions X, triangles tv and the adjustment
// normals an.corner (the rest surface's rule: per-edge control points, PN centre) are checked
// against the render normals (#T x 3 x 3); the trust of the vertices of every triangle whose
// patch folds is lowered (halved, 0 from the fifth round on) and `rest` rebuilt, until no patch
// folds or the trust is 0 (straight edges, flat triangles: no fold where the render normals
// agree with their triangle's orientation). With pieces (triangle t's pieces q in
// [piece_start[t], piece_start[t + 1]), corners' barycentric points piece_bary[9q ...]: the
// knot-box clipping), the flat triangles through the rest surface at each piece's corners
// (what the patches of the pieces start from) must not turn against the normals either.
// `check` (#T, 0 or 1): the triangles to check at first (default all; a triangle at a vertex
// whose trust is lowered is checked again anyway). Returns the number of vertices whose
// trust was lowered.
int bound_adjust_normals(const std::vector<double>& X, const std::vector<int>& tv, const EdgeTable& edges,
                         const std::vector<uint8_t>& sharp, const std::vector<double>& render,
                         AdjustNormals& an, RestSurface& rest, const std::vector<int>* piece_start = nullptr,
                         const std::vector<double>* piece_bary = nullptr,
                         const std::vector<uint8_t>* check = nullptr);

// The shading normals the geometry can carry through a deformation. The output's normals are
// the rest normals mapped by cof J, its surface the rest patch mapped by J; two directions
// theta apart end up as much as 2 atan(k tan(theta / 2)) apart under a Jacobian of condition
// number k, past 90 degrees (triangles reversed against their normals) once
// theta > 2 atan(1 / k). Where the geometry cannot follow a corner's normal (its adjustment
// normal was blended toward the triangle's own, or the triangle is flat), that normal is
// turned toward the adjustment normal until they are at most acos(kShadeCos) apart:
// 2 atan(1 / 2) = 53.13 degrees, cos = 0.6, so that no lattice whose Jacobian has a condition
// number under 2 reverses them. render: #T x 3 x 3 unit normals, changed in place; turned
// (#T x 3, optional): set to 1 at each corner turned. Returns the number of corners turned
// (those already at the limit, within rounding, are left).
constexpr double kShadeCos = 0.6;
int bound_render_normals(const AdjustNormals& an, std::vector<double>& render, std::vector<uint8_t>* turned);

// Point of triangle t's rest patch at barycentric coordinates b (of its corners 0, 1, 2).
void rest_surface_point(const RestSurface& rs, const std::vector<double>& X,
                        const std::vector<int>& tv, const EdgeTable& edges, int t,
                        const double b[3], double out[3]);

// PN quadratic normal field of a triangle with corners P (3 x 3) and unit normals N (3 x 3),
// at barycentric b; unit length.
void pn_quadratic_normal(const double P[9], const double N[9], const double b[3], double out[3]);

}  // namespace sffd
