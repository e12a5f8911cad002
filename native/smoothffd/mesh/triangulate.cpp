#include "smoothffd/mesh/triangulate.hpp"

#include <cmath>

namespace sffd {
namespace {

struct P2 {
  double x, y;
};

double cross2(P2 a, P2 b, P2 c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); }
double dist2(P2 a, P2 b) { return (a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y); }

// Inclusive: a point on the ear's boundary also blocks it (it would make a T-junction).
bool in_triangle(P2 p, P2 a, P2 b, P2 c, double eps) {
  return cross2(a, b, p) >= -eps && cross2(b, c, p) >= -eps && cross2(c, a, p) >= -eps;
}

void clip_ears(const std::vector<P2>& pts, const std::vector<int>& vid, std::vector<int> ring,
               std::vector<int>& out_local) {
  double scale = 0;
  for (const P2& p : pts) scale = std::fmax(scale, std::fmax(std::fabs(p.x), std::fabs(p.y)));
  double eps = 1e-14 * (scale * scale + 1e-300);
  while (ring.size() > 3) {
    int n = (int)ring.size();
    int best = -1;
    double best_q = -1;
    for (int i = 0; i < n; ++i) {
      int a = ring[(i + n - 1) % n], b = ring[i], c = ring[(i + 1) % n];
      double area = cross2(pts[a], pts[b], pts[c]);
      if (area <= eps) continue;  // reflex or flat corner
      bool blocked = false;
      for (int j = 0; j < n && !blocked; ++j) {
        int v = ring[j];
        if (v == a || v == b || v == c) continue;
        if (vid[v] == vid[a] || vid[v] == vid[b] || vid[v] == vid[c]) continue;
        blocked = in_triangle(pts[v], pts[a], pts[b], pts[c], eps);
      }
      if (blocked) continue;
      double q = area / (dist2(pts[a], pts[b]) + dist2(pts[b], pts[c]) + dist2(pts[c], pts[a]));
      if (q > best_q) {
        best_q = q;
        best = i;
        if (n > 64) break;  // large polygons: first valid ear, keeps this O(n^2)
      }
    }
    if (best < 0) {
      // Degenerate or self-intersecting polygon: cut the most convex corner anyway so every
      // corner still ends up in a triangle (zero-area triangles are handled downstream).
      double most = -INFINITY;
      for (int i = 0; i < n; ++i) {
        double area = cross2(pts[ring[(i + n - 1) % n]], pts[ring[i]], pts[ring[(i + 1) % n]]);
        if (area > most) { most = area; best = i; }
      }
    }
    out_local.push_back(ring[(best + n - 1) % n]);
    out_local.push_back(ring[best]);
    out_local.push_back(ring[(best + 1) % n]);
    ring.erase(ring.begin() + best);
  }
  out_local.insert(out_local.end(), ring.begin(), ring.end());
}

}  // namespace

Triangulation triangulate_polygons(const std::vector<double>& X, const std::vector<int>& cv,
                                   const std::vector<int>& fo) {
  Triangulation out;
  int F = (int)fo.size() - 1;
  out.corners.reserve(3 * (size_t)F);
  out.face.reserve(F);
  std::vector<int> poly, vid, local;
  std::vector<P2> pts;
  for (int f = 0; f < F; ++f) {
    poly.clear();
    for (int c = fo[f]; c < fo[f + 1]; ++c)
      if (poly.empty() || cv[poly.back()] != cv[c]) poly.push_back(c);
    while (poly.size() > 1 && cv[poly.back()] == cv[poly.front()]) poly.pop_back();
    int n = (int)poly.size();
    if (n < 3) continue;
    if (n == 3) {
      if (cv[poly[0]] != cv[poly[2]]) {
        out.corners.insert(out.corners.end(), poly.begin(), poly.end());
        out.face.push_back(f);
      }
      continue;
    }
    // Newell normal: robust plane of a non-planar or concave polygon.
    double nx = 0, ny = 0, nz = 0;
    for (int i = 0; i < n; ++i) {
      const double* a = &X[3 * (size_t)cv[poly[i]]];
      const double* b = &X[3 * (size_t)cv[poly[(i + 1) % n]]];
      nx += (a[1] - b[1]) * (a[2] + b[2]);
      ny += (a[2] - b[2]) * (a[0] + b[0]);
      nz += (a[0] - b[0]) * (a[1] + b[1]);
    }
    int drop = 2;
    double an[3] = {std::fabs(nx), std::fabs(ny), std::fabs(nz)};
    if (an[0] >= an[1] && an[0] >= an[2]) drop = 0; else if (an[1] >= an[2]) drop = 1;
    double sign = (drop == 0 ? nx : drop == 1 ? ny : nz) >= 0 ? 1.0 : -1.0;
    int ax = (drop + 1) % 3, ay = (drop + 2) % 3;
    pts.resize(n);
    vid.resize(n);
    std::vector<int> ring(n);
    for (int i = 0; i < n; ++i) {
      const double* a = &X[3 * (size_t)cv[poly[i]]];
      pts[i] = P2{a[ax], sign * a[ay]};
      vid[i] = cv[poly[i]];
      ring[i] = i;
    }
    local.clear();
    clip_ears(pts, vid, ring, local);
    for (size_t t = 0; t + 2 < local.size(); t += 3) {
      int a = local[t], b = local[t + 1], c = local[t + 2];
      if (vid[a] == vid[b] || vid[b] == vid[c] || vid[c] == vid[a]) continue;
      out.corners.push_back(poly[a]);
      out.corners.push_back(poly[b]);
      out.corners.push_back(poly[c]);
      out.face.push_back(f);
    }
  }
  return out;
}

}  // namespace sffd
