#include "smoothffd/plan/rest_surface.hpp"

#include <cmath>

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
                bool sharp, bool non_manifold, double* out) {
  double third[3], base[3];
  for (int i = 0; i < 3; ++i) {
    third[i] = (b[i] - a[i]) / 3.0;
    base[i] = a[i] + third[i];
  }
  for (int i = 0; i < 3; ++i) out[i] = base[i];
  if (non_manifold) return;
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

RestSurface build_rest_surface(const std::vector<double>& X, const std::vector<int>& tv,
                               const EdgeTable& e, const std::vector<uint8_t>& sharp,
                               const std::vector<double>& cn) {
  RestSurface rs;
  rs.edge_cp.assign(6 * (size_t)e.count(), 0.0);
  for (int id = 0; id < e.count(); ++id) {
    for (int end = 0; end < 2; ++end) {
      int v = e.vertex[2 * id + end], w = e.vertex[2 * id + 1 - end];
      int t0 = e.side[2 * id], t1 = e.side[2 * id + 1];
      const double* n0 = &cn[9 * (size_t)t0 + 3 * slot_of(tv, t0, v)];
      const double* n1 = t1 >= 0 ? &cn[9 * (size_t)t1 + 3 * slot_of(tv, t1, v)] : nullptr;
      edge_point(&X[3 * (size_t)v], &X[3 * (size_t)w], n0, n1, (sharp[id] >> end) & 1,
                 e.face_count[id] > 2, &rs.edge_cp[6 * (size_t)id + 3 * end]);
    }
  }
  return rs;
}

void rest_surface_point(const RestSurface& rs, const std::vector<double>& X,
                        const std::vector<int>& tv, const EdgeTable& e, int t, const double b[3],
                        double out[3]) {
  double cp[10][3];
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
  double B[10];
  cubic_basis<double>(b, B);
  for (int i = 0; i < 3; ++i) {
    out[i] = 0;
    for (int k = 0; k < 10; ++k) out[i] += B[k] * cp[k][i];
  }
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
