// The normals at the input's triangle corners: the given split normals (or smooth ones), and
// which triangles belong to flat faces (plan/rest_surface.hpp: they follow their own planes).
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd {

// v normalized, or fallback where v has no finite nonzero length. Inline: the plan's normal
// stages call it per corner and per patch corner on every pose.
inline void normalize_or(double* v, const double* fallback) {
  double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (l > 1e-30 && std::isfinite(l)) {
    for (int i = 0; i < 3; ++i) v[i] /= l;
  } else {
    for (int i = 0; i < 3; ++i) v[i] = fallback[i];
  }
}

// Unit normal at every triangle corner (#T x 3 x 3): the input split normals, or smooth
// area-weighted vertex normals when none are given. tv: the triangles' vertices (#T x 3).
std::vector<double> triangle_corner_normals(const InputMesh& m, const Triangulation& tr, const std::vector<int>& tv);

// Triangles of flat faces: faces whose every corner normal is within the sharp angle
// (cos_tol) of the face's own (Newell) normal, the normal Blender and most tools give a
// polygon. #T, 0 or 1.
std::vector<uint8_t> flat_triangles(const InputMesh& m, const Triangulation& tr, const std::vector<double>& tcn,
                                    double cos_tol);

}  // namespace sffd
