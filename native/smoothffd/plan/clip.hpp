// Knot-box clipping (paper sec. 3 and 4.3): split every triangle by the lattice's knot planes
// so that each piece lies in one knot box, and triangulate the convex pieces.
//
// Clipping runs in the lattice's parameter space s (an affine image of object space), where
// knot planes are axis-aligned. A clip vertex is keyed by the segment it splits (its two end
// vertices) and the plane, so the two triangles on a shared edge, and the two pieces on a
// shared cut, get the very same vertex: the sub-mesh stays watertight.
//
// Snapping (no slivers). A cut that crosses an edge very near one of its ends leaves a tiny
// piece there and, next to it, a needle (a piece with a side of that tiny length and a far
// vertex); a plane running along an edge close to it leaves a thin strip. So a vertex counts
// as lying on a knot plane (side 0: the plane passes through it and nothing is cut off next to
// it) when
//   * an input vertex: the plane crosses one of its edges within kClipEdgeSnap of the edge's
//     length from it, or runs along one of its edges, both ends within kClipEdgeSnap of the
//     edge's length from the plane;
//   * a clip vertex: the plane passes within kClipSnap of the segment it split (its snap
//     distance) from it, so cuts along one edge, or a cut and a later cut's crossing, are at
//     least that far apart;
//   * any vertex: within rounding (1e-5 of the smallest knot spacing, float32 noise).
// Of each axis only the plane nearest to the vertex snaps (beyond rounding): where planes are
// closer together than that, a fan of cuts through one vertex would leave needles between them;
// and only within a quarter of that plane's gap to its neighbours, so no piece reaches across
// more than a quarter of a knot span (knots of high multiplicity spread by a tiny amount make
// the deformation change fast between their planes: those pieces stay exact, thin as they are).
// Each decision depends only on the vertex, its neighbours and the plane, so every triangle
// and piece around a vertex decides alike and the sub-mesh stays watertight (the pieces of a
// polygon whose snapped vertices put it on both sides of a plane are split so that each edge
// goes to one half). A cut never crosses an input edge nearer than kClipEdgeSnap of its length
// to an end, nor a segment nearer than kClipSnap of its length to a clip vertex: a piece's
// smallest angle is about kClipEdgeSnap times the input's smallest angle or more (at least
// 1/154 of it in 400 random trials, native/tests/test_clip.cpp). A piece may extend past its
// knot plane by at most its corners' snap distances (ClipResult::snap); each sample still
// takes the polynomial piece it lies in, so the deformation is exact at the samples and
// continuous across the plane.
#pragma once

#include <optional>
#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"

namespace sffd {

// Relative snap distances (see above).
constexpr double kClipEdgeSnap = 1.0 / 20.0;  // input vertices: of the crossed edge's length
constexpr double kClipSnap = 1.0 / 32.0;      // clip vertices: of the segment they split
// hold_clip: how far (the sum of the weights' differences over the control points) the
// weights of a held piece's knot box, continued to one of its corners past the box's planes,
// may be from those at the corner.
constexpr double kHoldKink = 3e-3;

struct ClipResult {
  std::vector<double> flat;         // #SV x 3: positions; rows [0, V) are the input vertices
  std::vector<double> snap;         // #SV: how far (object space) a piece with a corner here
                                    // may reach past a knot plane: kClipEdgeSnap of an input
                                    // vertex's longest edge; for a clip vertex, kClipSnap of
                                    // the segment it split or its ends' bound if larger
  std::vector<int> origin_tri;      // #SV: triangle that created the clip vertex (-1: input)
  std::vector<double> origin_bary;  // #SV x 3: its barycentric point in that triangle
  std::vector<int> patch_vertex;    // #P x 3 sub-vertices, same winding as the triangle
  std::vector<int> patch_tri;       // #P: triangle each piece lies in
  std::vector<double> patch_bary;   // #P x 3 x 3: barycentric points of its corners
  int sub_vertices() const { return (int)origin_tri.size(); }
  int patches() const { return (int)patch_tri.size(); }
};

// An earlier clipping of the same triangles (another pose): its pieces' triangles (patch_vertex,
// patch_tri, in triangle order, as ClipResult's).
struct ClipHint {
  const std::vector<int>& patch_vertex;
  const std::vector<int>& patch_tri;
};

// X: #V x 3 input positions; tv: #T x 3 triangles. hint: where a piece is the same polygon of
// the same sub-vertices as one of the hint's (the triangle crosses the knot planes as it did
// there), it is cut into the hint's triangles, in their order, as long as none of them is
// flat or turned over in the new shape; else by shape (below). So a sub-mesh follows a pose
// without its pieces' diagonals flipping where two cuts are about equally good.
ClipResult clip_to_knot_boxes(const std::vector<double>& X, const std::vector<int>& tv,
                              const LatticeSpec& lattice, const ClipHint* hint = nullptr);

// The pieces of an earlier clipping of the same triangles (a plan's patch_vertex, patch_triangle
// and patch_bary), held in a new pose: every piece keeps its sub-vertices and its barycentric
// corners in its triangle, and a clip vertex is placed where its barycentric point in the
// lowest triangle that has it now lies. Returned where every held piece still lies in a knot
// box (its centroid's, its lowest or its highest corner's) as far as the deformation can tell:
// on each axis every corner lies in the box to within the snap distance of the piece's
// triangle's corners (kClipEdgeSnap of their longest edge, at most a quarter of the box's span:
// what a fresh clipping lets a piece reach past a plane), or else the box's polynomial piece,
// continued to the corner, gives weights within kHoldKink (summed over the control points) of
// those there. Else nullopt (then clip again). The deformation is a polynomial on each knot
// box, continuous across the planes: past a plane by delta (knot spans) a piece sees a
// polynomial that differs from its box's by about the weights' difference times the control
// points' spread about an affine map, growing as delta to the power of the continuity there
// plus one: on uniform knots 3e-3 is about 1/10 of a span for a cubic B-spline axis, 1/26 for
// a quadratic one, 1/670 for a linear one. Each sample still takes the polynomial piece it lies
// in (the deformation is exact at the samples); the fit spans the little that differs
// (docs/algorithm.md, "Holding the pieces", has the accuracy measured).
struct ClipHold {
  const std::vector<int>& patch_vertex;
  const std::vector<int>& patch_tri;
  const std::vector<double>& patch_bary;
};
// check false: every piece is held wherever it now lies (the fit then spans whatever part of
// the neighbouring boxes a piece reaches: continuous, less accurate the farther it reaches).
std::optional<ClipResult> hold_clip(const std::vector<double>& X, const std::vector<int>& tv,
                                    const LatticeSpec& lattice, const ClipHold& held, bool check = true);

}  // namespace sffd
