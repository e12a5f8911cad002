// The CUDA evaluator's device-side tables, built once per plan from the Plan in plain C++ (no
// CUDA header: the core builds this file too, and native/tests checks the tables without a
// GPU), then uploaded as they are. OpenSubdiv's CudaStencilTable plays this part for its
// kernels. The records hold plain vector structs (F4, I4, F2) with the layout and alignment of
// CUDA's float4, int4 and float2, which the kernels read them as (cuda/device_types.cuh).
//
// What each table serves:
//   grid_info, owns, render: the tessellation's walk, which patch writes each edge's points and
//       render vertices (both paths: the reference path's scatter, the inline kernel's records);
//   the rest: the fused path's kernel, k_inline (cuda/inline_kernel.cu), in one of three modes
//       (InlineMode) by where its tables fit: boxes and weights read them from shared memory,
//       global from device memory.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "smoothffd/core/hd.hpp"
#include "smoothffd/plan/plan.hpp"
#include "smoothffd/plan/tessellation.hpp"

namespace sffd {
namespace cuda_impl {

struct alignas(16) F4 {
  float x, y, z, w;
};
struct alignas(16) I4 {
  int x, y, z, w;
};
struct alignas(8) F2 {
  float x, y;
};

// Per grid point of the tessellation: kind (0 corner, 1 edge, 2 interior), which, step; and
// `order`: entry g holds the grid point at position g of the order the tessellation walks
// (the 3L boundary points first, then the interior points by `which`).
struct GridInfo {
  int kind, which, step, order;
};

// Which render vertices (plan.hpp) patch p writes the normal of, derived from the plan's
// render_owner / patch_grid_render (and checked against them for every grid point):
// corner[k]: render vertex of corner k, or -1 when another patch owns it; edge_base[k]: render
// vertex of step m = 1 (counted from the sub-edge's end a) on p's side of edge k, or -1 when
// another patch owns the edge's points; step m has base + (m - 1) * edge_stride[k]. Interior
// points: render vertex = output vertex + render_shift (R - N).
struct PatchRender {
  int corner[3], edge_base[3], edge_stride[3];
};

// The inline kernel's three ways of reading the lattice and the plan's tables:
//   kInlineBoxes:   tables in shared memory, samples from the lattice boxes in power form;
//   kInlineWeights: tables and control values in shared memory, samples from the per-axis
//                   weights (the boxes do not fit);
//   kInlineGlobal:  the tables stay in device memory (read through the caches), each sample's
//                   position and pieces come from the plan, the control values from the
//                   frame's upload: any plan (up to kMaxTerms terms an axis, any level, any
//                   lattice).
enum InlineMode { kInlineNone = -1, kInlineBoxes = 0, kInlineWeights = 1, kInlineGlobal = 2 };

// One axis piece as the shared-memory modes read it (6 x 16 bytes): the piece's own parameter
// t = dot(map.xyz, p) + map.w (the lattice's object -> parameter map, the piece's origin and
// 1 / scale folded in; all zeros for degree 0, so t = 0), the power coefficients of its C <= 4
// weights (zeros beyond the degree: the Horner scheme needs no branch) and each term's
// control-point offset along the axis (index times the axis stride, in points).
struct alignas(16) InlinePiece {
  F4 map;
  F4 coef[4];
  I4 off;
};
// The same for the global mode, up to kMaxTerms terms.
struct alignas(16) InlinePieceWide {
  F4 map;
  float coef[kMaxTerms][kMaxTerms];
  int off[kMaxTerms];
};

// Columns k_inline evaluates a patch (the grid's and the extra constraint columns). The
// fitting degree is at most 3 kMaxAxisDegree = 15: at most 136 grid columns, 145 in all.
// With the lattice tables in shared memory (C <= 4 terms an axis: degree <= 9) at most 55 + 9:
// InlinePatch::box has a byte for each.
constexpr int kMaxInlineGrid = (3 * kMaxAxisDegree + 1) * (3 * kMaxAxisDegree + 2) / 2;
constexpr int kMaxInlineColumns = kMaxInlineGrid + 9;
constexpr int kMaxBoxColumns = 64;

// The constraint columns (corners, edge points at 1/3 and 2/3) are usually fitting-grid points
// too (always the corners; the edge points when the fitting degree is a multiple of 3), with
// the same sample: such a column is evaluated once. con_of[k]: constraint column (0-8) that
// grid column k also is, or -1. order[0 .. n_cols): the columns k_inline evaluates (the grid's
// and the constraint columns that are no grid point), corners first, then edge points, then
// interior points, so that a warp's lanes mostly place samples of one kind at a time
// (inline_sample_point branches on it: in the grid's own order, every step of the column
// loop ran all three branches).
struct ColumnMap {
  int8_t con_of[kMaxInlineGrid];
  uint8_t order[kMaxInlineColumns];
  uint8_t n_cols;
  uint8_t pad[(4 - (kMaxInlineGrid + kMaxInlineColumns + 1) % 4) % 4];
};
static_assert(sizeof(ColumnMap) % 4 == 0, "ColumnMap is staged as words");

// A fitting column as k_inline reads it (32 bytes): its barycentric point and centre-row
// coefficient (0 for constraint columns), and where its sample lies: at corner `corner`, on
// patch edge `edge` (corner edge -> edge + 1) at parameter t_fwd from the edge's first corner
// (t_rev = 1 - t_fwd, exactly, from the other), or inside (both -1).
struct alignas(16) InlineColumn {
  F4 bary;
  float t_fwd, t_rev;
  int edge, corner;
};

// Position and vertex weight of the sample of column c of a patch whose corners' samples are
// P0-P2 (InlinePatch::corner) and whose edge k runs against its edge's own direction when
// bit 3 + k of flags is set: the plan's samples (plan.cpp, step 5) recomputed in float, with
// no gather. A sample on an edge is the same lerp from the edge's first vertex on both of its
// patches (the same operands, the same instructions: bitwise the same point, so both still
// compute bitwise the same edge control points); one inside is P0 + b1 (P1 - P0) + b2 (P2 -
// P0). V4: F4 on the host, float4 in the kernel. build_device_tables checks every sample
// against the plan's once per plan (where it is not, the global mode reads the plan's).
template <class V4>
SFFD_HD V4 inline_sample_point(const InlineColumn& c, uint32_t flags, V4 P0, V4 P1, V4 P2) {
  auto pick = [&](int i) { return i == 0 ? P0 : i == 1 ? P1 : P2; };
  auto lerp = [](float t, V4 a, V4 b) {
    return V4{fmaf(t, b.x - a.x, a.x), fmaf(t, b.y - a.y, a.y), fmaf(t, b.z - a.z, a.z), fmaf(t, b.w - a.w, a.w)};
  };
  if (c.corner >= 0) return pick(c.corner);
  if (c.edge >= 0) {
    const bool rev = (flags >> (3 + c.edge)) & 1u;
    const int k1 = c.edge == 2 ? 0 : c.edge + 1;
    return rev ? lerp(c.t_rev, pick(k1), pick(c.edge)) : lerp(c.t_fwd, pick(c.edge), pick(k1));
  }
  const V4 a = lerp(c.bary.y, P0, P1);  // P0 + b1 (P1 - P0)
  return V4{fmaf(c.bary.z, P2.x - P0.x, a.x), fmaf(c.bary.z, P2.y - P0.y, a.y), fmaf(c.bary.z, P2.z - P0.z, a.z),
            fmaf(c.bary.z, P2.w - P0.w, a.w)};
}

// What k_inline's tessellation needs to place a patch's boundary points (corners and edge
// points): with edge k's record {obase, ostep, rbase, rstep}, the point at step s (1 .. L - 1
// from corner k, the patch's walk, GridInfo::step) writes its position to output vertex
// obase + s ostep and its normal to render vertex rbase + s rstep; -1 / 0 when the patch
// writes neither (another patch owns the edge's points, or its normals are not split).
// corner[k]: render vertex of corner k or -1 (corner positions are written by the fit).
// items: the number of boundary points the patch's group of 32 writes (its entries of the
// group's boundary list; the shared-memory modes).
struct alignas(16) PatchBoundary {
  I4 edge[3];
  int corner[3];
  int items;
};

// Everything k_inline reads about one patch besides its samples, in one 336-byte record: a
// block copies its next group's records into shared memory with asynchronous copies
// (cp.async) during the current group's tessellation, so that the fit, the edge adjustment
// and the tessellation tables wait on no global load.
//   rest: the rest render normals at the corners (Plan::patch_render_normal);
//   adjust: the rest adjustment normals at the corners (patch_adjust_normal);
//   nb: per edge k, the adjustment normals of the patch across it at the edge's ends a and b
//       (edge order), zero on a boundary;
//   vertex: patch_vertex;
//   flags: bits 0-2 owns edge k's points, 3-5 edge k reversed, 8-10 writes corner k's
//       position (its first patch in plan order), at 12 + 4k edge k's sharp-at-a (1),
//       sharp-at-b (2), non-manifold (4) and has-a-second-patch (8) bits, at 24 + k: this
//       patch is side 1 of edge k (edge_control_points' p1);
//   bound: where its boundary points go (PatchBoundary);
//   corner: the corners' samples (position, vertex weight), from which k_inline places every
//       sample of the patch (inline_sample_point; shared-memory modes);
//   box: the lattice box (index into DeviceTables::box_list) of the sample of each evaluated
//       column (in the order of k_inline's column loop; shared-memory modes).
struct alignas(16) InlinePatch {
  float rest[9];
  float adjust[9];
  float nb[3][6];
  int vertex[3];
  uint32_t flags;
  PatchBoundary bound;
  F4 corner[3];
  uint8_t box[kMaxBoxColumns];
};
static_assert(sizeof(InlinePatch) == 336 && sizeof(InlinePatch) % 16 == 0, "copied as 16-byte pieces");

// Largest dynamic shared-memory table an inline launch may ask for (the kernel opts in to it;
// with its ~34 KB of static shared memory, 4 blocks fit an SM up to about 22 KB of it, 3
// beyond: W1 asks for 17 KB at L = 10, more than 22 KB beyond L = 23). Larger lattices (beyond
// about 1500 control points of degree 2) or levels (beyond 36 with W1's 27 boxes) run the
// global mode. Devices that give a block less shared memory (sm_75: 64 KB with the static
// part) lower it to what their limits leave (CudaEvaluator).
constexpr size_t kInlineSharedBytes = 28 * 1024;
constexpr int kBoxPoints = 512;  // control values that fit k_inline's ctrl table (32 patches)

// Terms an axis the kernels are built for: the plan's largest term count, at least 2 (2 to
// kMaxTerms: each its own instantiation, so that no padded term is summed).
inline int kernel_terms(int max_terms) { return max_terms <= 2 ? 2 : max_terms < kMaxTerms ? max_terms : kMaxTerms; }
// The plan's largest count / degree + 1 over its pieces.
int plan_max_terms(const Plan& p);

// Every table, on the host, as build_device_tables makes them from a plan.
struct DeviceTables {
  // Both paths.
  std::vector<GridInfo> grid_info;  // G, in the plan's grid order; .order: the walk
  std::vector<uint8_t> owns;        // P: bit k, the patch writes the points of its edge k
  std::vector<PatchRender> render;  // P
  long long render_shift = 0;       // R - N
  int max_terms = 0, terms = 0;     // the plan's largest term count; kernel_terms of it
  // The inline kernel. no_inline: why it cannot run the plan at all ("" when it can);
  // shared_why: why its shared-memory modes cannot ("" when they can, where they fit).
  std::string no_inline, shared_why;
  int points = 0, n_pieces = 0, columns = 0;
  int walk_boundary = 0, st_interior = 0, st_count = 0;  // the walk (WalkST, inline_kernel.cu)
  std::vector<I4> box_list;  // boxes holding samples: three piece indices, w: them packed 10 bits each
  std::vector<InlineColumn> column;                  // K
  ColumnMap column_map{};
  std::vector<int> evaluated;                        // the columns k_inline evaluates, its order
  float mrow[11][9] = {};                            // M_r's last 9 columns; row 10 the edge rows' sum
  std::vector<InlinePiece> pieces;                   // (shared-memory modes)
  std::vector<InlinePieceWide> pieces_wide;          // (global mode)
  std::vector<InlinePatch> patch_rec;                // P
  std::vector<int> loose;                            // sub-vertices in no patch
  std::vector<F2> grid_st;                           // (s, t) in walk order, interior from st_interior
  std::vector<GridInfo> grid_walk;                   // the walk's boundary points

  // Dynamic shared memory of the shared-memory modes (boxes: with the box polynomials, else
  // the control values), bytes: the layout k_inline stages (inline_kernel.cu).
  size_t shared_bytes(bool boxes) const;
  // Entries of a group's boundary list (a multiple of 8).
  int list_stride() const { return (32 * walk_boundary + 7) / 8 * 8; }
};

// Builds every table of the plan (tt: build_tessellation(plan.level)). Throws
// std::logic_error where the plan's tables are not in the layout plan.hpp documents.
DeviceTables build_device_tables(const Plan& p, const TessellationTables& tt);

// The inline mode for a dynamic shared-memory budget (bytes a block may add to the kernel's
// static tables): boxes where their polynomials fit, else the weights, else global;
// kInlineNone when the inline kernel cannot run the plan. Sets t.shared_why when the budget
// is what rules the shared modes out.
InlineMode choose_inline_mode(DeviceTables& t, size_t budget);

// Each group of 32 patches' boundary list for the shared-memory modes: the (patch q, walk
// position w) pairs that write a position or a normal, as q | w << 5, in walk order (so
// neighbouring threads store neighbouring points of an edge), list_stride() entries a group;
// sets each record's PatchBoundary::items to its group's count.
std::vector<uint16_t> build_boundary_lists(DeviceTables& t);

}  // namespace cuda_impl
}  // namespace sffd
