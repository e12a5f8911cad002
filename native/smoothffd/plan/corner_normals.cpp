#include "smoothffd/plan/corner_normals.hpp"

#include <cmath>

#include "smoothffd/core/parallel.hpp"

namespace sffd {
namespace {

void triangle_normal(const std::vector<double>& X, const int* t, double* n) {
  const double *a = &X[3 * (size_t)t[0]], *b = &X[3 * (size_t)t[1]], *c = &X[3 * (size_t)t[2]];
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  n[0] = u[1] * w[2] - u[2] * w[1];
  n[1] = u[2] * w[0] - u[0] * w[2];
  n[2] = u[0] * w[1] - u[1] * w[0];
}

}  // namespace

// Unit normal at every triangle corner (#T x 3 x 3): the input split normals, or smooth
// area-weighted vertex normals when none are given.
std::vector<double> triangle_corner_normals(const InputMesh& m, const Triangulation& tr,
                                            const std::vector<int>& tv) {
  size_t T = tr.face.size(), V = m.positions.size() / 3;
  std::vector<double> cn(9 * T), fn(3 * T);
  const double up[3] = {0, 0, 1};
  // Each triangle's own, and below its corners': in parallel, the same values.
  const int threads = default_threads();
  parallel_for((long long)T, threads, [&](long long b, long long e) {
    for (long long t = b; t < e; ++t) triangle_normal(m.positions, &tv[3 * t], &fn[3 * t]);
  });
  std::vector<double> vn;
  if (m.corner_normal.empty()) {
    vn.assign(3 * V, 0.0);
    for (size_t t = 0; t < T; ++t)
      for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i) vn[3 * (size_t)tv[3 * t + k] + i] += fn[3 * t + i];
  }
  parallel_for((long long)T, threads, [&](long long b, long long e) {
    for (long long t = b; t < e; ++t) {
      double face[3] = {fn[3 * t], fn[3 * t + 1], fn[3 * t + 2]};
      normalize_or(face, up);
      for (int k = 0; k < 3; ++k) {
        double* n = &cn[9 * t + 3 * k];
        if (m.corner_normal.empty()) {
          for (int i = 0; i < 3; ++i) n[i] = vn[3 * (size_t)tv[3 * t + k] + i];
        } else {
          for (int i = 0; i < 3; ++i) n[i] = m.corner_normal[3 * (size_t)tr.corners[3 * t + k] + i];
        }
        normalize_or(n, face);  // a zero input normal falls back to the face's own
      }
    }
  });
  return cn;
}

// Triangles of flat faces: faces whose every corner normal is within the sharp angle of the
// face's own (Newell) normal, the normal Blender and most tools give a polygon. #T, 0 or 1.
std::vector<uint8_t> flat_triangles(const InputMesh& m, const Triangulation& tr,
                                    const std::vector<double>& tcn, double cos_tol) {
  const size_t F = m.face_offset.size() - 1, T = tr.face.size();
  std::vector<double> fn(3 * F, 0.0);
  // Each face's normal, then each triangle's test, then each triangle's face's: in parallel,
  // the same values.
  const int threads = default_threads();
  parallel_for((long long)F, threads, [&](long long fb, long long fe) {
    for (long long f = fb; f < fe; ++f) {
      const int b = m.face_offset[f], e = m.face_offset[f + 1];
      for (int c = b; c < e; ++c) {
        const double* p = &m.positions[3 * (size_t)m.corner_vertex[c]];
        const double* q = &m.positions[3 * (size_t)m.corner_vertex[c + 1 < e ? c + 1 : b]];
        fn[3 * f] += (p[1] - q[1]) * (p[2] + q[2]);
        fn[3 * f + 1] += (p[2] - q[2]) * (p[0] + q[0]);
        fn[3 * f + 2] += (p[0] - q[0]) * (p[1] + q[1]);
      }
      const double l = std::sqrt(fn[3 * f] * fn[3 * f] + fn[3 * f + 1] * fn[3 * f + 1] + fn[3 * f + 2] * fn[3 * f + 2]);
      for (int i = 0; i < 3; ++i) fn[3 * f + i] = l > 0 && std::isfinite(l) ? fn[3 * f + i] / l : 0.0;
    }
  });
  std::vector<uint8_t> flat(T, 1);
  parallel_for((long long)T, threads, [&](long long b, long long e) {
    for (long long t = b; t < e; ++t) {
      const double* n = &fn[3 * (size_t)tr.face[t]];
      for (int k = 0; k < 3; ++k) {
        const double* c = &tcn[9 * t + 3 * k];
        if (!(c[0] * n[0] + c[1] * n[1] + c[2] * n[2] >= cos_tol)) flat[t] = 0;
      }
    }
  });
  std::vector<uint8_t> face_flat(F, 1);
  for (size_t t = 0; t < T; ++t) face_flat[tr.face[t]] &= flat[t];
  parallel_for((long long)T, threads, [&](long long b, long long e) {
    for (long long t = b; t < e; ++t) flat[t] = face_flat[tr.face[t]];
  });
  return flat;
}

}  // namespace sffd
