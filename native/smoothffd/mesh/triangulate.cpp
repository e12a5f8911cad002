#include "smoothffd/mesh/triangulate.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <queue>

#include "smoothffd/core/cancel.hpp"

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

// Tolerance of the orientation tests: relative to the polygon's extent.
double area_eps(const std::vector<P2>& pts) {
  double scale = 0;
  for (const P2& p : pts) scale = std::fmax(scale, std::fmax(std::fabs(p.x), std::fabs(p.y)));
  return 1e-14 * (scale * scale + 1e-300);
}

// Polygons of up to kSmallPolygon corners: every step scans the ring for the best-shaped ear,
// O(n^3) at worst, cheap for such n (their triangulations are pinned by the plans' tests).
constexpr int kSmallPolygon = 64;

void clip_ears(const std::vector<P2>& pts, const std::vector<int>& vid, std::vector<int> ring,
               std::vector<int>& out_local) {
  const double eps = area_eps(pts);
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
      if (best < 0) best = 0;  // every area NaN (coordinates near the double limit)
    }
    out_local.push_back(ring[(best + n - 1) % n]);
    out_local.push_back(ring[best]);
    out_local.push_back(ring[(best + 1) % n]);
    ring.erase(ring.begin() + best);
  }
  out_local.insert(out_local.end(), ring.begin(), ring.end());
}

// Larger polygons: the same greedy order (the best-shaped ear first, the most convex corner
// when no ear is left) in O(n log n) for ordinary polygons, where clip_ears is O(n^2) or worse
// (128k corners took 24-32 s). The corners form a linked ring; a heap holds the valid ears by
// shape, with lazy deletion (an entry whose corner changed since is skipped). Only corners
// that are not strictly convex can lie in an ear of a simple polygon, so only they are tested,
// through a k-d tree over all corners whose nodes keep the count and bounding box of such
// corners still in the ring (a node without any, or wholly outside an edge of the ear, is
// skipped). An ear blocked by a corner waits on it and is tested again when that corner turns
// convex or is cut.
class LargeEarClipper {
 public:
  LargeEarClipper(const std::vector<P2>& pts, const std::vector<int>& vid)
      : pts_(pts), vid_(vid), n_((int)pts.size()), eps_(area_eps(pts)), prev_(n_), next_(n_),
        stamp_(n_, 0), area_(n_), alive_(n_, 1), blocking_(n_, 0), waiting_(n_), leaf_(n_) {
    for (int i = 0; i < n_; ++i) {
      prev_[i] = (i + n_ - 1) % n_;
      next_[i] = (i + 1) % n_;
    }
    build_tree();
    for (int i = 0; i < n_; ++i) {
      area_[i] = corner_area(i);
      if (!(area_[i] > eps_)) set_blocking(i, true);
    }
    for (int i = 0; i < n_; ++i) {
      most_convex_.push({key(area_[i]), i, stamp_[i]});
      if (!blocking_[i]) test_ear(i);
    }
  }

  void run(std::vector<int>& out) {
    CancelPoller poller(1024);
    for (int remaining = n_; remaining > 3; --remaining) {
      poller.tick();
      int b = pop_ear();
      if (b < 0) b = pop_most_convex();
      const int a = prev_[b], c = next_[b];
      out.push_back(a);
      out.push_back(b);
      out.push_back(c);
      alive_[b] = 0;
      if (blocking_[b]) set_blocking(b, false);  // a cut corner blocks nothing: its waiters retry
      next_[a] = c;
      prev_[c] = a;
      refresh(a);
      refresh(c);
      retry_waiters();
    }
    int first = 0;
    while (!alive_[first]) ++first;
    out.push_back(first);
    out.push_back(next_[first]);
    out.push_back(next_[next_[first]]);
  }

 private:
  struct Entry {
    double key;
    int i;
    unsigned stamp;
    bool operator<(const Entry& o) const { return key < o.key || (key == o.key && i > o.i); }
  };
  struct Node {
    int lo, hi;  // corners order_[lo, hi)
    int left = -1, right = -1, parent = -1;
    int blocking = 0;  // corners in the node still in the ring and not strictly convex ...
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;  // ... their box
  };

  static double key(double v) { return std::isnan(v) ? -INFINITY : v; }
  double corner_area(int i) const { return cross2(pts_[prev_[i]], pts_[i], pts_[next_[i]]); }

  void build_tree() {
    order_.resize(n_);
    for (int i = 0; i < n_; ++i) order_[i] = i;
    nodes_.reserve(2 * (size_t)n_ / kLeaf + 2);
    build_node(0, n_, -1);
  }
  int build_node(int lo, int hi, int parent) {
    Node nd;
    nd.lo = lo;
    nd.hi = hi;
    nd.parent = parent;
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
    for (int k = lo; k < hi; ++k) {
      const P2& p = pts_[order_[k]];
      x0 = std::fmin(x0, p.x);
      x1 = std::fmax(x1, p.x);
      y0 = std::fmin(y0, p.y);
      y1 = std::fmax(y1, p.y);
    }
    const int id = (int)nodes_.size();
    nodes_.push_back(nd);
    if (hi - lo <= kLeaf) {
      for (int k = lo; k < hi; ++k) leaf_[order_[k]] = id;
      return id;
    }
    const bool by_x = !(x1 - x0 < y1 - y0);
    const int mid = lo + (hi - lo) / 2;
    std::nth_element(order_.begin() + lo, order_.begin() + mid, order_.begin() + hi, [&](int u, int v) {
      double pu = by_x ? pts_[u].x : pts_[u].y, pv = by_x ? pts_[v].x : pts_[v].y;
      return pu < pv || (pu == pv && u < v);
    });
    const int l = build_node(lo, mid, id);
    const int r = build_node(mid, hi, id);
    nodes_[id].left = l;
    nodes_[id].right = r;
    return id;
  }

  void set_blocking(int i, bool on) {
    blocking_[i] = on;
    Node& leaf = nodes_[leaf_[i]];
    leaf.blocking = 0;
    leaf.x0 = leaf.y0 = INFINITY;
    leaf.x1 = leaf.y1 = -INFINITY;
    for (int k = leaf.lo; k < leaf.hi; ++k) {
      const int v = order_[k];
      if (!blocking_[v]) continue;
      ++leaf.blocking;
      leaf.x0 = std::fmin(leaf.x0, pts_[v].x);
      leaf.x1 = std::fmax(leaf.x1, pts_[v].x);
      leaf.y0 = std::fmin(leaf.y0, pts_[v].y);
      leaf.y1 = std::fmax(leaf.y1, pts_[v].y);
    }
    for (int id = leaf.parent; id >= 0; id = nodes_[id].parent) {
      Node& nd = nodes_[id];
      const Node &l = nodes_[nd.left], &r = nodes_[nd.right];
      nd.blocking = l.blocking + r.blocking;
      nd.x0 = std::fmin(l.x0, r.x0);
      nd.x1 = std::fmax(l.x1, r.x1);
      nd.y0 = std::fmin(l.y0, r.y0);
      nd.y1 = std::fmax(l.y1, r.y1);
    }
    if (!on) {  // ears waiting on i may be free now
      for (const Entry& w : waiting_[i]) retry_.push_back(w);
      waiting_[i].clear();
      waiting_[i].shrink_to_fit();
    }
  }

  // Largest value of cross2(a, b, p) over the node's box (cross2 is affine in p).
  static double box_max_cross(const Node& nd, P2 a, P2 b) {
    P2 p{(b.y - a.y) > 0 ? nd.x0 : nd.x1, (b.x - a.x) > 0 ? nd.y1 : nd.y0};
    return cross2(a, b, p);
  }

  // A corner that is not strictly convex inside the ear at b (inclusive, as clip_ears), or -1.
  int find_blocker(int b) {
    const int a = prev_[b], c = next_[b];
    const P2 pa = pts_[a], pb = pts_[b], pc = pts_[c];
    // The ear's box, grown by what the tolerance admits beyond an edge longer than 1e-7 of
    // the polygon's extent (eps / length = 1e-7 of the extent).
    const double margin = std::sqrt(eps_);
    const double x0 = std::fmin(pa.x, std::fmin(pb.x, pc.x)) - margin;
    const double x1 = std::fmax(pa.x, std::fmax(pb.x, pc.x)) + margin;
    const double y0 = std::fmin(pa.y, std::fmin(pb.y, pc.y)) - margin;
    const double y1 = std::fmax(pa.y, std::fmax(pb.y, pc.y)) + margin;
    stack_.clear();
    stack_.push_back(0);
    while (!stack_.empty()) {
      const Node& nd = nodes_[stack_.back()];
      stack_.pop_back();
      if (nd.blocking == 0 || nd.x0 > x1 || nd.x1 < x0 || nd.y0 > y1 || nd.y1 < y0) continue;
      if (box_max_cross(nd, pa, pb) < -eps_ || box_max_cross(nd, pb, pc) < -eps_ ||
          box_max_cross(nd, pc, pa) < -eps_)
        continue;  // wholly outside one edge of the ear
      if (nd.left < 0) {
        for (int k = nd.lo; k < nd.hi; ++k) {
          const int v = order_[k];
          if (!blocking_[v] || v == a || v == b || v == c) continue;
          if (vid_[v] == vid_[a] || vid_[v] == vid_[b] || vid_[v] == vid_[c]) continue;
          if (in_triangle(pts_[v], pa, pb, pc, eps_)) return v;
        }
        continue;
      }
      stack_.push_back(nd.right);
      stack_.push_back(nd.left);
    }
    return -1;
  }

  double quality(int b) const {
    const P2 pa = pts_[prev_[b]], pb = pts_[b], pc = pts_[next_[b]];
    double q = area_[b] / (dist2(pa, pb) + dist2(pb, pc) + dist2(pc, pa));
    return std::isnan(q) ? 0.0 : q;
  }

  // b is strictly convex: queue its ear, or make it wait on a corner inside it.
  void test_ear(int b) {
    int r = find_blocker(b);
    if (r >= 0)
      waiting_[r].push_back({0.0, b, stamp_[b]});
    else
      ears_.push({quality(b), b, stamp_[b]});
  }

  // b's neighbours changed: a new corner angle and ear.
  void refresh(int b) {
    ++stamp_[b];
    area_[b] = corner_area(b);
    most_convex_.push({key(area_[b]), b, stamp_[b]});
    const bool blocking = !(area_[b] > eps_);
    if (blocking != (bool)blocking_[b]) set_blocking(b, blocking);
    if (!blocking) test_ear(b);
  }

  bool fresh(const Entry& e) const { return alive_[e.i] && stamp_[e.i] == e.stamp; }

  void retry_waiters() {
    while (!retry_.empty()) {
      Entry w = retry_.back();
      retry_.pop_back();
      if (fresh(w) && !blocking_[w.i]) test_ear(w.i);
    }
  }

  // The best-shaped ear that is still valid, or -1.
  int pop_ear() {
    while (!ears_.empty()) {
      Entry e = ears_.top();
      ears_.pop();
      if (!fresh(e) || blocking_[e.i]) continue;
      int r = find_blocker(e.i);  // a corner may have turned reflex since (degenerate input)
      if (r >= 0) {
        waiting_[r].push_back(e);
        continue;
      }
      return e.i;
    }
    return -1;
  }

  int pop_most_convex() {
    while (true) {
      Entry e = most_convex_.top();
      most_convex_.pop();
      if (fresh(e)) return e.i;
    }
  }

  static constexpr int kLeaf = 8;
  const std::vector<P2>& pts_;
  const std::vector<int>& vid_;
  const int n_;
  const double eps_;
  std::vector<int> prev_, next_;
  std::vector<unsigned> stamp_;
  std::vector<double> area_;
  std::vector<uint8_t> alive_, blocking_;
  std::vector<std::vector<Entry>> waiting_;
  std::vector<Entry> retry_;
  std::priority_queue<Entry> ears_, most_convex_;
  std::vector<int> order_, leaf_, stack_;
  std::vector<Node> nodes_;
};

// Two faces that share three vertices (Suzanne's chin: quads (137, 70, 196, 138) and
// (197, 70, 137, 138)) can each choose the diagonal that makes the same triangle, back to back:
// a fin of zero volume whose edges have three or four faces, which folds the output there and
// which Blender 3.4-4.4's custom normals cannot shade (tests/blender/check_normals.py). Where a
// triangle repeats another face's vertices, a quad among the two takes its other diagonal,
// if both of that diagonal's triangles keep the quad's orientation.
void split_duplicate_triangles(const std::vector<double>& X, const std::vector<int>& cv,
                               const std::vector<int>& fo, Triangulation& out) {
  const size_t T = out.face.size();
  std::map<std::array<int, 3>, size_t> seen;
  auto key = [&](size_t t) {
    std::array<int, 3> k{cv[out.corners[3 * t]], cv[out.corners[3 * t + 1]], cv[out.corners[3 * t + 2]]};
    std::sort(k.begin(), k.end());
    return k;
  };
  auto flip_quad = [&](size_t t) {
    const int f = out.face[t];
    if (fo[f + 1] - fo[f] != 4) return false;
    const size_t t0 = t > 0 && out.face[t - 1] == f ? t - 1 : t;  // the quad's two triangles
    if (t0 + 1 >= T || out.face[t0] != f || out.face[t0 + 1] != f) return false;
    const int* q = &cv[fo[f]];
    const double* p[4];
    for (int i = 0; i < 4; ++i) p[i] = &X[3 * (size_t)q[i]];
    double n[3] = {0, 0, 0};  // Newell normal
    for (int i = 0; i < 4; ++i) {
      const double *a = p[i], *b = p[(i + 1) % 4];
      n[0] += (a[1] - b[1]) * (a[2] + b[2]);
      n[1] += (a[2] - b[2]) * (a[0] + b[0]);
      n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    auto positive = [&](int a, int b, int c) {
      double u[3], v[3];
      for (int i = 0; i < 3; ++i) u[i] = p[b][i] - p[a][i], v[i] = p[c][i] - p[a][i];
      return (u[1] * v[2] - u[2] * v[1]) * n[0] + (u[2] * v[0] - u[0] * v[2]) * n[1] +
                 (u[0] * v[1] - u[1] * v[0]) * n[2] > 0;
    };
    // The diagonal in use is the corner pair both triangles hold; take the other one.
    const bool uses02 = [&] {
      int both = 0;
      for (int k = 0; k < 3; ++k)
        for (int l = 0; l < 3; ++l)
          if (out.corners[3 * t0 + k] == out.corners[3 * (t0 + 1) + l]) both |= 1 << ((out.corners[3 * t0 + k] - fo[f]) & 3);
      return both == 0b0101;
    }();
    const int a = uses02 ? 1 : 0;  // new diagonal a -- a + 2
    const int tri[2][3] = {{a, a + 1, (a + 2) % 4}, {a, (a + 2) % 4, (a + 3) % 4}};
    if (!positive(tri[0][0], tri[0][1], tri[0][2]) || !positive(tri[1][0], tri[1][1], tri[1][2])) return false;
    for (int s = 0; s < 2; ++s)
      for (int k = 0; k < 3; ++k) out.corners[3 * (t0 + s) + k] = fo[f] + tri[s][k];
    return true;
  };
  CancelPoller poller;
  for (size_t t = 0; t < T; ++t) {
    poller.tick();
    auto [it, fresh] = seen.emplace(key(t), t);
    if (fresh || out.face[it->second] == out.face[t]) continue;
    if (!flip_quad(t)) flip_quad(it->second);
  }
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
  CancelPoller poller;
  for (int f = 0; f < F; ++f) {
    poller.tick();
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
    if (n <= kSmallPolygon)
      clip_ears(pts, vid, ring, local);
    else
      LargeEarClipper(pts, vid).run(local);
    for (size_t t = 0; t + 2 < local.size(); t += 3) {
      int a = local[t], b = local[t + 1], c = local[t + 2];
      if (vid[a] == vid[b] || vid[b] == vid[c] || vid[c] == vid[a]) continue;
      out.corners.push_back(poly[a]);
      out.corners.push_back(poly[b]);
      out.corners.push_back(poly[c]);
      out.face.push_back(f);
    }
  }
  split_duplicate_triangles(X, cv, fo, out);
  return out;
}

}  // namespace sffd
