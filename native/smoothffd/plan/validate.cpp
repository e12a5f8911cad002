#include "smoothffd/plan/validate.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

namespace sffd {

void check_input_mesh(const InputMesh& m) {
  size_t V = m.positions.size() / 3, C = m.corner_vertex.size();
  if (m.positions.size() % 3) throw std::invalid_argument("positions: expected #V x 3 values");
  if (m.face_offset.empty() || m.face_offset.front() != 0 || (size_t)m.face_offset.back() != C)
    throw std::invalid_argument("face_offsets: must start at 0 and end at the corner count");
  for (size_t f = 0; f + 1 < m.face_offset.size(); ++f)
    if (m.face_offset[f + 1] - m.face_offset[f] < 3)
      throw std::invalid_argument("faces: face " + std::to_string(f) + " has fewer than 3 corners");
  for (int v : m.corner_vertex)
    if (v < 0 || (size_t)v >= V) throw std::invalid_argument("faces: vertex index out of range");
  if (!m.corner_normal.empty() && m.corner_normal.size() != 3 * C)
    throw std::invalid_argument("corner_normals: expected one normal per face corner");
  if (!m.corner_uv.empty() && m.corner_uv.size() != 2 * C)
    throw std::invalid_argument("uvs: expected one UV per face corner");
  if (!m.vertex_weight.empty() && m.vertex_weight.size() != V)
    throw std::invalid_argument("vertex_weights: expected one weight per vertex");
  for (double x : m.positions)
    if (!std::isfinite(x)) throw std::invalid_argument("positions: contain NaN or Inf");
}

void check_triangulation(const InputMesh& m, const Triangulation& tr) {
  const size_t T = tr.face.size(), F = m.face_offset.size() - 1;
  if (tr.corners.size() != 3 * T)
    throw std::invalid_argument("triangulation: expected three corners and one face a triangle");
  std::vector<int> per_face(F, 0);
  for (size_t t = 0; t < T; ++t) {
    const int f = tr.face[t];
    if (f < 0 || (size_t)f >= F)
      throw std::invalid_argument("triangulation: triangle " + std::to_string(t) + "'s face is out of range");
    const int* c = &tr.corners[3 * t];
    for (int k = 0; k < 3; ++k)
      if (c[k] < m.face_offset[f] || c[k] >= m.face_offset[f + 1] || c[k] == c[(k + 1) % 3])
        throw std::invalid_argument("triangulation: triangle " + std::to_string(t) +
                                    " is not three distinct corners of its face (the mesh's faces differ "
                                    "from those it was made for)");
    if (++per_face[f] > m.face_offset[f + 1] - m.face_offset[f] - 2)
      throw std::invalid_argument("triangulation: face " + std::to_string(f) + " has more triangles than corners - 2");
  }
}

void check_lattice_structure(const LatticeSpec& lattice) {
  for (int a = 0; a < 3; ++a)
    if (lattice.axes[a].pieces().size() > 1023)
      throw std::invalid_argument("lattice: too many knot spans on one axis (at most 1023)");
  if (lattice.components != 3 && lattice.components != 4)
    throw std::invalid_argument("lattice: components must be 3, or 4 with point weights");
  // The evaluators run in float: every value of the lattice tables must be a finite float, or
  // the output is NaN. Refused here, before any work, saying which axis and why.
  const char* axis = "uvw";
  auto finite_float = [](double x) { return std::isfinite(x) && std::isfinite((float)x); };
  for (int a = 0; a < 3; ++a) {
    for (const AxisPiece& pc : lattice.axes[a].pieces()) {
      bool ok = finite_float(pc.origin) && finite_float(1.0 / pc.scale);
      for (int k = 0; k < kMaxTerms && ok; ++k)
        for (int q = 0; q < kMaxTerms && ok; ++q) ok = finite_float(pc.coef[k][q]);
      if (!ok) {
        char msg[300];
        std::snprintf(msg, sizeof(msg),
                      "lattice: axis %c has a knot span of width %.6g at %.6g, beyond what float "
                      "evaluation can represent (spans and knots between about 1e-30 and 1e30)",
                      axis[a], pc.scale, pc.origin);
        throw std::invalid_argument(msg);
      }
    }
    for (int c = 0; c < 4; ++c)
      if (!finite_float(lattice.object_to_param[a][c]))
        throw std::invalid_argument("lattice: the object-to-parameter map is beyond float range "
                                    "(a lattice box too small or too large)");
  }
}

}  // namespace sffd
