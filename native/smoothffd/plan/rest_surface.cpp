#include "smoothffd/plan/rest_surface.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>

#include "smoothffd/core/parallel.hpp"

#include "smoothffd/plan/bezier.hpp"

namespace sffd {
namespace {

double dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

bool normalize3(double* v) {
  double l = std::sqrt(dot3(v, v));
  if (!(l > 1e-300)) return false;
  for (int i = 0; i < 3; ++i) v[i] /= l;
  return true;
}

// Control point next to `a` on the edge a -> b, from the normals n0 (and n1) at a.
void edge_point(const double* a, const double* b, const double* n0, const double* n1,
                bool sharp, bool keep, double* out) {
  double third[3], base[3];
  for (int i = 0; i < 3; ++i) {
    third[i] = (b[i] - a[i]) / 3.0;
    base[i] = a[i] + third[i];
  }
  for (int i = 0; i < 3; ++i) out[i] = base[i];
  if (keep) return;  // non-manifold edges and flat faces' edges: straight
  if (sharp && n1) {
    double t[3] = {n0[1] * n1[2] - n0[2] * n1[1], n0[2] * n1[0] - n0[0] * n1[2],
                   n0[0] * n1[1] - n0[1] * n1[0]};
    if (normalize3(t)) {
      double d = dot3(third, t);
      for (int i = 0; i < 3; ++i) out[i] = a[i] + d * t[i];
      return;
    }
  }
  double n[3] = {n0[0], n0[1], n0[2]};
  if (n1)
    for (int i = 0; i < 3; ++i) n[i] += n1[i];
  if (!normalize3(n)) return;
  double d = dot3(third, n);
  for (int i = 0; i < 3; ++i) out[i] = base[i] - d * n[i];
}

}  // namespace

AdjustNormals::AdjustNormals(const std::vector<double>& X, const std::vector<int>& tv,
                             const std::vector<double>& base_, const std::vector<uint8_t>& flat_)
    : base(base_), flat(flat_) {
  const size_t T = tv.size() / 3, V = X.size() / 3;
  own.assign(3 * T, 0.0);
  has_own.assign(T, 0);
  trust.assign(V, 1.0);
  corner.assign(base.size(), 0.0);
  // Each triangle on its own: in parallel, the same values.
  parallel_for((long long)T, default_threads(), [&](long long tb, long long te) {
    for (long long t = tb; t < te; ++t) {
      const double *a = &X[3 * (size_t)tv[3 * t]], *b = &X[3 * (size_t)tv[3 * t + 1]], *c = &X[3 * (size_t)tv[3 * t + 2]];
      double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
      double* n = &own[3 * t];
      n[0] = u[1] * w[2] - u[2] * w[1];
      n[1] = u[2] * w[0] - u[0] * w[2];
      n[2] = u[0] * w[1] - u[1] * w[0];
      // Degenerate triangles have no orientation of their own: they keep the input's normals.
      const double scale = dot3(u, u) + dot3(w, w);
      has_own[t] = std::sqrt(dot3(n, n)) > 1e-12 * scale && normalize3(n);
      for (int k = 0; k < 3; ++k) update(tv, (int)t, k);
    }
  });
}

void AdjustNormals::update(const std::vector<int>& tv, int t, int k) {
  const double* n = &base[9 * (size_t)t + 3 * k];
  double* out = &corner[9 * (size_t)t + 3 * k];
  const double lambda = trust[tv[3 * (size_t)t + k]];
  if (!has_own[t] || (!flat[t] && lambda >= 1.0)) {
    for (int i = 0; i < 3; ++i) out[i] = n[i];
    return;
  }
  const double* o = &own[3 * (size_t)t];
  const double l = flat[t] ? 0.0 : lambda;
  for (int i = 0; i < 3; ++i) out[i] = l * n[i] + (1.0 - l) * o[i];
  if (!normalize3(out))
    for (int i = 0; i < 3; ++i) out[i] = o[i];
}

namespace {

// Index of the cubic control point with barycentric exponents (i, j, k) (bezier.hpp order).
int cubic_index(int i, int j, int k) {
  int e[3];
  for (int c = 0; c < 10; ++c) {
    cubic_exponents(c, e);
    if (e[0] == i && e[1] == j && e[2] == k) return c;
  }
  return -1;
}

// Whether N turns more than acos(kFoldCos) from m: N.m < kFoldCos |N| |m|, from the squared
// lengths (no square roots: the fold test runs on every face at every pose).
inline bool turns_past_fold(double dot, double n2, double m2) {
  static_assert(kFoldCos > 0, "the squared comparison needs a positive bound");
  return dot < 0 || dot * dot < kFoldCos * kFoldCos * n2 * m2;
}

// The fold test's grid: 15 barycentric points (4 steps a side) with the 6 quadratic Bernstein
// values at each, in the order of kQuad; point-major (b[c][n], q[t][n]: the test runs over the
// points).
struct FoldGrid {
  static constexpr int kSteps = 4, kPoints = (kSteps + 1) * (kSteps + 2) / 2;
  double b[3][kPoints];
  double q[6][kPoints];
  int quad[6][3];  // exponents of the quadratic terms
  int plus[6][3];  // cubic control point index of quad term + e_c
  FoldGrid() {
    const int qe[6][3] = {{2, 0, 0}, {0, 2, 0}, {0, 0, 2}, {1, 1, 0}, {0, 1, 1}, {1, 0, 1}};
    for (int t = 0; t < 6; ++t)
      for (int c = 0; c < 3; ++c) {
        quad[t][c] = qe[t][c];
        int e[3] = {qe[t][0], qe[t][1], qe[t][2]};
        e[c] += 1;
        plus[t][c] = cubic_index(e[0], e[1], e[2]);
      }
    int n = 0;
    for (int i = 0; i <= kSteps; ++i)
      for (int j = 0; i + j <= kSteps; ++j, ++n) {
        b[0][n] = double(kSteps - i - j) / kSteps;
        b[1][n] = double(i) / kSteps;
        b[2][n] = double(j) / kSteps;
        for (int t = 0; t < 6; ++t) {
          double v = (t < 3 ? 1.0 : 2.0);
          for (int c = 0; c < 3; ++c)
            for (int r = 0; r < quad[t][c]; ++r) v *= b[c][n];
          q[t][n] = v;
        }
      }
  }
};

// The tessellations of levels 1 .. kLevels: their grid points (cubic Bernstein values at
// each) and triangles (grid point indices, barycentric centre).
struct ChordGrid {
  static constexpr int kLevels = 2;
  static constexpr int kPoints = 3 + 6;  // (L + 1)(L + 2) / 2 for L = 1 .. 2
  struct Tri {
    int v[3];
    double b[3];
  };
  double basis[kPoints][10];
  std::vector<Tri> tris;
  ChordGrid() {
    int base = 0;
    for (int L = 1; L <= kLevels; ++L) {
      auto id = [&](int i, int j) { return base + i * (L + 1) - i * (i - 1) / 2 + j; };  // b1 = i, b2 = j
      for (int i = 0; i <= L; ++i)
        for (int j = 0; i + j <= L; ++j) {
          const double b[3] = {double(L - i - j) / L, double(i) / L, double(j) / L};
          cubic_basis<double>(b, basis[id(i, j)]);
        }
      for (int i = 0; i < L; ++i)
        for (int j = 0; i + j < L; ++j) {
          Tri up{{id(i, j), id(i + 1, j), id(i, j + 1)}, {}};
          const double bu[3] = {(3.0 * L - 3 * i - 3 * j - 2) / (3.0 * L), (3.0 * i + 1) / (3.0 * L), (3.0 * j + 1) / (3.0 * L)};
          for (int c = 0; c < 3; ++c) up.b[c] = bu[c];
          tris.push_back(up);
          if (i + j + 1 < L) {
            Tri dn{{id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)}, {}};
            const double bd[3] = {(3.0 * L - 3 * i - 3 * j - 4) / (3.0 * L), (3.0 * i + 2) / (3.0 * L), (3.0 * j + 2) / (3.0 * L)};
            for (int c = 0; c < 3; ++c) dn.b[c] = bd[c];
            tris.push_back(dn);
          }
        }
      base += (L + 1) * (L + 2) / 2;
    }
  }
};

}  // namespace

bool rest_patch_folds(const double cp[10][3], const double rn[9]) {
  static const FoldGrid g;
  // Control nets of the tangents along corner 0 -> 1 and 0 -> 2 (quadratics): 3 (b_{j+e1} -
  // b_{j+e0}) and 3 (b_{j+e2} - b_{j+e0}); for the flat triangle they are its edges.
  double t1[6][3], t2[6][3];
  for (int t = 0; t < 6; ++t)
    for (int i = 0; i < 3; ++i) {
      const double base = cp[g.plus[t][0]][i];
      t1[t][i] = 3.0 * (cp[g.plus[t][1]][i] - base);
      t2[t][i] = 3.0 * (cp[g.plus[t][2]][i] - base);
    }
  double u[3], w[3];
  for (int i = 0; i < 3; ++i) {
    u[i] = cp[1][i] - cp[0][i];
    w[i] = cp[2][i] - cp[0][i];
  }
  const double c[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  const double flat2 = dot3(c, c);  // |N|^2 of the flat triangle (tangents u, w)
  // Every grid point, then the test (no early exit inside: the compiler vectorizes the points;
  // each point's arithmetic is the same, in the same order).
  constexpr int NP = FoldGrid::kPoints;
  double a1[3][NP], a2[3][NP];
  for (int i = 0; i < 3; ++i)
    for (int n = 0; n < NP; ++n) {
      double s1 = 0, s2 = 0;
      for (int t = 0; t < 6; ++t) {
        s1 += g.q[t][n] * t1[t][i];
        s2 += g.q[t][n] * t2[t][i];
      }
      a1[i][n] = s1;
      a2[i][n] = s2;
    }
  bool fold = false;
  for (int n = 0; n < NP; ++n) {
    const double N[3] = {a1[1][n] * a2[2][n] - a1[2][n] * a2[1][n], a1[2][n] * a2[0][n] - a1[0][n] * a2[2][n],
                         a1[0][n] * a2[1][n] - a1[1][n] * a2[0][n]};
    double m[3];
    for (int k = 0; k < 3; ++k) m[k] = g.b[0][n] * rn[k] + g.b[1][n] * rn[3 + k] + g.b[2][n] * rn[6 + k];
    const double ln2 = dot3(N, N), lm2 = dot3(m, m);
    fold |= lm2 > 0 && (turns_past_fold(dot3(N, m), ln2, lm2) || ln2 < kCollapse * kCollapse * flat2);
  }
  if (fold) return true;
  // The flat triangles a tessellation of level 1 to kLevels puts through the patch (what
  // the output is made of) against the normals at their centres, with the same margin.
  static const ChordGrid chords;
  double x[ChordGrid::kPoints][3];
  for (int n = 0; n < ChordGrid::kPoints; ++n)
    for (int i = 0; i < 3; ++i) {
      double v = 0;
      for (int k = 0; k < 10; ++k) v += chords.basis[n][k] * cp[k][i];
      x[n][i] = v;
    }
  for (const ChordGrid::Tri& t : chords.tris) {
    double u[3], w[3], m[3];
    for (int i = 0; i < 3; ++i) {
      u[i] = x[t.v[1]][i] - x[t.v[0]][i];
      w[i] = x[t.v[2]][i] - x[t.v[0]][i];
    }
    const double N[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    for (int k = 0; k < 3; ++k) m[k] = t.b[0] * rn[k] + t.b[1] * rn[3 + k] + t.b[2] * rn[6 + k];
    const double lm2 = dot3(m, m);
    if (lm2 > 0 && turns_past_fold(dot3(N, m), dot3(N, N), lm2)) return true;
  }
  return false;
}

namespace {

// Whether the flat triangle through the rest patch's points at barycentric corners b (3 x 3)
// turns more than acos(kFoldCos) from the render normal at its centre.
bool piece_folds(const double cp[10][3], const double rn[9], const double* b) {
  double x[3][3], m[3] = {0, 0, 0};
  for (int c = 0; c < 3; ++c) cubic_point(cp, b + 3 * c, x[c]);
  for (int c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) m[k] += (b[3 * c] * rn[k] + b[3 * c + 1] * rn[3 + k] + b[3 * c + 2] * rn[6 + k]) / 3.0;
  double u[3], w[3];
  for (int i = 0; i < 3; ++i) {
    u[i] = x[1][i] - x[0][i];
    w[i] = x[2][i] - x[0][i];
  }
  const double N[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  const double lm2 = dot3(m, m);
  return lm2 > 0 && turns_past_fold(dot3(N, m), dot3(N, N), lm2);
}

}  // namespace

int bound_adjust_normals(const std::vector<double>& X, const std::vector<int>& tv, const EdgeTable& e,
                         const std::vector<uint8_t>& sharp, const std::vector<double>& render,
                         AdjustNormals& an, RestSurface& rest, const std::vector<int>* piece_start,
                         const std::vector<double>* piece_bary, const std::vector<uint8_t>* check) {
  const int T = (int)(tv.size() / 3), V = (int)(X.size() / 3);
  std::vector<uint8_t> dirty(check ? *check : std::vector<uint8_t>(T, 1)), lowered(V, 0), folds(T, 0);
  for (int round = 0;; ++round) {
    rest = build_rest_surface(X, tv, e, sharp, an.corner, &an.flat);
    if (round == 64) break;  // each vertex is lowered at most 5 times: never reached
    parallel_for(T, default_threads(), [&](long long b, long long end) {
      for (long long t = b; t < end; ++t) {
        folds[t] = 0;
        if (!dirty[t] || !an.has_own[t]) continue;
        double cp[10][3];
        rest_patch(rest, X, tv, e, (int)t, cp);
        folds[t] = rest_patch_folds(cp, &render[9 * (size_t)t]);
        if (piece_start && (*piece_start)[t + 1] - (*piece_start)[t] > 1)
          for (int q = (*piece_start)[t]; q < (*piece_start)[t + 1] && !folds[t]; ++q)
            folds[t] = piece_folds(cp, &render[9 * (size_t)t], &(*piece_bary)[9 * (size_t)q]);
      }
    });
    std::fill(dirty.begin(), dirty.end(), 0);
    std::fill(lowered.begin(), lowered.end(), 0);
    bool changed = false;
    for (int t = 0; t < T; ++t) {
      if (!folds[t]) continue;
      for (int k = 0; k < 3; ++k) {
        const int v = tv[3 * (size_t)t + k];
        if (lowered[v] || an.trust[v] <= 0.0) continue;
        lowered[v] = 1;
        an.trust[v] = round >= 4 ? 0.0 : an.trust[v] * 0.5;
        changed = true;
      }
    }
    if (!changed) break;
    // The corners at the lowered vertices, and the patches they reach (their edges end
    // there): every triangle at a lowered vertex (each on its own, in parallel).
    parallel_for(T, default_threads(), [&](long long b, long long end) {
      for (long long t = b; t < end; ++t)
        for (int k = 0; k < 3; ++k)
          if (lowered[tv[3 * (size_t)t + k]]) {
            an.update(tv, (int)t, k);
            dirty[t] = 1;
          }
    });
  }
  int bounded = 0;
  for (int v = 0; v < V; ++v) bounded += an.trust[v] < 1.0;
  return bounded;
}

int bound_render_normals(const AdjustNormals& an, std::vector<double>& render, std::vector<uint8_t>* turned) {
  std::atomic<int> count{0};
  // Each corner on its own: in parallel, the same values.
  parallel_for((long long)(render.size() / 3), default_threads(), [&](long long b, long long e) {
    int n = 0;
    for (long long c = b; c < e; ++c) {
      double* r = &render[3 * c];
      const double* a = &an.corner[3 * c];
      const double d = dot3(r, a);
      if (d >= kShadeCos - 1e-9) continue;
      if (turned) (*turned)[c] = 1;
      // r' = cos(theta) a + sin(theta) u, u the unit part of r across a (a itself where r is
      // opposite to a).
      double u[3] = {r[0] - d * a[0], r[1] - d * a[1], r[2] - d * a[2]};
      const double s = std::sqrt(1.0 - kShadeCos * kShadeCos);
      if (normalize3(u))
        for (int i = 0; i < 3; ++i) r[i] = kShadeCos * a[i] + s * u[i];
      else
        for (int i = 0; i < 3; ++i) r[i] = a[i];
      ++n;
    }
    count += n;
  });
  return count.load();
}

RestSurface build_rest_surface(const std::vector<double>& X, const std::vector<int>& tv,
                               const EdgeTable& e, const std::vector<uint8_t>& sharp,
                               const std::vector<double>& cn, const std::vector<uint8_t>* flat) {
  RestSurface rs;
  rs.edge_cp.assign(6 * (size_t)e.count(), 0.0);
  // Each edge writes its own control points: in parallel, the same values.
  parallel_for(e.count(), default_threads(), [&](long long b, long long end_id) {
    for (long long id = b; id < end_id; ++id) {
      for (int end = 0; end < 2; ++end) {
        int v = e.vertex[2 * id + end], w = e.vertex[2 * id + 1 - end];
        int t0 = e.side[2 * id], t1 = e.side[2 * id + 1];
        const bool keep = e.face_count[id] > 2 || (flat && ((*flat)[t0] || (t1 >= 0 && (*flat)[t1])));
        const double* n0 = &cn[9 * (size_t)t0 + 3 * slot_of(tv, t0, v)];
        const double* n1 = t1 >= 0 ? &cn[9 * (size_t)t1 + 3 * slot_of(tv, t1, v)] : nullptr;
        edge_point(&X[3 * (size_t)v], &X[3 * (size_t)w], n0, n1, (sharp[id] >> end) & 1, keep,
                   &rs.edge_cp[6 * (size_t)id + 3 * end]);
      }
    }
  });
  return rs;
}

void rest_patch(const RestSurface& rs, const std::vector<double>& X, const std::vector<int>& tv,
                const EdgeTable& e, int t, double cp[10][3]) {
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 3; ++i) cp[k][i] = X[3 * (size_t)tv[3 * t + k] + i];
  double E[3] = {0, 0, 0}, V[3] = {0, 0, 0};
  for (int k = 0; k < 3; ++k) {
    int id = e.tri_edge[3 * t + k];
    bool forward = e.vertex[2 * id] == tv[3 * t + k];
    const double* near_a = &rs.edge_cp[6 * (size_t)id];
    const double* near_b = near_a + 3;
    const double* start = forward ? near_a : near_b;
    const double* end = forward ? near_b : near_a;
    for (int i = 0; i < 3; ++i) {
      cp[edge_control_index(k, false)][i] = start[i];
      cp[edge_control_index(k, true)][i] = end[i];
      E[i] += (start[i] + end[i]) / 6.0;
      V[i] += cp[k][i] / 3.0;
    }
  }
  for (int i = 0; i < 3; ++i) cp[kCentre][i] = E[i] + (E[i] - V[i]) / 2.0;
}

void cubic_point(const double cp[10][3], const double b[3], double out[3]) {
  double B[10];
  cubic_basis<double>(b, B);
  for (int i = 0; i < 3; ++i) {
    out[i] = 0;
    for (int k = 0; k < 10; ++k) out[i] += B[k] * cp[k][i];
  }
}

void cubic_normal(const double cp[10][3], const double b[3], double out[3]) {
  // d/db_c of each Bernstein term (homogeneous in b), then the tangents along b1 - b0, b2 - b0.
  double d[3][3] = {};
  for (int k = 0; k < 10; ++k) {
    int ex[3];
    cubic_exponents(k, ex);
    double coef = (k < 3 ? 1.0 : k == kCentre ? 6.0 : 3.0);
    for (int c = 0; c < 3; ++c) {
      if (!ex[c]) continue;
      double v = coef * ex[c];
      for (int j = 0; j < 3; ++j)
        for (int q = 0; q < ex[j] - (j == c); ++q) v *= b[j];
      for (int i = 0; i < 3; ++i) d[c][i] += v * cp[k][i];
    }
  }
  double t1[3], t2[3];
  for (int i = 0; i < 3; ++i) {
    t1[i] = d[1][i] - d[0][i];
    t2[i] = d[2][i] - d[0][i];
  }
  out[0] = t1[1] * t2[2] - t1[2] * t2[1];
  out[1] = t1[2] * t2[0] - t1[0] * t2[2];
  out[2] = t1[0] * t2[1] - t1[1] * t2[0];
}

void rest_surface_point(const RestSurface& rs, const std::vector<double>& X,
                        const std::vector<int>& tv, const EdgeTable& e, int t, const double b[3],
                        double out[3]) {
  double cp[10][3];
  rest_patch(rs, X, tv, e, t, cp);
  cubic_point(cp, b, out);
}

void pn_quadratic_normal(const double P[9], const double N[9], const double b[3], double out[3]) {
  // n_ij = normalize(Ni + Nj - v_ij (Pj - Pi)), v_ij = 2 (Pj - Pi).(Ni + Nj) / |Pj - Pi|^2.
  double mid[3][3];  // mid[k]: edge k (corner k -> k + 1)
  for (int k = 0; k < 3; ++k) {
    int i = k, j = (k + 1) % 3;
    double d[3], s[3];
    for (int c = 0; c < 3; ++c) {
      d[c] = P[3 * j + c] - P[3 * i + c];
      s[c] = N[3 * i + c] + N[3 * j + c];
    }
    double l2 = dot3(d, d);
    double v = l2 > 1e-300 ? 2.0 * dot3(d, s) / l2 : 0.0;
    for (int c = 0; c < 3; ++c) mid[k][c] = s[c] - v * d[c];
    if (!normalize3(mid[k]))
      for (int c = 0; c < 3; ++c) mid[k][c] = N[3 * i + c];
  }
  for (int c = 0; c < 3; ++c)
    out[c] = b[0] * b[0] * N[c] + b[1] * b[1] * N[3 + c] + b[2] * b[2] * N[6 + c] +
             b[0] * b[1] * mid[0][c] + b[1] * b[2] * mid[1][c] + b[2] * b[0] * mid[2][c];
  if (!normalize3(out))
    for (int c = 0; c < 3; ++c) out[c] = b[0] * N[c] + b[1] * N[3 + c] + b[2] * N[6 + c];
}

}  // namespace sffd
