#include "smoothffd/plan/clip.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <optional>
#include <tuple>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/core/parallel.hpp"

namespace sffd {
namespace {

// The knot planes of each axis (ascending), how close to one a vertex counts as on it, and
// how many parameter units an object unit is along each axis.
struct KnotPlanes {
  std::array<std::vector<double>, 3> planes;
  double floor_tol[3] = {0, 0, 0};
  double grad[3] = {0, 0, 0};
};

KnotPlanes knot_planes(const LatticeSpec& lattice) {
  KnotPlanes k;
  for (int a = 0; a < 3; ++a) {
    const std::vector<double>& pl = k.planes[a] = lattice.axes[a].planes();
    // Vertices this close to a plane count as on it: meshes made in float32 (Blender's) put
    // "on-plane" vertices some 1e-8 off it, and cutting there would leave near-duplicate clip
    // vertices and zero-area slivers. 1e-5 of the smallest knot spacing is far below anything
    // visible and far above float32 noise.
    double spacing = 1.0;
    for (size_t i = 1; i < pl.size(); ++i) spacing = std::min(spacing, pl[i] - pl[i - 1]);
    double mag = pl.empty() ? 0.0 : std::max(std::fabs(pl.front()), std::fabs(pl.back()));
    // The second term is the rounding of s = A p + b in double, which grows with |s| (knots
    // far from 0), plus 1e-12 of the planes' extent: no larger for shifted knots.
    const double extent = pl.size() > 1 ? pl.back() - pl.front() : 1.0;
    k.floor_tol[a] = std::max(1e-5 * spacing, 1e-12 * extent + 16 * std::numeric_limits<double>::epsilon() * mag);
    const double* A = lattice.object_to_param[a];
    k.grad[a] = std::sqrt(A[0] * A[0] + A[1] * A[1] + A[2] * A[2]);
  }
  return k;
}

struct PolyVertex {
  int id;
  double bary[3];  // in the triangle being clipped
};

using Poly = std::vector<PolyVertex>;

struct Clipper {
  const LatticeSpec& lattice;
  ClipResult& out;
  std::vector<double> param;  // #SV x 3: parameter-space position of every sub-vertex
  std::vector<double> reach;  // #SV x 3: snap distance in parameter units, per axis
  std::map<std::tuple<int, int, int, int>, int> cut_vertex;  // (lo id, hi id, axis, plane)
  double floor_tol[3] = {0, 0, 0};  // parameter units: rounding noise of "on the plane"
  double grad[3] = {0, 0, 0};       // |ds_a/dp|: parameter units per object unit
  int inputs = 0;                   // V: sub-vertices [0, V) are the input vertices
  std::array<std::vector<double>, 3> planes;  // the knot planes of each axis, ascending
  std::vector<int> ring_start, ring;  // input vertex -> its neighbours in the triangles (CSR)
  std::vector<double> ring_length;    // the length of each of those edges

  const double* s(int id) const { return &param[3 * (size_t)id]; }

  // Sets the snap distance of sub-vertex id (object units), its per-axis reach in parameter
  // units, and the bound ClipResult::snap reports (at least the distance).
  void set_snap(int id, double dist, double bound) {
    out.snap[id] = std::max(dist, bound);
    for (int a = 0; a < 3; ++a) reach[3 * (size_t)id + a] = std::max(floor_tol[a], dist * grad[a]);
  }

  // Side of sub-vertex id of the plane s_a = c: -1, +1, or 0 where it counts as on the plane.
  // Within rounding; else, where may_snap allows (the plane of axis a nearest to the vertex
  // only: snapping a fan of planes onto one vertex would make needles of the pieces between
  // them; and within a quarter of that plane's gap to the next), input vertices when the plane
  // crosses one of their edges within kClipEdgeSnap of its length from them or runs along one
  // within that, clip vertices within their snap distance.
  int side_of(int id, int a, double c) const {
    const double d = s(id)[a] - c;
    if (std::fabs(d) <= floor_tol[a]) return 0;
    const int side = d < 0 ? -1 : 1;
    if (!may_snap(a, s(id)[a], c)) return side;
    if (id >= inputs) return std::fabs(d) <= reach[3 * (size_t)id + a] ? 0 : side;
    for (int i = ring_start[id]; i < ring_start[id + 1]; ++i) {
      const double dw = s(ring[i])[a] - c;
      // The plane crosses the edge near this end ...
      if ((dw < 0) != (d < 0) && std::fabs(dw) > floor_tol[a] && std::fabs(d) < kClipEdgeSnap * std::fabs(dw - d))
        return 0;
      // ... or runs along it: both ends within kClipEdgeSnap of its length (a thin strip).
      const double len = ring_length[i] * grad[a] * kClipEdgeSnap;
      if (std::fabs(d) < len && std::fabs(dw) < len) return 0;
    }
    return side;
  }

  // Whether a vertex at parameter value x may snap to plane c of axis a: c is the plane
  // nearest to x (ties: the lower), and x lies within a quarter of c's distance to its
  // neighbouring planes, so a piece never reaches across more than a quarter of a knot span
  // (planes closer together than that, as knots of high multiplicity spread by rounding, are
  // kept apart: the deformation may change fast between them).
  bool may_snap(int a, double x, double c) const {
    const std::vector<double>& pl = planes[a];
    auto it = std::lower_bound(pl.begin(), pl.end(), x);
    double best = INFINITY, at = 0;
    if (it != pl.end()) best = *it - x, at = *it;
    if (it != pl.begin() && x - *(it - 1) <= best) at = *(it - 1);
    if (at != c) return false;
    auto ci = std::lower_bound(pl.begin(), pl.end(), c);
    double gap = INFINITY;
    if (ci != pl.begin()) gap = c - *(ci - 1);
    if (ci + 1 != pl.end()) gap = std::min(gap, *(ci + 1) - c);
    return std::fabs(x - c) <= 0.25 * gap;
  }

  // The vertex where the segment u-v crosses plane `pi` (value c) of axis a. Computed from the
  // lower id so both sides of a shared segment compute (and find) the same vertex.
  PolyVertex crossing(const PolyVertex& p, const PolyVertex& q, int a, int pi, double c, int tri) {
    const PolyVertex& u = p.id < q.id ? p : q;
    const PolyVertex& v = p.id < q.id ? q : p;
    double tau = (c - s(u.id)[a]) / (s(v.id)[a] - s(u.id)[a]);
    PolyVertex x;
    for (int i = 0; i < 3; ++i) x.bary[i] = u.bary[i] + tau * (v.bary[i] - u.bary[i]);
    auto key = std::make_tuple(u.id, v.id, a, pi);
    auto it = cut_vertex.find(key);
    if (it != cut_vertex.end()) {
      x.id = it->second;
      return x;
    }
    x.id = out.sub_vertices();
    cut_vertex.emplace(key, x.id);
    double len2 = 0;
    for (int i = 0; i < 3; ++i) {
      double fu = out.flat[3 * (size_t)u.id + i], fv = out.flat[3 * (size_t)v.id + i];
      out.flat.push_back(fu + tau * (fv - fu));
      len2 += (fv - fu) * (fv - fu);
      double su = s(u.id)[i], sv = s(v.id)[i];
      param.push_back(i == a ? c : su + tau * (sv - su));
      out.origin_bary.push_back(x.bary[i]);
    }
    out.origin_tri.push_back(tri);
    out.snap.push_back(0);
    reach.resize(3 * (size_t)out.sub_vertices());
    // Its own snap: of the segment it splits. A segment between vertices that were snapped to a
    // plane lies off it by as much as they do: the bound is inherited.
    set_snap(x.id, kClipSnap * std::sqrt(len2), std::max(out.snap[u.id], out.snap[v.id]));
    return x;
  }

  // Sutherland-Hodgman split of a convex polygon by the plane s_a = c. Vertices within their
  // snap distance of the plane belong to both halves; a polygon lying in the plane stays whole
  // (below).
  void split(const Poly& poly, int a, int pi, double c, int tri, std::vector<Poly>& result) {
    Poly below, above;
    bool has_below = false, has_above = false;
    int n = (int)poly.size();
    auto side = [&](const PolyVertex& v) { return side_of(v.id, a, c); };
    std::vector<int> sd(n);
    for (int i = 0; i < n; ++i) sd[i] = side(poly[i]);
    for (int i = 0; i < n; ++i) {
      const PolyVertex& cur = poly[i];
      const PolyVertex& nxt = poly[(i + 1) % n];
      int sc = sd[i], sn = sd[(i + 1) % n];
      has_below |= sc < 0;
      has_above |= sc > 0;
      // A vertex on the plane goes to both halves. Snapped vertices sit up to their snap
      // distance off the plane, so a (nearly convex) piece can also touch the plane at a run of
      // vertices and cross it elsewhere, or have two consecutive vertices on it with the piece
      // on both sides: a run whose nearest off-plane neighbours lie on one side belongs to that
      // side's half only; a run between the two sides goes whole to the side after it, and its
      // first vertex also to the side before it (where the cut starts).
      int to = 0;
      if (sc == 0) {
        int before = 0, after = 0;
        for (int j = 1; j < n && !before; ++j) before = sd[(i + n - j) % n];
        for (int j = 1; j < n && !after; ++j) after = sd[(i + j) % n];
        if (before == after) to = before;
        else if (sd[(i + n - 1) % n] == 0) to = after;
      }
      if (sc < 0 || (sc == 0 && to <= 0)) below.push_back(cur);
      if (sc > 0 || (sc == 0 && to >= 0)) above.push_back(cur);
      if (sc * sn < 0) {
        PolyVertex x = crossing(cur, nxt, a, pi, c, tri);
        below.push_back(x);
        above.push_back(x);
      }
    }
    if ((has_below || !has_above) && below.size() >= 3) result.push_back(below);
    if (has_above && above.size() >= 3) result.push_back(above);
  }

  void emit(const PolyVertex& p, const PolyVertex& q, const PolyVertex& r, int tri) {
    for (const PolyVertex* v : {&p, &q, &r}) {
      out.patch_vertex.push_back(v->id);
      for (int i = 0; i < 3; ++i) out.patch_bary.push_back(v->bary[i]);
    }
    out.patch_tri.push_back(tri);
  }

  // Triangulates a convex piece (which may carry collinear clip points on its sides) by
  // cutting, each time, the ear with the best shape among those whose diagonal leaves every
  // other vertex strictly inside: no slivers, no T-junctions.
  // The hint's triangles of `tri` (ClipHint), hint_start[tri] .. hint_start[tri + 1].
  const ClipHint* hint = nullptr;
  std::vector<int> hint_start;

  // Cuts the piece into the hint's triangles over the very same sub-vertices, where there are
  // n - 2 of them and each has an area over eps in the current shape.
  bool triangulate_as_hinted(const Poly& ring, int tri, double eps, const std::function<double(const PolyVertex&, const PolyVertex&, const PolyVertex&)>& area) {
    if (!hint || tri + 1 >= (int)hint_start.size()) return false;
    const int n = (int)ring.size();
    auto at = [&](int id) {
      for (int i = 0; i < n; ++i)
        if (ring[i].id == id) return i;
      return -1;
    };
    std::vector<std::array<int, 3>> tris;
    for (int q = hint_start[tri]; q < hint_start[tri + 1]; ++q) {
      std::array<int, 3> k;
      for (int c = 0; c < 3; ++c) k[c] = at(hint->patch_vertex[3 * (size_t)q + c]);
      if (k[0] < 0 || k[1] < 0 || k[2] < 0) continue;
      if (!(area(ring[k[0]], ring[k[1]], ring[k[2]]) > eps)) return false;
      tris.push_back(k);
    }
    if ((int)tris.size() != n - 2) return false;
    for (const auto& k : tris) emit(ring[k[0]], ring[k[1]], ring[k[2]], tri);
    return true;
  }

  void triangulate(Poly ring, const double* nrm, int tri) {
    auto P = [&](const PolyVertex& v) { return &out.flat[3 * (size_t)v.id]; };
    auto area = [&](const PolyVertex& a, const PolyVertex& b, const PolyVertex& c) {
      const double *pa = P(a), *pb = P(b), *pc = P(c);
      double u[3] = {pb[0] - pa[0], pb[1] - pa[1], pb[2] - pa[2]};
      double w[3] = {pc[0] - pa[0], pc[1] - pa[1], pc[2] - pa[2]};
      return (u[1] * w[2] - u[2] * w[1]) * nrm[0] + (u[2] * w[0] - u[0] * w[2]) * nrm[1] +
             (u[0] * w[1] - u[1] * w[0]) * nrm[2];
    };
    auto d2 = [&](const PolyVertex& a, const PolyVertex& b) {
      const double *pa = P(a), *pb = P(b);
      return (pa[0] - pb[0]) * (pa[0] - pb[0]) + (pa[1] - pb[1]) * (pa[1] - pb[1]) +
             (pa[2] - pb[2]) * (pa[2] - pb[2]);
    };
    double diam2 = 0;
    for (const PolyVertex& v : ring) diam2 = std::max(diam2, d2(v, ring[0]));
    double eps = 1e-12 * diam2;
    if (ring.size() > 3 && triangulate_as_hinted(ring, tri, eps, area)) return;
    while (ring.size() > 3) {
      int n = (int)ring.size(), best = -1;
      double best_q = -1, most = -INFINITY;
      int most_i = 0;
      for (int i = 0; i < n; ++i) {
        const PolyVertex &a = ring[(i + n - 1) % n], &b = ring[i], &c = ring[(i + 1) % n];
        double ar = area(a, b, c);
        if (ar > most) { most = ar; most_i = i; }
        if (ar <= eps) continue;
        bool ok = true;
        for (int j = 0; j < n && ok; ++j) {
          if (j == i || j == (i + 1) % n || j == (i + n - 1) % n) continue;
          ok = area(a, c, ring[j]) > eps;
        }
        if (!ok) continue;
        double q = ar / (d2(a, b) + d2(b, c) + d2(c, a));
        if (q > best_q) { best_q = q; best = i; }
      }
      if (best < 0) best = most_i;  // degenerate (zero-area) piece: any consistent split
      emit(ring[(best + n - 1) % n], ring[best], ring[(best + 1) % n], tri);
      ring.erase(ring.begin() + best);
    }
    emit(ring[0], ring[1], ring[2], tri);
  }
};

}  // namespace

ClipResult clip_to_knot_boxes(const std::vector<double>& X, const std::vector<int>& tv,
                              const LatticeSpec& lattice, const ClipHint* hint) {
  ClipResult out;
  int V = (int)(X.size() / 3), T = (int)(tv.size() / 3);
  out.flat = X;
  out.origin_tri.assign(V, -1);
  out.origin_bary.assign(3 * (size_t)V, 0.0);
  out.snap.assign(V, 0.0);
  Clipper c{lattice, out, {}, {}, {}};
  if (hint) {
    c.hint = hint;
    c.hint_start.assign(T + 1, 0);
    for (int t : hint->patch_tri)
      if (t >= 0 && t < T) c.hint_start[t + 1]++;
    for (int t = 0; t < T; ++t) c.hint_start[t + 1] += c.hint_start[t];
    // The hint's pieces come in triangle order (as this function emits them), else none is used.
    if (!std::is_sorted(hint->patch_tri.begin(), hint->patch_tri.end()) ||
        hint->patch_vertex.size() != 3 * hint->patch_tri.size() || c.hint_start[T] != (int)hint->patch_tri.size())
      c.hint = nullptr;
  }
  c.param.resize(3 * (size_t)V);
  c.reach.resize(3 * (size_t)V);
  for (int v = 0; v < V; ++v) lattice.to_param(&X[3 * (size_t)v], &c.param[3 * (size_t)v]);
  std::array<std::vector<double>, 3>& planes = c.planes;
  const KnotPlanes kp = knot_planes(lattice);
  for (int a = 0; a < 3; ++a) {
    planes[a] = kp.planes[a];
    c.floor_tol[a] = kp.floor_tol[a];
    c.grad[a] = kp.grad[a];
  }
  // Input vertices: their neighbours (for side_of) and their snap distance, which only the
  // tests read (ClipResult::snap): kClipEdgeSnap of their longest edge.
  c.inputs = V;
  {
    std::vector<double> longest(V, 0.0);
    c.ring_start.assign(V + 1, 0);
    for (int t = 0; t < T; ++t)
      for (int k = 0; k < 3; ++k) c.ring_start[tv[3 * t + k] + 1] += 2;
    for (int v = 0; v < V; ++v) c.ring_start[v + 1] += c.ring_start[v];
    c.ring.resize(c.ring_start[V]);
    c.ring_length.resize(c.ring_start[V]);
    std::vector<int> fill(c.ring_start.begin(), c.ring_start.end() - 1);
    for (int t = 0; t < T; ++t)
      for (int k = 0; k < 3; ++k) {
        int u = tv[3 * t + k], w = tv[3 * t + (k + 1) % 3];
        double d2 = 0;
        for (int i = 0; i < 3; ++i) d2 += (X[3 * (size_t)u + i] - X[3 * (size_t)w + i]) * (X[3 * (size_t)u + i] - X[3 * (size_t)w + i]);
        c.ring_length[fill[u]] = c.ring_length[fill[w]] = std::sqrt(d2);
        c.ring[fill[u]++] = w;
        c.ring[fill[w]++] = u;
        longest[u] = std::max(longest[u], d2);
        longest[w] = std::max(longest[w], d2);
      }
    for (int v = 0; v < V; ++v) c.set_snap(v, 0.0, kClipEdgeSnap * std::sqrt(longest[v]));
  }
  std::vector<Poly> polys, next;
  CancelPoller poller(1024);
  for (int t = 0; t < T; ++t) {
    poller.tick();
    polys.assign(1, Poly(3));
    for (int k = 0; k < 3; ++k) {
      polys[0][k].id = tv[3 * t + k];
      for (int i = 0; i < 3; ++i) polys[0][k].bary[i] = (i == k);
    }
    bool clipped = false;
    for (int a = 0; a < 3; ++a) {
      double lo = INFINITY, hi = -INFINITY;
      for (int k = 0; k < 3; ++k) {
        lo = std::min(lo, c.s(tv[3 * t + k])[a]);
        hi = std::max(hi, c.s(tv[3 * t + k])[a]);
      }
      for (int pi = 0; pi < (int)planes[a].size(); ++pi) {
        double v = planes[a][pi];
        if (!(v > lo && v < hi)) continue;  // split() decides, with each vertex's snap
        next.clear();
        poller.tick();
        for (const Poly& p : polys) c.split(p, a, pi, v, t, next);
        polys.swap(next);
        clipped = true;
      }
    }
    if (!clipped) {
      c.emit(polys[0][0], polys[0][1], polys[0][2], t);
      continue;
    }
    const double *p0 = &X[3 * (size_t)tv[3 * t]], *p1 = &X[3 * (size_t)tv[3 * t + 1]],
                 *p2 = &X[3 * (size_t)tv[3 * t + 2]];
    double u[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    double w[3] = {p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2]};
    double nrm[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    double l = std::sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
    for (double& x : nrm) x = l > 0 ? x / l : 0.0;
    for (const Poly& p : polys) {
      poller.tick();
      c.triangulate(p, nrm, t);
    }
  }
  return out;
}

std::optional<ClipResult> hold_clip(const std::vector<double>& X, const std::vector<int>& tv,
                                    const LatticeSpec& lattice, const ClipHold& held, bool check) {
  const int V = (int)(X.size() / 3), T = (int)(tv.size() / 3), P = (int)held.patch_tri.size();
  int SV = V;
  for (int v : held.patch_vertex) SV = std::max(SV, v + 1);
  if (held.patch_vertex.size() != 3 * (size_t)P || held.patch_bary.size() != 9 * (size_t)P) return std::nullopt;
  ClipResult out;
  out.origin_tri.assign(SV, -1);
  out.origin_bary.assign(3 * (size_t)SV, 0.0);
  // Each clip vertex from the first piece that has it: the lowest triangle with it, where
  // clip_to_knot_boxes made it (pieces come in triangle order).
  for (int p = 0; p < P; ++p) {
    const int t = held.patch_tri[p];
    if (t < 0 || t >= T) return std::nullopt;
    for (int c = 0; c < 3; ++c) {
      const int v = held.patch_vertex[3 * (size_t)p + c];
      if (v < V || out.origin_tri[v] >= 0) continue;
      out.origin_tri[v] = t;
      for (int i = 0; i < 3; ++i) out.origin_bary[3 * (size_t)v + i] = held.patch_bary[9 * (size_t)p + 3 * c + i];
    }
  }
  out.flat.resize(3 * (size_t)SV);
  std::copy(X.begin(), X.end(), out.flat.begin());
  for (int v = V; v < SV; ++v) {
    const int t = out.origin_tri[v];
    if (t < 0) return std::nullopt;  // a sub-vertex no piece has
    for (int i = 0; i < 3; ++i) {
      double x = 0;
      for (int k = 0; k < 3; ++k) x += out.origin_bary[3 * (size_t)v + k] * X[3 * (size_t)tv[3 * t + k] + i];
      out.flat[3 * (size_t)v + i] = x;
    }
  }
  // Every piece still in one knot box: each corner past the box's planes by at most the snap
  // distance of the piece's triangle's corners (kClipEdgeSnap of their longest edge, the most a
  // fresh clipping's pieces reach past a plane there), or where the box's polynomial piece,
  // continued to the corner, weighs the control points within kHoldKink of the piece the
  // corner lies in.
  std::vector<double> longest(V, 0.0);
  for (int t = 0; t < T; ++t)
    for (int k = 0; k < 3; ++k) {
      const int u = tv[3 * t + k], w = tv[3 * t + (k + 1) % 3];
      double d2 = 0;
      for (int i = 0; i < 3; ++i) d2 += (X[3 * (size_t)u + i] - X[3 * (size_t)w + i]) * (X[3 * (size_t)u + i] - X[3 * (size_t)w + i]);
      longest[u] = std::max(longest[u], d2);
      longest[w] = std::max(longest[w], d2);
    }
  out.snap.assign(SV, 0.0);  // ClipResult::snap: the reach of the vertex's pieces
  std::vector<double> piece_snap(P);
  for (int p = 0; p < P; ++p) {
    const int t = held.patch_tri[p];
    double d2 = 0;
    for (int k = 0; k < 3; ++k) d2 = std::max(d2, longest[tv[3 * t + k]]);
    piece_snap[p] = kClipEdgeSnap * std::sqrt(d2);
    for (int c = 0; c < 3; ++c) {
      double& sn = out.snap[held.patch_vertex[3 * (size_t)p + c]];
      sn = std::max(sn, piece_snap[p]);
    }
  }
  const KnotPlanes kp = knot_planes(lattice);
  std::vector<double> param(3 * (size_t)SV);
  parallel_for(SV, default_threads(), [&](long long b, long long e) {
    for (long long v = b; v < e; ++v) lattice.to_param(&out.flat[3 * (size_t)v], &param[3 * (size_t)v]);
  });
  // How far the weights of the box's polynomial piece, continued to s, are from those of the
  // piece s lies in: the sum over control points of the weights' differences.
  auto kink = [&](const AxisBasis& axis, int box, double s) {
    const int at = axis.find_piece(s);
    if (at == box) return 0.0;
    double wb[kMaxTerms], wt[kMaxTerms], dw[kMaxTerms];
    axis.weights(box, s, wb, dw);
    axis.weights(at, s, wt, dw);
    const AxisPiece &pb = axis.pieces()[box], &pt = axis.pieces()[at];
    double sum = 0;
    for (int k = 0; k < pb.count; ++k) {
      double d = wb[k];
      for (int m = 0; m < pt.count; ++m)
        if (pt.index[m] == pb.index[k]) d -= wt[m];
      sum += std::fabs(d);
    }
    for (int m = 0; m < pt.count; ++m) {
      bool shared = false;
      for (int k = 0; k < pb.count; ++k) shared |= pb.index[k] == pt.index[m];
      if (!shared) sum += std::fabs(wt[m]);
    }
    return sum;
  };
  std::atomic<bool> left{false};  // a piece left its box
  if (check) parallel_for(P, default_threads(), [&](long long pb, long long pe) {
    for (long long p = pb; p < pe && !left.load(std::memory_order_relaxed); ++p) {
      const int* pv = &held.patch_vertex[3 * (size_t)p];
      for (int a = 0; a < 3; ++a) {
        const AxisBasis& axis = lattice.axes[a];
        double s[3];
        for (int c = 0; c < 3; ++c) s[c] = param[3 * (size_t)pv[c] + a];
        // The box: that of its centroid, its lowest or its highest corner, whichever the piece
        // fits (a piece along a plane may lie in either box, one between two planes has its
        // corners on them). Within the snap distance (at most a quarter of the box's span, as
        // may_snap) a corner needs no check.
        auto fits = [&](int box) {
          const AxisPiece& piece = axis.pieces()[box];
          const double reach = kp.floor_tol[a] + std::min(piece_snap[p] * kp.grad[a], 0.25 * (piece.hi - piece.lo));
          for (int c = 0; c < 3; ++c)
            if (!(s[c] >= piece.lo - reach && s[c] <= piece.hi + reach) && kink(axis, box, s[c]) > kHoldKink) return false;
          return true;
        };
        const int mid = axis.find_piece((s[0] + s[1] + s[2]) / 3);
        const int lo = axis.find_piece(std::min({s[0], s[1], s[2]})), hi = axis.find_piece(std::max({s[0], s[1], s[2]}));
        if (!fits(mid) && (lo == mid || !fits(lo)) && (hi == mid || hi == lo || !fits(hi))) {
          left.store(true);
          return;
        }
      }
    }
  });
  if (left.load()) return std::nullopt;
  out.patch_vertex = held.patch_vertex;
  out.patch_tri = held.patch_tri;
  out.patch_bary = held.patch_bary;
  return out;
}

}  // namespace sffd
