#include "smoothffd/plan/clip.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <tuple>

#include "smoothffd/core/cancel.hpp"

namespace sffd {
namespace {

struct PolyVertex {
  int id;
  double bary[3];  // in the triangle being clipped
};

using Poly = std::vector<PolyVertex>;

struct Clipper {
  const LatticeSpec& lattice;
  ClipResult& out;
  std::vector<double> param;  // #SV x 3: parameter-space position of every sub-vertex
  std::map<std::tuple<int, int, int, int>, int> cut_vertex;  // (lo id, hi id, axis, plane)

  const double* s(int id) const { return &param[3 * (size_t)id]; }

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
    for (int i = 0; i < 3; ++i) {
      double fu = out.flat[3 * (size_t)u.id + i], fv = out.flat[3 * (size_t)v.id + i];
      out.flat.push_back(fu + tau * (fv - fu));
      double su = s(u.id)[i], sv = s(v.id)[i];
      param.push_back(i == a ? c : su + tau * (sv - su));
      out.origin_bary.push_back(x.bary[i]);
    }
    out.origin_tri.push_back(tri);
    return x;
  }

  // Sutherland-Hodgman split of a convex polygon by the plane s_a = c. Vertices within `tol`
  // of the plane belong to both halves; a polygon lying in the plane stays whole (below).
  void split(const Poly& poly, int a, int pi, double c, double tol, int tri,
             std::vector<Poly>& result) {
    Poly below, above;
    bool has_below = false, has_above = false;
    int n = (int)poly.size();
    auto side = [&](const PolyVertex& v) {
      double d = s(v.id)[a] - c;
      return d < -tol ? -1 : (d > tol ? 1 : 0);
    };
    for (int i = 0; i < n; ++i) {
      const PolyVertex& cur = poly[i];
      const PolyVertex& nxt = poly[(i + 1) % n];
      int sc = side(cur), sn = side(nxt);
      has_below |= sc < 0;
      has_above |= sc > 0;
      if (sc <= 0) below.push_back(cur);
      if (sc >= 0) above.push_back(cur);
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
                              const LatticeSpec& lattice) {
  ClipResult out;
  int V = (int)(X.size() / 3), T = (int)(tv.size() / 3);
  out.flat = X;
  out.origin_tri.assign(V, -1);
  out.origin_bary.assign(3 * (size_t)V, 0.0);
  Clipper c{lattice, out, {}, {}};
  c.param.resize(3 * (size_t)V);
  for (int v = 0; v < V; ++v) lattice.to_param(&X[3 * (size_t)v], &c.param[3 * (size_t)v]);
  std::array<std::vector<double>, 3> planes;
  std::array<double, 3> tol;
  for (int a = 0; a < 3; ++a) {
    planes[a] = lattice.axes[a].planes();
    // Vertices this close to a plane count as on it: meshes made in float32 (Blender's) put
    // "on-plane" vertices some 1e-8 off it, and cutting there would leave near-duplicate clip
    // vertices and zero-area slivers. 1e-5 of the smallest knot spacing is far below anything
    // visible and far above float32 noise.
    double spacing = 1.0;
    for (size_t i = 1; i < planes[a].size(); ++i)
      spacing = std::min(spacing, planes[a][i] - planes[a][i - 1]);
    double mag = planes[a].empty() ? 0.0 : std::max(std::fabs(planes[a].front()), std::fabs(planes[a].back()));
    tol[a] = std::max(1e-5 * spacing, 1e-12 * (1.0 + mag));
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
        if (!(v > lo + tol[a] && v < hi - tol[a])) continue;
        next.clear();
        poller.tick();
        for (const Poly& p : polys) c.split(p, a, pi, v, tol[a], t, next);
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

}  // namespace sffd
