// One axis of a lattice: a piecewise polynomial partition of unity over the axis parameter s.
//
// Both lattice kinds (the paper's B-spline volume, Eq. 1, and Blender's Lattice modifier) are
// tensor products of three of these, so they share the evaluation, the knot planes used for
// clipping, and the GPU tables. A piece covers [lo, hi) of s; on it the weight of term k is
//   w_k(t) = sum_p coef[k][p] t^p,  t = (s - origin) / scale,
// applied to control index index[k]. Pieces cover the whole real line: the first and last are
// the constant continuation outside the lattice.
#pragma once

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace sffd {

constexpr int kMaxAxisDegree = 5;
constexpr int kMaxTerms = kMaxAxisDegree + 1;  // Blender's cubic stencil needs 4

struct AxisPiece {
  double lo = 0, hi = 0;         // interval of s ([lo, hi); the outer pieces are unbounded)
  double origin = 0, scale = 1;  // local parameter t = (s - origin) / scale
  int degree = 0;                // highest power with a non-zero coefficient
  int count = 0;                 // number of terms
  int index[kMaxTerms] = {};     // control point index of each term
  double coef[kMaxTerms][kMaxTerms] = {};  // coef[term][power]
};

enum class BlenderInterp { Linear, Cardinal, CatmullRom, BSpline };

// Parses "LINEAR", "CARDINAL", "CATMULL_ROM", "BSPLINE" (Blender's KEY_* names without KEY_).
BlenderInterp parse_blender_interp(const std::string& name);

class AxisBasis {
 public:
  // Open or custom B-spline basis: `knots` has n_ctrl + degree + 1 non-decreasing values; the
  // domain is [knots[degree], knots[n_ctrl]]; outside it the boundary weights continue.
  static AxisBasis bspline(int degree, const std::vector<double>& knots, int n_ctrl);
  // Blender's per-axis weights in lattice index space s = (q - f) / d, stencil indices
  // clamped into [0, n - 1]; a one-point axis is the constant weight 1 on index 0.
  static AxisBasis blender(BlenderInterp type, int n_points);

  int n_ctrl() const { return n_ctrl_; }
  int degree() const { return degree_; }  // max over pieces: enters the fitting degree
  const std::vector<AxisPiece>& pieces() const { return pieces_; }
  // Values of s where the polynomial piece changes (the knot planes of this axis), ascending.
  std::vector<double> planes() const;
  // Index of the piece used at s. A point on a plane takes the piece above it, except on the
  // outer boundary of the polynomial range (within rounding), which takes the inner piece (so
  // the Jacobian on the faces of a B-spline box or a Blender lattice is the inner one).
  int find_piece(double s) const;
  // The same, tried first at `guess` (a piece index, or -1): where the span lies in that
  // piece (a point that moved a little since it was last located) no search.
  int find_piece(double s, int guess) const;
  // Whether find_piece gives piece `pi` at every point within `margin` of s (pi's planes
  // farther than margin plus find_piece's own rounding allowance from s).
  bool inside_piece(double s, int pi, double margin) const;

  // Weights and d/ds of the terms of piece `pi` at s (arrays of kMaxTerms).
  void weights(int pi, double s, double* w, double* dw) const;

 private:
  void finish();  // merge duplicate indices, drop zero terms, merge equal constant pieces
  int n_ctrl_ = 0;
  int degree_ = 0;
  double extent_ = 1.0;  // from the first to the last plane (1 with fewer than two planes)
  std::vector<AxisPiece> pieces_;
};

inline int AxisBasis::find_piece(double s) const { return find_piece(s, -1); }

// Inline: plan builds locate every sample (millions) with it.
inline int AxisBasis::find_piece(double s, int guess) const {
  const int last = (int)pieces_.size() - 1;
  int lo = 0;
  if (guess >= 0 && guess <= last && pieces_[guess].lo <= s && (guess == last || s < pieces_[guess + 1].lo)) {
    lo = guess;  // the last piece with pieces_[i].lo <= s, as the search finds it
  } else {
    int hi = last;
    while (lo < hi) {  // last piece with pieces_[i].lo <= s
      int mid = (lo + hi + 1) / 2;
      if (pieces_[mid].lo <= s) lo = mid; else hi = mid - 1;
    }
  }
  // Within rounding of a plane counts as on it (and takes the piece above, as Blender's floor
  // does for exact values), except on the top of the polynomial range, which takes the piece
  // inside: vertices fitted to a lattice's or a box's faces get the one-sided inner Jacobian,
  // whatever the rounding of s = A p + b.
  // Rounding of s = A p + b in double is about 1e-16 |s|; 1e-9 of the axis's polynomial range
  // on top (not 1e-9 |s|: with knots shifted to 1e7 that took points 0.01 off a plane as on it,
  // and extrapolated the next piece's polynomial there, 3e-4 off in a lattice 2 wide).
  const double eps = 1e-9 * extent_ + 8 * std::numeric_limits<double>::epsilon() * std::abs(s);
  if (lo < last && pieces_[lo + 1].lo - s <= eps) ++lo;
  if (lo == last && lo > 0 && pieces_[lo].degree == 0 && pieces_[lo - 1].degree > 0 &&
      s - pieces_[lo].lo <= eps)
    --lo;
  return lo;
}

inline bool AxisBasis::inside_piece(double s, int pi, double margin) const {
  const int last = (int)pieces_.size() - 1;
  if (pi < 0 || pi > last || !(margin >= 0)) return false;
  // find_piece's allowance at any point within margin of s.
  const double eps = 1e-9 * extent_ + 8 * std::numeric_limits<double>::epsilon() * (std::abs(s) + margin);
  if (pi > 0 && !(s - margin - pieces_[pi].lo > eps)) return false;  // also its degree-0 top rule
  if (pi < last && !(pieces_[pi + 1].lo - (s + margin) > eps)) return false;
  return true;
}

}  // namespace sffd
