#include "smoothffd/plan/plan.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>

#include "smoothffd/core/cancel.hpp"
#include "smoothffd/plan/adjacency.hpp"
#include "smoothffd/plan/centre_rows.hpp"
#include "smoothffd/plan/clip.hpp"
#include "smoothffd/plan/edges.hpp"
#include "smoothffd/plan/fit_matrix.hpp"
#include "smoothffd/plan/input_surface.hpp"
#include "smoothffd/plan/lattice_tables.hpp"
#include "smoothffd/plan/output_topology.hpp"
#include "smoothffd/plan/patch_normals.hpp"
#include "smoothffd/plan/render_vertices.hpp"
#include "smoothffd/plan/samples.hpp"
#include "smoothffd/plan/sources.hpp"
#include "smoothffd/plan/sub_vertices.hpp"
#include "smoothffd/plan/tessellation.hpp"
#include "smoothffd/plan/validate.hpp"

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

// PlanOptions::memory_limit, checked once the clipping has decided the patch count.
void check_memory_limit(const PlanOptions& opt, const InputMesh& mesh, const LatticeSpec& lattice,
                        int triangles, const ClipResult& clip) {
  if (opt.memory_limit <= 0) return;
  const int P = clip.patches();
  const double need = estimate_plan_bytes(P, clip.sub_vertices(), opt.level, lattice.degree_sum(), !mesh.corner_uv.empty());
  if (need > opt.memory_limit) {
    char msg[400];
    std::snprintf(msg, sizeof(msg),
                  "level %d: %d triangles clipped by the lattice's knot planes into %d patches need "
                  "about %.2f GiB (plan, frame buffers and one result), more than the %.2f GiB "
                  "available; lower the level or use a lattice with fewer knot spans across the mesh",
                  opt.level, triangles, P, need / 1073741824.0, opt.memory_limit / 1073741824.0);
    throw PlanTooLarge(msg);
  }
}

}  // namespace

uint64_t new_table_id() {
  static std::atomic<uint64_t> last{0};
  return ++last;
}

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
  for (const auto& t : {input_edges, sub_edges})
    if (t)
      b += 4 * (t->tri_vertex.size() + t->edges.vertex.size() + t->edges.side.size() + t->edges.face_count.size() +
                t->edges.tri_edge.size());
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

namespace {

// The plan build's stages. triangulation: the input's (else triangulate_polygons by its
// shape). like: a plan whose pieces' triangles the clipping keeps where it can (ClipHint).
// previous: a plan of the same connectivity, options and lattice structure whose output
// topology and render vertices are taken over when the new clipping gives the very same
// sub-mesh with the same edge flags (*kept says whether they were), else whose arrays store the
// new ones; it is given up (*gave_up) only after everything that depends on positions.
// The output topology's and render vertices' index tables: what a plan that follows keeps, or
// builds anew in the previous plan's storage.
std::vector<int> Plan::* const kOutputTables[] = {
    &Plan::patch_grid_vertex, &Plan::output_owner,     &Plan::triangles,         &Plan::face_index,
    &Plan::sharp_edges,       &Plan::render_owner,     &Plan::render_position,   &Plan::patch_grid_render,
    &Plan::render_triangles};

Plan build(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& opt,
           const Triangulation* triangulation, const Plan* like, HoldPieces hold, Plan* previous, bool* kept,
           bool* gave_up) {
  check_input_mesh(mesh);
  if (opt.level < 1) throw std::invalid_argument("level: must be at least 1");
  // The tessellation tables grow as L^2 whatever the mesh: level 2^31 - 1 from the bindings
  // spent 11 s allocating before a MemoryError (found by native/fuzz/fuzz_bindings.py).
  if (opt.level > kMaxLevel)
    throw std::invalid_argument("level: at most " + std::to_string(kMaxLevel) + " (L^2 triangles a patch), got " +
                                std::to_string(opt.level));
  check_lattice_structure(lattice);
  Plan plan;
  StageTimer timer{plan};
  const std::vector<double>& X = mesh.positions;
  const double cos_tol = std::cos(opt.sharp_angle_degrees * M_PI / 180.0);

  // 1. The input surface: triangles, corner normals, sharp edge ends, flat faces.
  InputSurface in = build_input_surface(mesh, cos_tol, triangulation, like ? like->input_edges : nullptr);
  plan.input_edges = in.edge_table;
  timer.lap("triangulate");

  // 2. Knot-box clipping (the patch count, checked against the memory limit before any table of
  // that size); the rest surface, bounded so that no patch nor piece folds; the clip vertices
  // moved onto it.
  std::optional<ClipResult> held;
  if (hold != HoldPieces::none && like)
    held = hold_clip(X, in.tv, lattice, ClipHold{like->patch_vertex, like->patch_triangle, like->patch_bary},
                     hold == HoldPieces::checked);
  const ClipHint hint{like ? like->patch_vertex : in.tv, like ? like->patch_triangle : in.tv};
  ClipResult clip = held ? std::move(*held) : clip_to_knot_boxes(X, in.tv, lattice, like ? &hint : nullptr);
  plan.pieces_held = held.has_value();
  check_memory_limit(opt, mesh, lattice, (int)(in.tv.size() / 3), clip);
  timer.lap("clip");
  BoundedRest rest = bound_rest_surface(X, in, clip);
  timer.lap("rest_surface");
  SubVertices sub_vertices = place_sub_vertices(mesh, in, rest.surface, clip);
  plan.input_vertices = (int)(X.size() / 3);
  plan.sub_vertices = clip.sub_vertices();
  plan.patches = clip.patches();
  plan.flat_triangles = rest.flat_triangles;
  plan.bounded_vertices = rest.bounded_vertices;
  plan.turned_normals = rest.turned_normals;
  timer.lap("sub_vertices");

  // 3. Patches: where each lies on the input, its corner normals bounded on the sub-mesh, and
  // the sub-mesh's adjacency.
  build_patch_sources(plan, mesh, in.triangulation, clip);
  plan.sub_edges = edges_of(clip.patch_vertex, like ? like->sub_edges : nullptr);
  const EdgeTable& sub = plan.sub_edges->edges;
  timer.lap("sources_edges");
  std::vector<uint8_t> sharp = bound_patch_normals(plan, patch_corner_normals(X, in, clip, rest.shade), sub,
                                                   sub_vertices.position, clip, in.adjust.flat, cos_tol);
  timer.lap("patch_normals");
  build_adjacency(plan, clip.patch_vertex, sub, sharp, clip.patch_tri, in.adjust.flat);
  timer.lap("adjacency");

  // 4. Samples, their lattice pieces, the fitting matrix and the centre rows.
  {
    const FitTables fit = build_fit_tables(std::max(3, lattice.degree_sum()));
    // With held pieces the samples are the same points of the same sub-mesh, moved a little:
    // their indexing is the old plan's, and each is looked for first in the piece it had.
    const std::vector<double> sample_exact =
        build_samples(plan, fit, sub_vertices, &lattice, held ? like : nullptr, opt.centre_rows);
    timer.lap("samples");
    if (opt.centre_rows) build_centre_rows(plan, lattice, fit, sample_exact);
  }
  timer.lap("centre_rows");

  // 5. The welded output topology and its render vertices: the previous plan's where the
  // sub-mesh and its edges' flags are the same (they depend on nothing else), with the rest
  // positions and UVs of this one. A plan that follows (previous given) gives its arrays up
  // from here on, as the new plan's tables or as their storage (the same sizes within a few
  // patches: no fresh pages to fault in, at high levels most of these stages' cost), so nothing
  // below is cancelled: a cancel would leave neither plan whole.
  const TessellationTables tess = build_tessellation(opt.level);
  const bool same = previous && previous->level == opt.level && previous->sub_vertices == plan.sub_vertices &&
                    previous->patch_vertex == plan.patch_vertex && previous->patch_triangle == plan.patch_triangle &&
                    previous->edge_flags == plan.edge_flags;
  if (kept) *kept = same;
  std::optional<CancelScope> uncancelled;
  if (previous) {
    uncancelled.emplace([] { return false; });
    if (gave_up) *gave_up = true;
    for (auto table : kOutputTables) (plan.*table).swap(previous->*table);
    plan.rest_positions.swap(previous->rest_positions);
    plan.uvs.swap(previous->uvs);
  }
  if (same) {
    const Plan& q = *previous;
    plan.grid_basis = q.grid_basis;
    plan.local_triangles = q.local_triangles;
    plan.grid = q.grid;
    plan.output_vertices = q.output_vertices;
    plan.output_triangles = q.output_triangles;
    plan.render_vertices = q.render_vertices;
    plan.level = opt.level;
    plan.topology_id = q.topology_id;
    output_rest_positions(plan, tess, clip.flat, plan.rest_positions);
    output_uvs(plan, mesh.corner_uv, plan.uvs);
    build_lattice_tables(plan, lattice);
    timer.lap("kept_topology");
    return plan;
  }
  for (auto table : kOutputTables) (plan.*table).clear();
  build_output_topology(plan, tess, clip.flat, mesh.corner_uv);
  timer.lap("tessellation");
  build_render_vertices(plan, plan.sub_vertices, tess, sub.face_count);
  plan.topology_id = new_table_id();
  timer.lap("render_vertices");

  // 6. The lattice tables for the evaluators.
  build_lattice_tables(plan, lattice);
  return plan;
}

}  // namespace

Plan build_plan(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& opt,
                const Triangulation* triangulation) {
  return build(mesh, lattice, opt, triangulation, nullptr, HoldPieces::none, nullptr, nullptr, nullptr);
}

Plan build_plan_like(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& opt, const Plan& like) {
  const Triangulation tr{like.input_triangle_corner, like.input_triangle_face};
  return build(mesh, lattice, opt, &tr, &like, HoldPieces::none, nullptr, nullptr, nullptr);
}

bool follow_plan(Plan& plan, const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& opt, HoldPieces hold) {
  if (opt.level != plan.level)
    throw std::invalid_argument("follow_plan: the options' level differs from the plan's");
  if ((int)(mesh.positions.size() / 3) != plan.input_vertices || (int)mesh.corner_vertex.size() != plan.input_corners)
    throw std::invalid_argument("follow_plan: the mesh's vertex or corner count differs from the plan's");
  const Triangulation tr{plan.input_triangle_corner, plan.input_triangle_face};
  bool kept = false, gave_up = false;
  try {
    Plan next = build(mesh, lattice, opt, &tr, &plan, hold, &plan, &kept, &gave_up);
    plan = std::move(next);
  } catch (...) {
    if (gave_up) plan = Plan();  // out of memory while building the new tables in the old ones
    throw;
  }
  return kept;
}

}  // namespace sffd
