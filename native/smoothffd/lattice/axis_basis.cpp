#include "smoothffd/lattice/axis_basis.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>

namespace sffd {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Values of the p + 1 B-spline basis functions that are non-zero on knot span `span`
// (knots[span] <= u < knots[span + 1]), as the polynomial of that span evaluated at any u.
// The NURBS Book, algorithm A2.2; out[r] belongs to control point span - p + r.
void span_basis(const std::vector<double>& U, int span, int p, double u, double* out) {
  double left[kMaxTerms + 1], right[kMaxTerms + 1];
  out[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[span + 1 - j];
    right[j] = U[span + j] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      double tmp = out[r] / (right[r + 1] + left[j - r]);
      out[r] = saved + right[r + 1] * tmp;
      saved = left[j - r] * tmp;
    }
    out[j] = saved;
  }
}

AxisPiece constant_piece(double lo, double hi, const double* w, int first_index, int count) {
  AxisPiece pc;
  pc.lo = lo;
  pc.hi = hi;
  pc.count = count;
  for (int k = 0; k < count; ++k) {
    pc.index[k] = first_index + k;
    pc.coef[k][0] = w[k];
  }
  return pc;
}

}  // namespace

BlenderInterp parse_blender_interp(const std::string& name) {
  if (name == "LINEAR" || name == "KEY_LINEAR") return BlenderInterp::Linear;
  if (name == "CARDINAL" || name == "KEY_CARDINAL") return BlenderInterp::Cardinal;
  if (name == "CATMULL_ROM" || name == "KEY_CATMULL_ROM") return BlenderInterp::CatmullRom;
  if (name == "BSPLINE" || name == "KEY_BSPLINE") return BlenderInterp::BSpline;
  throw std::invalid_argument("interpolation: unknown type '" + name +
                              "' (expected LINEAR, CARDINAL, CATMULL_ROM or BSPLINE)");
}

AxisBasis AxisBasis::bspline(int p, const std::vector<double>& U, int n) {
  if (p < 1 || p > kMaxAxisDegree)
    throw std::invalid_argument("degree: must be between 1 and 5, got " + std::to_string(p));
  if (n < p + 1)
    throw std::invalid_argument("control_points: an axis of degree " + std::to_string(p) +
                                " needs at least " + std::to_string(p + 1) + " points");
  if ((int)U.size() != n + p + 1)
    throw std::invalid_argument("knots: expected " + std::to_string(n + p + 1) + " values");
  for (size_t i = 0; i + 1 < U.size(); ++i)
    if (!(U[i] <= U[i + 1])) throw std::invalid_argument("knots: must be non-decreasing");
  if (!(U[p] < U[n])) throw std::invalid_argument("knots: the domain [knots[p], knots[n]] is empty");

  AxisBasis ab;
  ab.n_ctrl_ = n;
  double w[kMaxTerms];
  // Below the domain: the boundary weights continue (displacement of the nearest box point).
  int first_span = p;
  while (!(U[first_span] < U[first_span + 1])) ++first_span;
  span_basis(U, first_span, p, U[p], w);
  ab.pieces_.push_back(constant_piece(-kInf, U[p], w, first_span - p, p + 1));
  int last_span = first_span;
  for (int span = first_span; span < n; ++span) {
    double a = U[span], b = U[span + 1];
    if (!(a < b)) continue;
    last_span = span;
    // Power-basis coefficients of the span's polynomials by interpolation at p + 1 nodes of
    // the local parameter t in [0, 1] (double precision, degree <= 5: well conditioned).
    Eigen::MatrixXd V(p + 1, p + 1), N(p + 1, p + 1);
    for (int k = 0; k <= p; ++k) {
      double t = double(k) / p;
      span_basis(U, span, p, a + t * (b - a), w);
      for (int q = 0; q <= p; ++q) V(k, q) = std::pow(t, q);
      for (int r = 0; r <= p; ++r) N(k, r) = w[r];
    }
    Eigen::MatrixXd C = V.fullPivLu().solve(N);  // C(q, r): coefficient of t^q of term r
    AxisPiece pc;
    pc.lo = a;
    pc.hi = b;
    pc.origin = a;
    pc.scale = b - a;
    pc.count = p + 1;
    for (int r = 0; r <= p; ++r) {
      pc.index[r] = span - p + r;
      for (int q = 0; q <= p; ++q) pc.coef[r][q] = C(q, r);
    }
    ab.pieces_.push_back(pc);
  }
  span_basis(U, last_span, p, U[n], w);
  ab.pieces_.push_back(constant_piece(U[n], kInf, w, last_span - p, p + 1));
  ab.finish();
  return ab;
}

AxisBasis AxisBasis::blender(BlenderInterp type, int n) {
  if (n < 1) throw std::invalid_argument("points: every axis needs at least one point");
  AxisBasis ab;
  ab.n_ctrl_ = n;
  if (n == 1) {
    double one = 1.0;
    ab.pieces_.push_back(constant_piece(-kInf, kInf, &one, 0, 1));
    ab.finish();
    return ab;
  }
  // key_curve_position_weights: rows are the terms t0..t3, columns the powers t^0..t^3.
  double c[4][4] = {};
  auto cardinal = [&](double fc) {
    double rows[4][4] = {{0, -fc, 2 * fc, -fc},
                         {1, 0, fc - 3, 2 - fc},
                         {0, fc, 3 - 2 * fc, fc - 2},
                         {0, 0, -fc, fc}};
    std::copy(&rows[0][0], &rows[0][0] + 16, &c[0][0]);
  };
  switch (type) {
    case BlenderInterp::Linear: {
      double rows[4][4] = {{0, 0, 0, 0}, {1, -1, 0, 0}, {0, 1, 0, 0}, {0, 0, 0, 0}};
      std::copy(&rows[0][0], &rows[0][0] + 16, &c[0][0]);
      break;
    }
    case BlenderInterp::Cardinal: cardinal(0.71); break;
    case BlenderInterp::CatmullRom: cardinal(0.5); break;
    case BlenderInterp::BSpline: {
      double rows[4][4] = {{1.0 / 6, -0.5, 0.5, -1.0 / 6},
                           {2.0 / 3, 0, -1, 0.5},
                           {1.0 / 6, 0.5, 0.5, -0.5},
                           {0, 0, 0, 1.0 / 6}};
      std::copy(&rows[0][0], &rows[0][0] + 16, &c[0][0]);
      break;
    }
  }
  // Cell i0 = floor(s) covers [i0, i0 + 1); its stencil is i0 - 1 .. i0 + 2, clamped. Cells
  // below -1 and from n on have all four indices clamped to one point: constant.
  for (int i0 = -2; i0 <= n; ++i0) {
    AxisPiece pc;
    pc.lo = (i0 == -2) ? -kInf : double(i0);
    pc.hi = (i0 == n) ? kInf : double(i0 + 1);
    pc.origin = i0;
    pc.scale = 1.0;
    pc.count = 4;
    for (int k = 0; k < 4; ++k) {
      pc.index[k] = std::min(std::max(i0 - 1 + k, 0), n - 1);
      for (int q = 0; q < 4; ++q) pc.coef[k][q] = c[k][q];
    }
    ab.pieces_.push_back(pc);
  }
  ab.finish();
  return ab;
}

void AxisBasis::finish() {
  for (AxisPiece& pc : pieces_) {
    AxisPiece m = pc;
    m.count = 0;
    for (int k = 0; k < kMaxTerms; ++k)
      for (int q = 0; q < kMaxTerms; ++q) m.coef[k][q] = 0.0;
    for (int k = 0; k < pc.count; ++k) {
      int slot = 0;
      while (slot < m.count && m.index[slot] != pc.index[k]) ++slot;
      if (slot == m.count) m.index[m.count++] = pc.index[k];
      for (int q = 0; q < kMaxTerms; ++q) m.coef[slot][q] += pc.coef[k][q];
    }
    // Drop terms that vanish on the piece and find the degree actually used.
    AxisPiece out = m;
    out.count = 0;
    out.degree = 0;
    for (int k = 0; k < m.count; ++k) {
      bool any = false;
      for (int q = 0; q < kMaxTerms; ++q) {
        if (std::abs(m.coef[k][q]) > 1e-13) {
          any = true;
          out.degree = std::max(out.degree, q);
        } else {
          m.coef[k][q] = 0.0;
        }
      }
      if (!any) continue;
      out.index[out.count] = m.index[k];
      for (int q = 0; q < kMaxTerms; ++q) out.coef[out.count][q] = m.coef[k][q];
      ++out.count;
    }
    for (int k = out.count; k < kMaxTerms; ++k)
      for (int q = 0; q < kMaxTerms; ++q) out.coef[k][q] = 0.0;
    pc = out;
  }
  // Merge neighbours that are the same constant: they need no plane between them.
  std::vector<AxisPiece> merged;
  for (const AxisPiece& pc : pieces_) {
    if (!merged.empty()) {
      AxisPiece& prev = merged.back();
      bool same = prev.degree == 0 && pc.degree == 0 && prev.count == pc.count;
      for (int k = 0; same && k < pc.count; ++k)
        same = prev.index[k] == pc.index[k] && std::abs(prev.coef[k][0] - pc.coef[k][0]) < 1e-13;
      if (same) {
        prev.hi = pc.hi;
        continue;
      }
    }
    merged.push_back(pc);
  }
  pieces_ = merged;
  extent_ = pieces_.size() > 2 ? pieces_.back().lo - pieces_[1].lo : 1.0;
  if (!(extent_ > 0) || !std::isfinite(extent_)) extent_ = 1.0;
  degree_ = 0;
  for (const AxisPiece& pc : pieces_) degree_ = std::max(degree_, pc.degree);
}

std::vector<double> AxisBasis::planes() const {
  std::vector<double> out;
  for (size_t i = 1; i < pieces_.size(); ++i) out.push_back(pieces_[i].lo);
  return out;
}

void AxisBasis::weights(int pi, double s, double* w, double* dw) const {
  const AxisPiece& pc = pieces_[pi];
  double t = pc.degree == 0 ? 0.0 : (s - pc.origin) / pc.scale;
  for (int k = 0; k < pc.count; ++k) {
    double v = 0.0, d = 0.0;
    for (int q = pc.degree; q >= 0; --q) {  // Horner for the value and the derivative
      d = d * t + v;
      v = v * t + pc.coef[k][q];
    }
    w[k] = v;
    dw[k] = d / pc.scale;
  }
}

}  // namespace sffd
