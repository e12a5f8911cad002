#include "smoothffd/plan/plan.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/core/parallel.hpp"
#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/centre_rows.hpp"
#include "smoothffd/plan/clip.hpp"
#include "smoothffd/plan/corner_normals.hpp"
#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/fit_matrix.hpp"
#include "smoothffd/plan/render_vertices.hpp"
#include "smoothffd/plan/rest_surface.hpp"
#include "smoothffd/plan/sources.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {
namespace {

using Clock = std::chrono::steady_clock;

struct StageTimer {
  Plan& plan;
  Clock::time_point t0 = Clock::now();
  void lap(const char* name) {
    auto t1 = Clock::now();
    plan.build_ms.emplace_back(name, std::chrono::duration<double, std::milli>(t1 - t0).count());
    t0 = t1;
  }
};

void validate(const InputMesh& m) {
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

uint32_t pack_pieces(const int p[3]) { return uint32_t(p[0]) | uint32_t(p[1]) << 10 | uint32_t(p[2]) << 20; }

// The evaluators run in float: every value of the lattice tables (step 7) must be a finite
// float, or the output is NaN. Refused here, before any work, saying which axis and why.
void check_float_range(const LatticeSpec& lattice) {
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

// The shift step 7 measures an axis's float parameter from: its first knot plane when that
// lies further from 0 than the planes' extent, else 0.
double float_shift(const AxisBasis& axis) {
  const std::vector<double> planes = axis.planes();
  if (!planes.empty() && std::fabs(planes.front()) > planes.back() - planes.front()) return planes.front();
  return 0.0;
}

// Whether the float evaluation of t = (s(p) - origin) / scale from a sample's float position
// loses more than 2^-11 of some span: its rounding is about 2^-24 (|ds/dp| |p| + |b - shift| +
// |origin - shift|) / scale (knot spans small next to the mesh's distance from 0, or to the
// others: then each sample's t is computed in double at plan time).
bool needs_local_coordinates(const LatticeSpec& lattice, const std::vector<double>& pos) {
  double R = 0;
  for (double x : pos) R = std::max(R, std::fabs(x));
  for (int a = 0; a < 3; ++a) {
    const double* A = lattice.object_to_param[a];
    const double G = std::fabs(A[0]) + std::fabs(A[1]) + std::fabs(A[2]);
    const double shift = float_shift(lattice.axes[a]);
    for (const AxisPiece& pc : lattice.axes[a].pieces()) {
      if (pc.degree == 0) continue;
      const double err = G * R + std::fabs(A[3] - shift) + std::fabs(pc.origin - shift);
      if (err > std::ldexp(pc.scale, 13)) return true;
    }
  }
  return false;
}

}  // namespace

size_t Plan::bytes() const {
  size_t b = 0;
  b += pieces.size() * sizeof(AxisPieceF);
  b += 4 * (sample_position.size() + sample_piece.size() + sample_weight.size() + sample_local.size() +
            fit_matrix.size() + column_bary.size() + patch_samples.size() + patch_vertex.size() +
            patch_edge.size() + patch_render_normal.size() + patch_adjust_normal.size() +
            patch_face.size() + edge_vertex.size() + edge_constraint.size() + edge_patch.size() +
            grid_basis.size() + local_triangles.size() + patch_grid_vertex.size() +
            output_owner.size() + rest_positions.size() + triangles.size() + face_index.size() +
            uvs.size() + sharp_edges.size() + render_owner.size() + render_position.size() +
            patch_grid_render.size() + render_triangles.size() + input_triangle_corner.size() +
            input_triangle_face.size() + patch_triangle.size() + centre_row.size() + centre_constant.size());
  b += 8 * (centre_box.size() + centre_start.size());
  b += 8 * patch_bary.size();
  b += patch_edge_reversed.size() + edge_slot.size() + edge_flags.size();
  return b;
}

double estimate_plan_bytes(double P, double SV, int level, int fit_degree, bool uvs) {
  const double L = level, n = std::max(3, fit_degree);
  const double K = (n + 1) * (n + 2) / 2 + 9, G = (L + 1) * (L + 2) / 2;
  const double E = 1.5 * P + SV;                        // edges of a closed triangle mesh
  const double T = P * L * L;                           // output triangles
  const double N = SV + E * (L - 1) + P * (L - 1) * (L - 2) / 2;  // output vertices
  const double S = SV + E * (n - 1) + P * (n - 1) * (n - 2) / 2;  // samples
  const double row = std::ceil(std::pow(n / 3.0 + 1, 3) / 8) * 8;  // centre row (plan/centre_rows.hpp)
  const double per_patch = 4 * K + 4 * (3 + 3 + 9 + 9 + 1 + 1) + 72 + 1 + 8 * G + 240 + 240 + 4 * (row + 3) + 16;
  const double per_edge = 4 * (2 + 2 + 2 + 4) + 4 + 1 + 24;
  const double per_triangle = 2 * (12 + 4 + 12 + (uvs ? 24 : 0)) + 36;  // plan + numpy copy, normals
  const double per_vertex = 2 * (12 + 8 + 12) + 12;     // rest, owners (plan + copy), positions
  const double per_sample = 12 + 4 + 4 + 48;            // position, piece, weight, F and J
  return P * per_patch + E * per_edge + T * per_triangle + N * per_vertex + S * per_sample;
}

Plan build_plan(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& opt) {
  validate(mesh);
  if (opt.level < 1) throw std::invalid_argument("level: must be at least 1");
  // The tessellation tables grow as L^2 whatever the mesh: level 2^31 - 1 from the bindings
  // spent 11 s allocating before a MemoryError (found by native/fuzz/fuzz_bindings.py).
  if (opt.level > kMaxLevel)
    throw std::invalid_argument("level: at most " + std::to_string(kMaxLevel) + " (L^2 triangles a patch), got " +
                                std::to_string(opt.level));
  for (int a = 0; a < 3; ++a)
    if (lattice.axes[a].pieces().size() > 1023)
      throw std::invalid_argument("lattice: too many knot spans on one axis (at most 1023)");
  if (lattice.components != 3 && lattice.components != 4)
    throw std::invalid_argument("lattice: components must be 3, or 4 with point weights");
  check_float_range(lattice);
  Plan plan;
  StageTimer timer{plan};
  const int V = (int)(mesh.positions.size() / 3);
  const std::vector<double>& X = mesh.positions;
  const double cos_tol = std::cos(opt.sharp_angle_degrees * M_PI / 180.0);

  // 1. Triangulation, corner normals and the sharpness of the input's edge ends.
  Triangulation tr = triangulate_polygons(X, mesh.corner_vertex, mesh.face_offset);
  std::vector<int> tv(tr.corners.size());
  for (size_t i = 0; i < tv.size(); ++i) tv[i] = mesh.corner_vertex[tr.corners[i]];
  std::vector<double> tcn = triangle_corner_normals(mesh, tr, tv);
  EdgeTable in_edges = build_edges(tv);
  std::vector<uint8_t> in_sharp = classify_sharp_ends(in_edges, tv, tcn, cos_tol);
  // The normals the geometry follows (plan/rest_surface.hpp): flat faces their triangles' own.
  AdjustNormals adjust(X, tv, tcn, flat_triangles(mesh, tr, tcn, cos_tol));
  timer.lap("triangulate");

  // 2. Knot-box clipping; the crease-aware PN rest surface from the adjustment normals,
  // bounded so that no patch, nor the triangle through any piece's corners on it, folds; clip
  // vertices move onto the rest surface (4.3.1).
  ClipResult clip = clip_to_knot_boxes(X, tv, lattice);
  const int SV = clip.sub_vertices(), P = clip.patches();
  if (opt.memory_limit > 0) {
    const double need = estimate_plan_bytes(P, SV, opt.level, lattice.degree_sum(), !mesh.corner_uv.empty());
    if (need > opt.memory_limit) {
      char msg[400];
      std::snprintf(msg, sizeof(msg),
                    "level %d: %d triangles clipped by the lattice's knot planes into %d patches need "
                    "about %.2f GiB (plan, frame buffers and one result), more than the %.2f GiB "
                    "available; lower the level or use a lattice with fewer knot spans across the mesh",
                    opt.level, (int)(tv.size() / 3), P, need / 1073741824.0, opt.memory_limit / 1073741824.0);
      throw PlanTooLarge(msg);
    }
  }
  RestSurface rest;
  {
    std::vector<int> piece_start(tv.size() / 3 + 1, 0);
    for (int p = 0; p < P; ++p) piece_start[clip.patch_tri[p] + 1]++;
    for (size_t t = 0; t + 1 < piece_start.size(); ++t) piece_start[t + 1] += piece_start[t];
    std::vector<double> piece_bary(9 * (size_t)P);
    std::vector<int> fill(piece_start.begin(), piece_start.end() - 1);
    for (int p = 0; p < P; ++p) {
      const int q = fill[clip.patch_tri[p]]++;
      std::copy(&clip.patch_bary[9 * (size_t)p], &clip.patch_bary[9 * (size_t)p] + 9, &piece_bary[9 * (size_t)q]);
    }
    plan.bounded_vertices = bound_adjust_normals(X, tv, in_edges, in_sharp, tcn, adjust, rest, &piece_start, &piece_bary);
  }
  for (uint8_t f : adjust.flat) plan.flat_triangles += f;
  const std::vector<double>& acn = adjust.corner;
  // The shading normals, turned where the geometry cannot follow them (rest_surface.hpp).
  std::vector<double> shade(tcn);
  plan.turned_normals = bound_render_normals(adjust, shade, nullptr);
  std::vector<double> moved(clip.flat);
  std::vector<double> sub_weight(SV, 1.0);
  CancelPoller poller(256);
  for (int v = 0; v < SV; ++v) {
    poller.tick();
    if (v < V) {
      if (!mesh.vertex_weight.empty()) sub_weight[v] = mesh.vertex_weight[v];
      continue;
    }
    int t = clip.origin_tri[v];
    const double* b = &clip.origin_bary[3 * (size_t)v];
    rest_surface_point(rest, X, tv, in_edges, t, b, &moved[3 * (size_t)v]);
    if (!mesh.vertex_weight.empty()) {
      sub_weight[v] = 0;
      for (int k = 0; k < 3; ++k) sub_weight[v] += b[k] * mesh.vertex_weight[tv[3 * t + k]];
    }
  }
  timer.lap("clip");

  // 3. Patches: corner normals for shading (barycentric, 4.3.2) and for the adjustment
  // (the PN quadratic normal field at clip vertices, the input normal at input vertices).
  plan.patch_vertex = clip.patch_vertex;
  plan.patch_face.resize(P);
  plan.patch_render_normal.resize(9 * (size_t)P);
  plan.patch_adjust_normal.resize(9 * (size_t)P);
  std::vector<double> render_d(9 * (size_t)P), adjust_d(9 * (size_t)P);
  for (int p = 0; p < P; ++p) {
    poller.tick();
    int t = clip.patch_tri[p];
    plan.patch_face[p] = tr.face[t];
    double Pt[9], Nt[9], At[9];
    for (int k = 0; k < 3; ++k)
      for (int i = 0; i < 3; ++i) {
        Pt[3 * k + i] = X[3 * (size_t)tv[3 * t + k] + i];
        Nt[3 * k + i] = shade[9 * (size_t)t + 3 * k + i];
        At[3 * k + i] = acn[9 * (size_t)t + 3 * k + i];
      }
    for (int c = 0; c < 3; ++c) {
      const double* b = &clip.patch_bary[9 * (size_t)p + 3 * c];
      double rn[3], an[3];
      for (int i = 0; i < 3; ++i) rn[i] = b[0] * Nt[i] + b[1] * Nt[3 + i] + b[2] * Nt[6 + i];
      normalize_or(rn, Nt);
      const int v = plan.patch_vertex[3 * p + c];
      if (v < V) {
        const int k = slot_of(tv, t, v);
        for (int i = 0; i < 3; ++i) an[i] = At[3 * k + i];
      } else {
        pn_quadratic_normal(Pt, At, b, an);
      }
      for (int i = 0; i < 3; ++i) {
        render_d[9 * (size_t)p + 3 * c + i] = rn[i];
        adjust_d[9 * (size_t)p + 3 * c + i] = an[i];
      }
    }
  }
  // Where each patch lies on the input (plan/sources.hpp: UVs and any other carried data).
  plan.input_corners = (int)mesh.corner_vertex.size();
  plan.input_triangle_corner = tr.corners;
  plan.input_triangle_face = tr.face;
  plan.patch_triangle = clip.patch_tri;
  plan.patch_bary = clip.patch_bary;

  // 4. Sub-mesh adjacency. The patches the evaluators make at rest from the clip vertices on
  // the rest surface must not fold either (pieces next to cuts can be thin): the same bound on
  // the sub-mesh, then its shading normals turned where its geometry cannot follow them. A
  // turn can split a vertex's normals (sharp ends: other edge control points), so both repeat
  // until nothing turns (each round lowers some trust; at most 8 rounds).
  EdgeTable sub = build_edges(plan.patch_vertex);
  const int E = sub.count();
  std::vector<uint8_t> sharp;
  {
    // A patch that is a whole input triangle is that triangle's rest patch, checked above.
    std::vector<uint8_t> sub_flat(P), check(P), turned(3 * (size_t)P, 0);
    std::vector<int> pieces(tv.size() / 3, 0);
    for (int p = 0; p < P; ++p) pieces[clip.patch_tri[p]]++;
    for (int p = 0; p < P; ++p) {
      sub_flat[p] = adjust.flat[clip.patch_tri[p]];
      check[p] = pieces[clip.patch_tri[p]] > 1;
    }
    AdjustNormals sub_adjust(moved, plan.patch_vertex, adjust_d, sub_flat);
    RestSurface sub_rest;
    for (int round = 0;; ++round) {
      sharp = classify_sharp_ends(sub, plan.patch_vertex, render_d, cos_tol);
      plan.bounded_sub_vertices = bound_adjust_normals(moved, plan.patch_vertex, sub, sharp, render_d, sub_adjust,
                                                       sub_rest, nullptr, nullptr, &check);
      if (round == 7 || !bound_render_normals(sub_adjust, render_d, &turned)) break;
      check.assign(P, 1);
    }
    for (uint8_t f : turned) plan.turned_sub_normals += f;
    for (size_t i = 0; i < plan.patch_adjust_normal.size(); ++i) {
      plan.patch_adjust_normal[i] = (float)sub_adjust.corner[i];
      plan.patch_render_normal[i] = (float)render_d[i];
    }
  }
  plan.edge_vertex = sub.vertex;
  plan.edge_patch = sub.side;
  plan.edge_flags.resize(E);
  plan.edge_slot.assign(4 * (size_t)E, 0);
  for (int e = 0; e < E; ++e) {
    uint8_t f = sharp[e];
    if (sub.face_count[e] == 1) f |= kBoundary;
    if (sub.face_count[e] > 2) f |= kNonManifold;
    // A flat face's edges (docs/algorithm.md, "Flat faces"): its patches are the accurate FFD
    // of its triangles, edges included, so the edge a smooth face shares with it follows the
    // flat one, straight at rest.
    for (int s = 0; s < 2; ++s) {
      const int p = sub.side[2 * e + s];
      if (p >= 0 && adjust.flat[clip.patch_tri[p]]) f |= kFlatFace;
    }
    plan.edge_flags[e] = f;
    for (int s = 0; s < 2; ++s) {
      int p = sub.side[2 * e + s];
      if (p < 0) continue;
      plan.edge_slot[4 * (size_t)e + 2 * s] = (uint8_t)slot_of(plan.patch_vertex, p, sub.vertex[2 * e]);
      plan.edge_slot[4 * (size_t)e + 2 * s + 1] = (uint8_t)slot_of(plan.patch_vertex, p, sub.vertex[2 * e + 1]);
    }
  }
  plan.patch_edge = sub.tri_edge;
  plan.patch_edge_reversed.resize(3 * (size_t)P);
  for (int p = 0; p < P; ++p)
    for (int k = 0; k < 3; ++k)
      plan.patch_edge_reversed[3 * p + k] = sub.vertex[2 * sub.tri_edge[3 * p + k]] != plan.patch_vertex[3 * p + k];
  timer.lap("adjacency");

  // 5. Samples (sec. 5.1): one per sub-vertex, per point inside an edge, per interior point.
  const int n = std::max(3, lattice.degree_sum());
  FitTables fit = build_fit_tables(n);
  const int K = fit.columns, N3 = 3 * n;
  std::vector<int> edge_num;  // numerators over 3n of the sample points inside an edge
  for (int q = 1; q < N3; ++q)
    if (q % 3 == 0 || q == n || q == 2 * n) edge_num.push_back(q);
  const int ES = (int)edge_num.size(), IS = (n - 1) * (n - 2) / 2;
  auto edge_index = [&](int q) { return int(std::lower_bound(edge_num.begin(), edge_num.end(), q) - edge_num.begin()); };
  const long long S = (long long)SV + (long long)E * ES + (long long)P * IS;
  if (S > 2000000000LL) throw std::invalid_argument("mesh: too large for one plan");
  plan.sample_position.resize(3 * S);
  std::vector<double> sample_exact(3 * S);  // the positions before rounding to float
  plan.sample_weight.resize(S);
  auto put_sample = [&](long long s, const double* pos, double w) {
    for (int i = 0; i < 3; ++i) {
      plan.sample_position[3 * s + i] = (float)pos[i];
      sample_exact[3 * s + i] = pos[i];
    }
    plan.sample_weight[s] = (float)w;
  };
  for (int v = 0; v < SV; ++v) put_sample(v, &moved[3 * (size_t)v], sub_weight[v]);
  for (int e = 0; e < E; ++e) {
    int a = sub.vertex[2 * e], b = sub.vertex[2 * e + 1];
    for (int j = 0; j < ES; ++j) {
      double t = edge_num[j] / double(N3), pos[3];
      for (int i = 0; i < 3; ++i) pos[i] = (1 - t) * moved[3 * (size_t)a + i] + t * moved[3 * (size_t)b + i];
      put_sample(SV + (long long)e * ES + j, pos, (1 - t) * sub_weight[a] + t * sub_weight[b]);
    }
  }
  std::vector<int> column_interior(K, -1);
  for (int k = 0, ord = 0; k < K; ++k) {
    const int* q = &fit.numerator[3 * k];
    if (q[0] > 0 && q[1] > 0 && q[2] > 0) column_interior[k] = ord++;
  }
  plan.patch_samples.resize((size_t)P * K);
  for (int p = 0; p < P; ++p) {
    poller.tick();
    const int* cv = &plan.patch_vertex[3 * p];
    for (int k = 0; k < K; ++k) {
      const int* q = &fit.numerator[3 * k];
      long long s;
      int zeros = (q[0] == 0) + (q[1] == 0) + (q[2] == 0);
      if (zeros == 2) {
        s = cv[q[0] ? 0 : q[1] ? 1 : 2];
      } else if (zeros == 1) {
        int ek = q[2] == 0 ? 0 : q[0] == 0 ? 1 : 2;  // edge corner ek -> ek + 1
        int along = q[(ek + 1) % 3];                  // numerator of the far corner
        if (plan.patch_edge_reversed[3 * p + ek]) along = N3 - along;
        s = SV + (long long)plan.patch_edge[3 * p + ek] * ES + edge_index(along);
      } else {
        s = SV + (long long)E * ES + (long long)p * IS + column_interior[k];
        double b[3] = {q[0] / double(N3), q[1] / double(N3), q[2] / double(N3)}, pos[3], w = 0;
        for (int i = 0; i < 3; ++i) {
          pos[i] = 0;
          for (int c = 0; c < 3; ++c) pos[i] += b[c] * moved[3 * (size_t)cv[c] + i];
        }
        for (int c = 0; c < 3; ++c) w += b[c] * sub_weight[cv[c]];
        put_sample(s, pos, w);
      }
      plan.patch_samples[(size_t)p * K + k] = (int)s;
    }
  }
  plan.edge_constraint.resize(2 * (size_t)E);
  for (int e = 0; e < E; ++e) {
    plan.edge_constraint[2 * e] = SV + e * ES + edge_index(n);
    plan.edge_constraint[2 * e + 1] = SV + e * ES + edge_index(2 * n);
  }
  // Each sample's piece, and where the evaluators' float arithmetic (t from the float position
  // and the float map, about 6e-8 (|ds/dp| |p| + |s - shift| + |origin - shift|) / span of
  // the span) cannot place a sample within 2^-11 of its span, each sample's local coordinate t
  // in its span, computed here in double from its exact position (sample_local).
  const bool local = needs_local_coordinates(lattice, sample_exact);
  plan.sample_piece.resize(S);
  if (local) plan.sample_local.resize(3 * S);
  parallel_for(S, default_threads(), [&](long long b, long long e) {
    for (long long s = b; s < e; ++s) {
      double pos[3], prm[3];
      int pc[3];
      for (int i = 0; i < 3; ++i) pos[i] = local ? sample_exact[3 * s + i] : plan.sample_position[3 * s + i];
      lattice.to_param(pos, prm);
      lattice.find_pieces(prm, pc);
      plan.sample_piece[s] = pack_pieces(pc);
      if (local)
        for (int a = 0; a < 3; ++a) {
          const AxisPiece& piece = lattice.axes[a].pieces()[pc[a]];
          plan.sample_local[3 * s + a] = piece.degree == 0 ? 0.0f : (float)((prm[a] - piece.origin) / piece.scale);
        }
    }
  });
  build_centre_rows(plan, lattice, fit, sample_exact);
  std::vector<double>().swap(sample_exact);
  plan.fit_matrix.assign(fit.M_r.begin(), fit.M_r.end());
  plan.column_bary.resize(3 * (size_t)K);
  for (int i = 0; i < 3 * K; ++i) plan.column_bary[i] = (float)(fit.numerator[i] / double(N3));
  timer.lap("samples");

  // 6. Tessellation tables and the welded output topology.
  const int L = opt.level;
  TessellationTables tess = build_tessellation(L);
  const int G = tess.grid, IG = (L - 1) * (L - 2) / 2;
  const long long N = (long long)SV + (long long)E * (L - 1) + (long long)P * IG;
  const long long T = (long long)P * L * L;
  if (N > 2000000000LL || 3 * T > 2000000000LL)
    throw std::invalid_argument("level: output too large (" + std::to_string(T) + " triangles)");
  plan.grid_basis = tess.basis;
  plan.local_triangles = tess.triangles;
  plan.patch_grid_vertex.resize((size_t)P * G);
  plan.output_owner.assign(2 * (size_t)(N - SV), -1);
  plan.rest_positions.resize(3 * (size_t)N);
  for (int v = 0; v < SV; ++v)
    for (int i = 0; i < 3; ++i) plan.rest_positions[3 * (size_t)v + i] = (float)clip.flat[3 * (size_t)v + i];
  for (int p = 0; p < P; ++p) {
    poller.tick();
    const int* cv = &plan.patch_vertex[3 * p];
    for (int g = 0; g < G; ++g) {
      const GridPoint& gp = tess.points[g];
      long long o;
      if (gp.kind == 0) {
        o = cv[gp.which];
      } else if (gp.kind == 1) {
        int m = plan.patch_edge_reversed[3 * p + gp.which] ? L - gp.step : gp.step;
        o = SV + (long long)plan.patch_edge[3 * p + gp.which] * (L - 1) + (m - 1);
      } else {
        o = SV + (long long)E * (L - 1) + (long long)p * IG + gp.which;
      }
      plan.patch_grid_vertex[(size_t)p * G + g] = (int)o;
      if (o >= SV && plan.output_owner[2 * (o - SV)] < 0) {
        plan.output_owner[2 * (o - SV)] = p;
        plan.output_owner[2 * (o - SV) + 1] = g;
        const double* b = &tess.bary[3 * g];
        for (int i = 0; i < 3; ++i) {
          double x = 0;
          for (int c = 0; c < 3; ++c) x += b[c] * clip.flat[3 * (size_t)cv[c] + i];
          plan.rest_positions[3 * o + i] = (float)x;
        }
      }
    }
  }
  plan.triangles.resize(3 * (size_t)T);
  plan.face_index.resize(T);
  const int LL = L * L;
  for (int p = 0; p < P; ++p)
    for (int t = 0; t < LL; ++t) {
      if (t == 0) poller.tick();
      size_t ot = (size_t)p * LL + t;
      plan.face_index[ot] = plan.patch_face[p];
      for (int c = 0; c < 3; ++c)
        plan.triangles[3 * ot + c] = plan.patch_grid_vertex[(size_t)p * G + tess.triangles[3 * t + c]];
    }
  plan.level = L;  // interpolate_corners reads it
  if (!mesh.corner_uv.empty()) {
    plan.uvs.resize(6 * (size_t)T);
    interpolate_corners(plan, mesh.corner_uv.data(), 2, plan.uvs.data());
  }
  for (int e = 0; e < E; ++e) {
    if (!(plan.edge_flags[e] & (kSharpAtA | kSharpAtB))) continue;
    int prev = sub.vertex[2 * e];
    for (int m = 1; m <= L; ++m) {
      int cur = m == L ? sub.vertex[2 * e + 1] : SV + e * (L - 1) + (m - 1);
      plan.sharp_edges.push_back(prev);
      plan.sharp_edges.push_back(cur);
      prev = cur;
    }
  }
  timer.lap("tessellation");

  build_render_vertices(plan, SV, tess, sub.face_count);
  timer.lap("render_vertices");

  // 7. Lattice tables for the evaluators. The float tables measure each axis's parameter from
  // `shift`: its first knot plane when that lies further from 0 than the planes' extent, else 0
  // (ordinary lattices: unchanged tables). In float, s = A p + b near 1e4 has steps of 1e-3: a
  // B-spline axis with knots at -13451.4916 + [0, 2.4e-4] lost its spans to rounding (input
  // vertices 0.76 off in a lattice 2 wide, found by fuzz_plan); from its first plane it keeps
  // them.
  plan.components = lattice.components;
  for (int a = 0; a < 3; ++a) {
    plan.axis_offset[a] = (int)plan.pieces.size();
    plan.dims[a] = lattice.axes[a].n_ctrl();
    const double shift = float_shift(lattice.axes[a]);
    for (const AxisPiece& pc : lattice.axes[a].pieces()) {
      AxisPieceF f{};
      f.origin = (float)(pc.origin - shift);
      f.inv_scale = (float)(1.0 / pc.scale);
      f.degree = pc.degree;
      f.count = pc.count;
      for (int k = 0; k < kMaxTerms; ++k) {
        f.index[k] = k < pc.count ? pc.index[k] : 0;  // padded terms: weight 0, any valid index
        for (int q = 0; q < kMaxTerms; ++q) f.coef[k][q] = (float)pc.coef[k][q];
      }
      plan.pieces.push_back(f);
    }
    for (int c = 0; c < 3; ++c) plan.param_map[4 * a + c] = (float)lattice.object_to_param[a][c];
    plan.param_map[4 * a + 3] = (float)(lattice.object_to_param[a][3] - shift);
  }

  plan.input_vertices = V;
  plan.sub_vertices = SV;
  plan.patches = P;
  plan.edges = E;
  plan.samples = (int)S;
  plan.fit_degree = n;
  plan.columns = K;
  plan.edge_samples = ES;
  plan.level = L;
  plan.grid = G;
  plan.output_vertices = (int)N;
  plan.output_triangles = (int)T;
  return plan;
}

}  // namespace sffd
