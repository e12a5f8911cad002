// Small meshes and lattices built in code for the native unit tests (no files, no Python).
#pragma once

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/eval/cpu_evaluator.hpp"
#include "smoothffd/plan/plan.hpp"

namespace sffd_test {

// A plan at `level`, shared as the evaluators take it.
inline std::shared_ptr<const sffd::Plan> plan_of(const sffd::InputMesh& m, const sffd::LatticeSpec& s,
                                                 int level) {
  sffd::PlanOptions opt;
  opt.level = level;
  return std::make_shared<const sffd::Plan>(sffd::build_plan(m, s, opt));
}

// One CPU frame: positions (N x 3) and corner normals (T x 3 x 3); isa as CpuEvaluator's.
struct CpuOut {
  std::vector<float> pos, nrm;
};

inline CpuOut run_cpu(const std::shared_ptr<const sffd::Plan>& plan, const std::vector<float>& D,
                      int threads = 0, const std::string& isa = "auto") {
  sffd::CpuEvaluator ev(plan, threads, isa);
  CpuOut o;
  o.pos.resize(3 * (size_t)plan->output_vertices);
  o.nrm.resize(9 * (size_t)plan->output_triangles);
  ev.evaluate(D.data(), o.pos.data(), o.nrm.data(), sffd::Frame::whole);
  return o;
}

using sffd::AxisBasis;
using sffd::InputMesh;
using sffd::LatticeSpec;

// Clamped (open-uniform) knot vector on [0, 1].
inline std::vector<double> clamped_knots(int p, int n) {
  std::vector<double> U;
  for (int i = 0; i <= p; ++i) U.push_back(0);
  for (int i = 1; i < n - p; ++i) U.push_back(double(i) / (n - p));
  for (int i = 0; i <= p; ++i) U.push_back(1);
  return U;
}

// B-spline lattice structure over the box [lo, hi]^3 mapped onto [0, 1]^3, `n` control
// points and degree `p` on every axis (internal knot planes at i / (n - p)).
inline LatticeSpec bspline_box(int p, int n, double lo = 0.0, double hi = 1.0) {
  LatticeSpec s;
  for (int a = 0; a < 3; ++a) {
    s.axes[a] = AxisBasis::bspline(p, clamped_knots(p, n), n);
    s.object_to_param[a][a] = 1.0 / (hi - lo);
    s.object_to_param[a][3] = -lo / (hi - lo);
  }
  return s;
}

// Control displacements that make the B-spline volume the identity: all zero (F = p + W D).
inline std::vector<float> zero_values(const LatticeSpec& s) {
  return std::vector<float>((size_t)s.components * s.count(), 0.0f);
}

// Mesh of triangles only.
inline InputMesh tri_mesh(const std::vector<double>& X, const std::vector<int>& tris) {
  InputMesh m;
  m.positions = X;
  m.corner_vertex = tris;
  for (size_t f = 0; f <= tris.size() / 3; ++f) m.face_offset.push_back(int(3 * f));
  return m;
}

// Octahedron centred at c with radius r (closed, genus 0, consistently wound outwards).
inline InputMesh octahedron(double cx = 0.5, double cy = 0.5, double cz = 0.5, double r = 0.4) {
  std::vector<double> X = {cx + r, cy, cz, cx - r, cy, cz, cx, cy + r, cz,
                           cx, cy - r, cz, cx, cy, cz + r, cx, cy, cz - r};
  std::vector<int> T = {0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5};
  return tri_mesh(X, T);
}

// Axis-aligned cube [lo, hi]^3 as 6 quads (polygons), outward winding.
inline InputMesh cube_quads(double lo = 0.2, double hi = 0.8) {
  InputMesh m;
  for (int i = 0; i < 8; ++i) {
    m.positions.push_back(i & 1 ? hi : lo);
    m.positions.push_back(i & 2 ? hi : lo);
    m.positions.push_back(i & 4 ? hi : lo);
  }
  m.corner_vertex = {0, 2, 3, 1, 4, 5, 7, 6, 0, 1, 5, 4, 2, 6, 7, 3, 0, 4, 6, 2, 1, 3, 7, 5};
  for (int f = 0; f <= 6; ++f) m.face_offset.push_back(4 * f);
  return m;
}

// Flat (z = z0) regular grid of n x n quads split into triangles over [lo, hi]^2.
inline InputMesh flat_grid(int n, double lo = 0.1, double hi = 0.9, double z0 = 0.37) {
  std::vector<double> X;
  std::vector<int> T;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      X.push_back(lo + (hi - lo) * i / n);
      X.push_back(lo + (hi - lo) * j / n);
      X.push_back(z0);
    }
  auto id = [n](int i, int j) { return j * (n + 1) + i; };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      T.insert(T.end(), {id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      T.insert(T.end(), {id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
  return tri_mesh(X, T);
}

// Undirected edge -> number of triangles using it, and directed edge counts.
struct EdgeCounts {
  std::map<std::pair<int, int>, int> undirected, directed;
};
inline EdgeCounts count_edges(const std::vector<int>& tv) {
  EdgeCounts c;
  for (size_t t = 0; t + 2 < tv.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      int a = tv[t + k], b = tv[t + (k + 1) % 3];
      c.directed[{a, b}]++;
      c.undirected[{std::min(a, b), std::max(a, b)}]++;
    }
  return c;
}

inline double tri_area(const double* a, const double* b, const double* c) {
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  return 0.5 * std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
}

}  // namespace sffd_test

namespace sffd_test {

// Blender lattice structure with n points per axis spanning the box [lo, hi]^3.
inline LatticeSpec blender_box(sffd::BlenderInterp type, int n, double lo = 0.0, double hi = 1.0) {
  LatticeSpec s;
  for (int a = 0; a < 3; ++a) {
    s.axes[a] = AxisBasis::blender(type, n);
    double scale = n > 1 ? (n - 1) / (hi - lo) : 0.0;
    s.object_to_param[a][a] = scale;
    s.object_to_param[a][3] = -lo * scale;
  }
  return s;
}

// A random lattice structure: B-spline (random degree per axis, random non-decreasing knots
// with repeated interior knots) or Blender (random type and count), over a random box.
inline LatticeSpec random_lattice(std::mt19937& rng) {
  std::uniform_int_distribution<int> coin(0, 1), deg(1, 3), extra(0, 3), bl(0, 3), cnt(1, 5);
  std::uniform_real_distribution<double> U(0, 1);
  LatticeSpec s;
  bool blender = coin(rng);
  double lo = -0.2 + 0.3 * U(rng), hi = 0.9 + 0.4 * U(rng);
  for (int a = 0; a < 3; ++a) {
    if (blender) {
      int n = cnt(rng);
      s.axes[a] = AxisBasis::blender(sffd::BlenderInterp(bl(rng)), n);
      double scale = n > 1 ? (n - 1) / (hi - lo) : 0.0;
      s.object_to_param[a][a] = scale;
      s.object_to_param[a][3] = -lo * scale;
    } else {
      int p = deg(rng), n = p + 1 + extra(rng);
      std::vector<double> inner;
      for (int i = 0; i < n - p - 1; ++i) inner.push_back(U(rng) < 0.3 && !inner.empty() ? inner.back() : U(rng));
      std::sort(inner.begin(), inner.end());
      std::vector<double> knots(p + 1, 0.0);
      knots.insert(knots.end(), inner.begin(), inner.end());
      knots.insert(knots.end(), p + 1, 1.0);
      s.axes[a] = AxisBasis::bspline(p, knots, n);
      s.object_to_param[a][a] = 1.0 / (hi - lo);
      s.object_to_param[a][3] = -lo / (hi - lo);
    }
  }
  return s;
}

// A random polygon soup: points partly outside the lattice box, faces of 3..6 corners with
// random (possibly repeated) vertices, sometimes split normals (some zero), UVs and weights.
inline InputMesh random_mesh(std::mt19937& rng, int max_vertices = 30, int max_faces = 30) {
  std::uniform_real_distribution<double> U(-0.3, 1.3), N(-1, 1);
  std::uniform_int_distribution<int> nv(3, max_vertices), nf(1, max_faces), fs(3, 6), coin(0, 3);
  InputMesh m;
  int V = nv(rng), F = nf(rng);
  for (int i = 0; i < 3 * V; ++i) m.positions.push_back(U(rng));
  std::uniform_int_distribution<int> vid(0, V - 1);
  m.face_offset.push_back(0);
  for (int f = 0; f < F; ++f) {
    int n = fs(rng);
    for (int k = 0; k < n; ++k) m.corner_vertex.push_back(vid(rng));
    m.face_offset.push_back((int)m.corner_vertex.size());
  }
  size_t C = m.corner_vertex.size();
  if (coin(rng) == 0)
    for (size_t i = 0; i < 3 * C; ++i) m.corner_normal.push_back(coin(rng) == 0 ? 0.0f : (float)N(rng));
  if (coin(rng) == 0)
    for (size_t i = 0; i < 2 * C; ++i) m.corner_uv.push_back((float)N(rng));
  if (coin(rng) == 0)
    for (int i = 0; i < V; ++i) m.vertex_weight.push_back((float)(2 * N(rng)));
  return m;
}

}  // namespace sffd_test
