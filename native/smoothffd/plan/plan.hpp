// The plan: everything that depends only on the mesh topology, its rest geometry and the
// lattice *structure*, built once (OpenSubdiv's "Far" stage). Evaluators then run every frame
// from new control values only. All arrays are flat and row-major so that the CUDA evaluator
// uploads them as they are.
//
// The plan build (build_plan) is a pipeline of stages, each a function of its own under plan/
// (and mesh/) that takes the earlier stages' results and returns its own or fills its part of
// the Plan:
//   validate          the input mesh and the lattice structure, before any work
//   input_surface     polygons triangulated (mesh/triangulate), corner normals and flat faces
//                     (corner_normals), edges and which of their ends split the normals (edges)
//   clip              knot-box clipping: the sub-mesh of patches (checked against memory_limit)
//   sub_vertices      adjustment normals bounded so that nothing folds, the crease-aware PN rest
//                     surface (rest_surface), clip vertices moved onto it (sec. 4.3.1), weights
//   sources           where each patch lies on the input
//   patch_normals     corner normals for shading and the adjustment (4.3.2), bounded again on
//                     the sub-mesh
//   adjacency         the sub-mesh's edges, their patches, corner slots and flags
//   samples           samples (sec. 5.1) and their lattice pieces; fitting matrix M_r (Eq. 11,
//                     fit_matrix)
//   centre_rows       each patch's centre as an affine function of the control values
//   output_topology   tessellation tables (Eq. 14, tessellation) and the welded output topology
//   render_vertices   output vertices duplicated where their normals split
//   lattice_tables    the lattice structure in float, as the evaluators read it
#pragma once

#include <cstdint>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "smoothffd/lattice/lattice_spec.hpp"
#include "smoothffd/mesh/triangulate.hpp"
#include "smoothffd/plan/edges.hpp"

namespace sffd {

struct InputMesh {
  std::vector<double> positions;     // #V x 3
  std::vector<int> corner_vertex;    // #C
  std::vector<int> face_offset;      // #F + 1
  std::vector<float> corner_normal;  // #C x 3, or empty: smooth area-weighted vertex normals
  std::vector<float> corner_uv;      // #C x 2, or empty
  std::vector<float> vertex_weight;  // #V, or empty: all 1
};

// The highest level build_plan takes (L^2 output triangles a patch), the one limit the Python
// package (smoothffd.MAX_LEVEL), its command line and the Blender add-on ask for.
constexpr int kMaxLevel = 64;

// How follow_plan treats the previous plan's pieces (hold_clip, plan/clip.hpp).
enum class HoldPieces {
  none,     // clip the new pose (with the previous pieces' triangles as a hint)
  checked,  // keep them where each still lies in its knot box, else clip
  always,   // keep them wherever they now lie
};

struct PlanOptions {
  int level = 10;                      // L: L^2 output triangles a patch, 1..kMaxLevel
  double sharp_angle_degrees = 1.0;    // corner normals further apart than this are split
  // Refuse (PlanTooLarge) a plan whose tables, one frame's evaluator buffers and one
  // per-corner result would take more than this many bytes (estimate_plan_bytes); 0: no
  // limit. Checked right after the knot-box clipping, which decides the patch count, before
  // any table of the patches' or the output's size is allocated.
  double memory_limit = 0;
  // Whether to build the centre rows (Plan::centre_row): they make positions-only frames about
  // four times cheaper and cost about two of them to build, so a plan that follows a moving
  // input every frame (follow_plan) does better without them.
  bool centre_rows = true;
};

// What build_plan throws when PlanOptions::memory_limit is exceeded (MemoryError in Python),
// with the estimate and the limit in its message.
class PlanTooLarge : public std::bad_alloc {
 public:
  explicit PlanTooLarge(std::string message) : message_(std::move(message)) {}
  const char* what() const noexcept override { return message_.c_str(); }

 private:
  std::string message_;
};

// Bytes that a plan of `patches` patches and `sub_vertices` sub-vertices at `level` with
// fitting degree `fit_degree` holds (Plan::bytes()), with one frame's CPU evaluator buffers
// and one per-corner result and its static arrays in numpy: within about 20% of the
// measured sum (tests/test_memory.py).
double estimate_plan_bytes(double patches, double sub_vertices, int level, int fit_degree, bool uvs);

// Float copy of one axis piece for the evaluators (see lattice/axis_basis.hpp).
struct AxisPieceF {
  float origin, inv_scale;
  int degree, count;
  int index[kMaxTerms];
  float coef[kMaxTerms][kMaxTerms];
};

// Flags of a sub-mesh edge.
enum EdgeFlags : uint8_t {
  kSharpAtA = 1,      // the two faces' normals differ at end a
  kSharpAtB = 2,
  kBoundary = 4,      // one face
  kNonManifold = 8,   // three or more faces: left as fitted
  kFlatFace = 16,     // a patch on it is a flat face's: left as fitted (the edge's own FFD)
};
// Edges whose control points the evaluators leave as fitted (no adjustment to the normals).
constexpr uint8_t kKeepFitted = kNonManifold | kFlatFace;

struct Plan {
  // --- sizes
  int input_vertices = 0;   // V: output vertices [0, V) are the deformed input vertices
  int sub_vertices = 0;     // V + clip vertices
  int patches = 0;          // P: sub-triangles, one cubic geometry + one cubic normal patch each
  int edges = 0;            // E: sub-mesh edges
  int samples = 0;          // S: unique sample points (vertices, then edges, then interiors)
  int fit_degree = 0;       // n: fitting grid degree (sum of lattice degrees, at least 3)
  int columns = 0;          // K = (n+1)(n+2)/2 + 9: samples a patch (fitting + constraint)
  int edge_samples = 0;     // samples inside each edge
  int level = 0;            // L
  int grid = 0;             // G = (L+1)(L+2)/2 tessellation points a patch
  int output_vertices = 0;  // N
  int output_triangles = 0; // T = P L^2
  int render_vertices = 0;  // R >= N (for the output vertices that lie on a patch)
  // Whether any output vertex has more than one normal (R > N: a sharp edge or split normals
  // on the input): then a normal a corner describes the result, else one a vertex.
  bool splits_normals() const { return render_vertices > output_vertices; }
  int flat_triangles = 0;   // input triangles of flat faces (plan/rest_surface.hpp)
  int bounded_vertices = 0; // input vertices whose normals were blended toward their
                            // triangles' own so that no patch folds (AdjustNormals::trust < 1)
  int bounded_sub_vertices = 0;  // the same on the clipped sub-mesh (its patches at rest)
  int turned_normals = 0;   // input triangle corners whose shading normal was turned toward
                            // the geometry, which cannot follow it (bound_render_normals)
  int turned_sub_normals = 0;  // patch corners turned again on the sub-mesh (its own bound)
  bool pieces_held = false;    // follow_plan held the previous plan's pieces (hold_clip)
  // What the CPU evaluator derives its own tables from, named so that an evaluator of a plan
  // that followed a pose can take over its predecessor's (eval/cpu_evaluator.hpp): numbers
  // from new_table_id.
  uint64_t samples_id = 0;   // this build's samples (their count, indexing and lattice pieces)
  uint64_t samples_base_id = 0;       // the followed plan's samples_id where these samples are
                                      // its samples (the same count and indexing), else 0
  std::vector<int> repieced_samples;  // then the samples whose lattice pieces are not those
                                      // they had there (ascending)
  uint64_t topology_id = 0;  // the output topology and render vertices (output_owner,
                             // render_owner and their counts): new where a build makes them,
                             // the previous plan's where a follow keeps them

  // --- lattice tables
  std::vector<AxisPieceF> pieces;  // the three axes' pieces, concatenated
  int axis_offset[3] = {0, 0, 0};
  int dims[3] = {1, 1, 1};          // nu, nv, nw (control values D are nu*nv*nw x components)
  int components = 3;               // LatticeSpec::components: 3, or 4 with point weights
  float param_map[12] = {};         // s = A p + b, row-major [A | b]

  // --- samples (sec. 5.1)
  std::vector<float> sample_position;  // S x 3: rest point (clip vertices on the rest surface)
  std::vector<uint32_t> sample_piece;  // S: piece per axis, 10 bits each (relative to axis)
  std::vector<float> sample_weight;    // S: per-vertex deformation factor, interpolated
  std::vector<float> sample_local;     // S x 3 or empty: each sample's local coordinate t in its
                                       // piece of each axis, computed in double, where t from the
                                       // float position would not resolve the spans (knot spans
                                       // tiny next to the mesh's coordinates, or to the others)

  // --- constrained fitting (Eqs. 11-13)
  std::vector<float> fit_matrix;     // 10 x K (M_r)
  std::vector<float> column_bary;    // K x 3: barycentric point of each column
  std::vector<int> patch_samples;    // P x K: sample of each column

  // --- centre rows (plan/centre_rows.hpp; empty with point weights, components 4): each
  // geometry patch's centre before the edge adjustment's share, c_p + sum_j a_pj D_j, over a
  // block of control points: lo_a + [0, ext_a) along each axis a, a_pj at (u ext_1 + v) ext_2 + w
  std::vector<uint64_t> centre_box;    // P: lo_a in bits 16a (16 bits), ext_a in bits 48 + 5a
  std::vector<long long> centre_start; // P + 1: the rows' offsets (each a multiple of 8 floats)
  std::vector<float> centre_row;       // a_pj, 0 in a row's padding
  std::vector<float> centre_constant;  // P x 3: c_p

  // --- patches
  std::vector<int> patch_vertex;            // P x 3 sub-vertices (= their vertex samples)
  std::vector<int> patch_edge;              // P x 3: edge k runs corner k -> corner k+1
  std::vector<uint8_t> patch_edge_reversed; // P x 3: 1 when corner k is the edge's end b
  std::vector<float> patch_render_normal;   // P x 3 x 3: rest normals at the corners (shading)
  std::vector<float> patch_adjust_normal;   // P x 3 x 3: rest normals for the adjustment (4.3.2)
  std::vector<int> patch_face;              // P: input face

  // --- edges (geometry adjustment, sec. 4.2)
  std::vector<int> edge_vertex;           // E x 2: ends a, b
  std::vector<int> edge_constraint;       // E x 2: samples at 1/3 and 2/3 from a
  std::vector<int> edge_patch;            // E x 2: patch on each side (-1: none)
  std::vector<uint8_t> edge_slot;         // E x 4: corner slots of a and b in side 0, side 1
  std::vector<uint8_t> edge_flags;        // E: EdgeFlags

  // --- tessellation (sec. 5.5, Eq. 14)
  std::vector<float> grid_basis;       // G x 10: cubic Bernstein values at the grid points
  std::vector<int> local_triangles;    // L^2 x 3 grid indices
  std::vector<int> patch_grid_vertex;  // P x G: output vertex of each grid point
  std::vector<int> output_owner;       // (N - sub_vertices) x 2: (patch, grid point)

  // --- static outputs (identical every frame)
  std::vector<float> rest_positions;   // N x 3
  std::vector<int> triangles;          // T x 3
  std::vector<int> face_index;         // T
  std::vector<float> uvs;              // T x 3 x 2, or empty
  std::vector<int> sharp_edges;        // K x 2 output vertex pairs where normals split

  // --- render vertices: an output vertex duplicated only where its normals split (the
  // compact per-frame output of the CUDA evaluator: normals R x 3, see cuda_evaluator.hpp).
  // The (patch, grid point) pairs at output vertex o fall into normal classes, one render
  // vertex each:
  //   interior grid point: one class;
  //   point inside sub-edge e: one class when edge_flags[e] has neither sharp bit nor
  //     kNonManifold, else one per incident patch ("side");
  //   sub-vertex v: the patches around v, joined (union-find) across each sub-edge at v that
  //     is manifold (two patches) and smooth at v's end; one class per connected set.
  // Numbering: by output vertex; the classes of one output vertex are consecutive. At a
  // sub-vertex classes are ordered by their lowest (patch, corner); along a split sub-edge e
  // the render vertex of step m (1..L-1 from end a) on side s (incident patches in increasing
  // order) is base_e + (m - 1) * sides_e + s. Interior points: render = output vertex +
  // (R - N). So R == N (and render == output vertex) when no normal splits.
  std::vector<int> render_owner;       // R x 2: (patch, grid point) whose normal patch gives the
                                       // class's normal; for an unsplit edge or interior point
                                       // the output_owner pair
  std::vector<int> render_position;    // R: output vertex (its position)
  std::vector<int> patch_grid_render;  // P x G: render vertex of each grid point
  std::vector<int> render_triangles;   // T x 3: triangles in render-vertex indices

  // --- where the output lies on the input (plan/sources.hpp): the core's triangulation of the
  // input faces, and each patch as a piece of one of its triangles. An output corner or vertex
  // of patch p at grid point g is the barycentric point sum_c bary_g[c] * patch_bary[p][c] of
  // input triangle patch_triangle[p] (the same arithmetic as the UVs).
  int input_corners = 0;                   // C
  std::vector<int> input_triangle_corner;  // Tin x 3: input corners (indices into the corner arrays)
  std::vector<int> input_triangle_face;    // Tin: input face of each
  std::vector<int> patch_triangle;         // P: input triangle each patch is a piece of
  std::vector<double> patch_bary;          // P x 3 x 3: its corners' barycentric points there

  // The edge tables of the input triangles and of the sub-mesh (patch_vertex), which depend on
  // connectivity alone: a plan that follows (follow_plan) takes them over where its triangles
  // and pieces are the same (shared with copies of this plan, read-only).
  std::shared_ptr<const TriangleEdges> input_edges, sub_edges;

  // Timings of the plan's build stages (ms), for the stats.
  std::vector<std::pair<std::string, double>> build_ms;

  size_t bytes() const;  // host memory held
};

// A number no earlier call returned (in this process): Plan::samples_id, topology_id.
uint64_t new_table_id();

// Builds the plan. Throws std::invalid_argument on invalid input. triangulation: the input's
// polygons as these triangles of corners (checked: each three distinct corners of its face),
// or null: ear clipping by the polygons' current shape (mesh/triangulate.hpp). A plan's own
// (input_triangle_corner, input_triangle_face) keeps its triangles for the same connectivity
// in another pose.
Plan build_plan(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& options,
                const Triangulation* triangulation = nullptr);

// The plan build_plan makes of `mesh` with the triangles of `like` (a plan of the same
// connectivity in another pose), whose pieces' triangles the knot-box clipping keeps wherever a
// triangle crosses the knot planes as it did there (ClipHint, plan/clip.hpp).
Plan build_plan_like(const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& options, const Plan& like);

// The plan of the same input in a new pose (positions, normals, UVs or weights changed; the
// connectivity, the options and the lattice structure the same): exactly
// build_plan_like(mesh, lattice, options, plan), which replaces `plan`. Everything that
// depends on positions is computed again (the corner normals, the knot-box clipping, the rest
// surface, the samples, their pieces and the centre rows); the output topology and the render
// vertices, the largest tables, are kept where the clipping gives the same sub-mesh with the
// same sharp and flat edges (no face crossed a knot plane differently, no normal split or
// joined). Returns whether they were: then the output's triangles, face indices, sharp edges
// and render vertices are the same as before. The old plan's arrays store the new one's (no
// fresh memory to fault in). Throws as build_plan and std::invalid_argument when the mesh's
// vertex or corner count, or its faces' corners, or the level differ from the plan's: `plan` is
// then left as it was, except when memory runs out while its arrays are being reused (after
// everything that depends on positions; nothing is cancelled there): then it is left empty (no
// patches). Evaluators of the old plan must not be used after it.
//
// hold: HoldPieces::checked keeps the old plan's pieces (its sub-mesh) in the new pose where
// each still lies in its knot box (hold_clip, plan/clip.hpp; pieces_held says whether they
// were), instead of clipping again: the output topology is then kept unless a normal splits
// or joins, where a new clipping changes it as soon as one face crosses a knot plane
// differently. The result is then not build_plan_like's: it differs by a small part of the
// fit's error (docs/algorithm.md, "Holding the pieces"). Where a piece has left its box the
// new pose is clipped as without hold. HoldPieces::always keeps them wherever they lie (a
// render's motion-blur subframes, which need one topology, and where accuracy matters less).
bool follow_plan(Plan& plan, const InputMesh& mesh, const LatticeSpec& lattice, const PlanOptions& options,
                 HoldPieces hold = HoldPieces::none);

}  // namespace sffd
