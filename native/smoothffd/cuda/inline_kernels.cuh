// The fused path (the CUDA evaluator's default, every plan): one kernel a frame samples, fits,
// adjusts the edges and tessellates, with nothing going through device memory between the
// stages. Included by cuda_evaluator.cu inside its anonymous namespace (it uses GridInfo,
// PatchCtrl, eval_point and tessellate_interior from there).
//
// Why: a staged pipeline (sampling kernel -> edge kernel -> fit, as the reference path runs)
// writes every sample's value and Jacobian (48 bytes) and gathers them back by index for each
// patch; the fit then waits on those dependent gathers, and the edge kernel is a launch of its
// own (2.8x slower than this kernel on W1 at L = 10, the last time both ran). Here each
// patch evaluates its 37 columns itself (28 evaluations once the constraint columns that are
// grid points are shared; a sample on an edge is evaluated by both patches, about 1.6
// evaluations a sample), from tables in shared memory, and adjusts its own three edges from
// its own constraint columns. It places each sample itself, from the three corner samples in
// its patch record (inline_sample_point), so no per-sample record is gathered. The two
// patches of an edge place and evaluate the same samples with the same instructions, so they
// compute bitwise the same edge control points and the surface stays watertight, as with one
// thread an edge. The tessellation evaluates the patches in power form (eval_point).
//
// A sample is evaluated either from the lattice boxes in power form (convert_boxes, once a
// block; eval_box: three nested Horner schemes) or, where those do not fit in shared memory,
// from the axis pieces' weights and the tensor contraction (sample_inline); where even those
// tables do not fit, they stay in device memory and each sample comes from the plan
// (InlineMode). The profile that led here, and the measurements, are in git
// (docs/benchmarks.md says where).
#pragma once

// Largest lattice whose control values ride in the launch's parameters (3 KB) instead of a
// copy to the device before the kernel: a frame is then one launch and nothing else.
constexpr int kParamPoints = 256;
struct InlineControls {
  float v[3 * kParamPoints];
};

// One axis piece as the inline kernel reads it (shared memory, 6 x 16 bytes): the piece's own
// parameter t = dot(map.xyz, p) + map.w (the lattice's object -> parameter map, the piece's
// origin and 1 / scale folded in; all zeros for degree 0, so t = 0), the power coefficients of
// its C <= 4 weights (zeros beyond the degree: the Horner scheme needs no branch) and each
// term's control-point offset along the axis (index times the axis stride, in float4s).
struct InlinePiece {
  float4 map;
  float4 coef[4];
  int4 off;
};

// The same for the global mode (tables in device memory), up to kMaxTerms terms.
struct __align__(16) InlinePieceWide {
  float4 map;
  float coef[kMaxTerms][kMaxTerms];
  int off[kMaxTerms];
};

// A piece's coefficients of term k and its terms' offsets, C terms (C <= 4 for InlinePiece).
template <int C>
__device__ __forceinline__ void piece_coefficients(const InlinePiece& pc, int k, float c[C]) {
  const float4 c4 = pc.coef[k];
  const float v[4] = {c4.x, c4.y, c4.z, c4.w};
#pragma unroll
  for (int q = 0; q < C; ++q) c[q] = v[q];
}
template <int C>
__device__ __forceinline__ void piece_coefficients(const InlinePieceWide& pc, int k, float c[C]) {
#pragma unroll
  for (int q = 0; q < C; ++q) c[q] = pc.coef[k][q];
}
template <int C>
__device__ __forceinline__ void piece_offsets(const InlinePiece& pc, int o[C]) {
  const int4 q = pc.off;
  const int v[4] = {q.x, q.y, q.z, q.w};
#pragma unroll
  for (int k = 0; k < C; ++k) o[k] = v[k];
}
template <int C>
__device__ __forceinline__ void piece_offsets(const InlinePieceWide& pc, int o[C]) {
#pragma unroll
  for (int k = 0; k < C; ++k) o[k] = pc.off[k];
}

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

// A fitting column as k_inline reads it (shared memory, 32 bytes): its barycentric point and
// centre-row coefficient (0 for constraint columns), and where its sample lies: at corner
// `corner`, on patch edge `edge` (corner edge -> edge + 1) at parameter t_fwd from the
// edge's first corner (t_rev = 1 - t_fwd, exactly, from the other), or inside (both -1).
struct __align__(16) InlineColumn {
  float4 bary;
  float t_fwd, t_rev;
  int edge, corner;
};

// Position and vertex weight of the sample of column c of a patch whose corners' samples are
// P0-P2 (InlinePatch::corner) and whose edge k runs against its edge's own direction when
// bit 3 + k of flags is set: the plan's samples (plan.cpp, step 5) recomputed in float, with
// no gather. A sample on an edge is the same lerp from the edge's first vertex on both of its
// patches (the same operands, the same instructions: bitwise the same point, so both still
// compute bitwise the same edge control points); one inside is P0 + b1 (P1 - P0) + b2 (P2 -
// P0). CudaEvaluator checks every sample against the plan's once per plan.
__host__ __device__ __forceinline__ float4 inline_sample_point(const InlineColumn& c, uint32_t flags, float4 P0,
                                                                float4 P1, float4 P2) {
  auto pick = [&](int i) { return i == 0 ? P0 : i == 1 ? P1 : P2; };
  auto lerp = [](float t, float4 a, float4 b) {
    return make_float4(fmaf(t, b.x - a.x, a.x), fmaf(t, b.y - a.y, a.y), fmaf(t, b.z - a.z, a.z),
                       fmaf(t, b.w - a.w, a.w));
  };
  if (c.corner >= 0) return pick(c.corner);
  if (c.edge >= 0) {
    const bool rev = (flags >> (3 + c.edge)) & 1u;
    const int k1 = c.edge == 2 ? 0 : c.edge + 1;
    return rev ? lerp(c.t_rev, pick(k1), pick(c.edge)) : lerp(c.t_fwd, pick(c.edge), pick(k1));
  }
  const float4 a = lerp(c.bary.y, P0, P1);  // P0 + b1 (P1 - P0)
  return make_float4(fmaf(c.bary.z, P2.x - P0.x, a.x), fmaf(c.bary.z, P2.y - P0.y, a.y),
                     fmaf(c.bary.z, P2.z - P0.z, a.z), fmaf(c.bary.z, P2.w - P0.w, a.w));
}

// What k_inline's tessellation needs to place a patch's boundary points (corners and edge
// points), built once per plan (CudaEvaluator::Impl::build_inline_tables): with edge k's
// record {obase, ostep, rbase, rstep}, the point at step s (1 .. L - 1 from corner k, the
// patch's walk, gi[w].step) writes its position to output vertex obase + s ostep and its normal
// to render vertex rbase + s rstep; -1 / 0 when the patch writes neither (another patch owns
// the edge's points, or its normals are not split). corner[k]: render vertex of corner k or
// -1 (corner positions are written by the fit). items: the number of boundary points the
// patch's group of 32 writes (its entries of InlineArgs::boundary_list).
// Before, every thread derived these per point from the patch's edge, flags and render tables
// (a chain of dependent shared loads and 64-bit products: a seventh of the stall samples).
struct __align__(16) PatchBoundary {
  int4 edge[3];
  int corner[3];
  int items;
};

// Everything k_inline reads about one patch besides its samples, in one 224-byte record
// (CudaEvaluator::Impl::build_inline_tables): a block copies its next group's records into
// shared memory with asynchronous copies (cp.async) during the current group's tessellation,
// so that the fit, the edge adjustment and the tessellation tables wait on no global load.
// Before, those were chains of dependent gathers (patch -> edge -> neighbour -> its normals)
// at the end of each group's sampling: a tenth of the kernel's stall samples.
//   rest: the rest render normals at the corners (PlanView::patch_render_normal);
//   adjust: the rest adjustment normals at the corners (patch_adjust_normal);
//   nb: per edge k, the adjustment normals of the patch across it at the edge's ends a and b
//       (edge order), zero on a boundary;
//   vertex: patch_vertex;
//   flags: bits 0-2 owns edge k's points, 3-5 edge k reversed, 8-10 writes corner k's
//       position (corner_owns), at 12 + 4k edge k's sharp-at-a (1), sharp-at-b (2),
//       non-manifold (4) and has-a-second-patch (8) bits, at 24 + k: this patch is side 1 of
//       edge k (edge_control_points' p1);
//   bound: where its boundary points go (PatchBoundary).
//   corner: the corners' samples (position, vertex weight), from which k_inline places every
//       sample of the patch (inline_sample_point);
//   box: the lattice box (index into InlineArgs::box_list) of the sample of each evaluated
//       column (in the order of k_inline's column loop).
struct __align__(16) InlinePatch {
  float rest[9];
  float adjust[9];
  float nb[3][6];
  int vertex[3];
  uint32_t flags;
  PatchBoundary bound;
  float4 corner[3];
  uint8_t box[kMaxBoxColumns];
};
static_assert(sizeof(InlinePatch) == 336 && sizeof(InlinePatch) % 16 == 0, "copied as 16-byte pieces");
constexpr int kPatchChunks = sizeof(InlinePatch) / 16;

// Everything the inline kernel needs besides the plan view, built once per plan
// (CudaEvaluator::Impl::build_inline_tables). mrow: M_r's last 9 columns (rows 0-9: the
// constraint columns' part of each control point) and, row 10, the sum of its six edge rows
// (the fitted edge control points' sum, which finish_patch_from compares with the adjusted
// ones). It is a launch parameter so the products read it from the constant bank.
struct InlineArgs {
  const InlinePiece* pieces;           // the shared-memory modes'
  const InlinePieceWide* pieces_wide;  // kInlineGlobal's
  const InlineColumn* column;  // K
  const ColumnMap* column_map;
  const float* D;  // control values on the device, or null: from InlineControls (not kInlineGlobal)
  int points, n_pieces, groups;
  // The lattice boxes (one piece an axis) that hold samples, box_count of them: box_list, each
  // box's three pieces (indices into `pieces`) and, w, the three packed 10 bits each. In power
  // form they are computed in shared memory by every block from the control values when they
  // fit (boxes = box_count > 0), else the per-sample weights are used (boxes = 0).
  const int4* box_list;
  int box_count, boxes;
  // The tessellation grid in the order tessellate_listed walks it (entry g is grid point
  // gi[g].order of the plan's tables): the boundary points' GridInfo (walk_boundary of them),
  // and every point's parameters (s, t) (grid_st), the interior from index st_interior (the
  // boundary count rounded up to even: WalkST), st_count entries in all.
  const GridInfo* grid_walk;
  const float2* grid_st;
  int walk_boundary, st_interior, st_count;
  const InlinePatch* patch_rec;  // P
  // Per group of 32 patches, a slot of list_stride entries (a multiple of 8): the boundary
  // points (corners and edge points) its patches write, in walk order, each as
  // q | w << 5 (patch q of the group, position w of the grid walk); the group's count is in
  // its records' PatchBoundary::items. About 40% of a patch's boundary points write nothing
  // (another patch owns them): without the list, their threads idled beside the others.
  const uint16_t* boundary_list;
  int list_stride;
  float mrow[11][9];
  // Dynamic shared memory: control values, pieces, columns, the grid's (s, t) table and the
  // boundary points' GridInfo, the boxes and their list, a group's boundary list, the
  // ColumnMap, in 16-byte units. With boxes the control values are staged in the block's ctrl
  // table (kBoxPoints at most) only while the boxes are computed.
  size_t shared_units(int K, int C) const {
    return (boxes > 0 ? 0 : (size_t)points) + 6 * (size_t)n_pieces + 2 * (size_t)K + ((size_t)st_count + 1) / 2 +
           (size_t)walk_boundary + (size_t)boxes * C * C * C + (size_t)box_count;
  }
  size_t shared_bytes(int K, int C) const {
    return 16 * shared_units(K, C) + 2 * (size_t)list_stride + sizeof(ColumnMap);
  }
};

// Largest dynamic shared-memory table an inline launch may ask for (the kernels opt in to it;
// with the ~34 KB of static shared memory, 4 blocks fit an SM up to about 22 KB of it, 3
// beyond: W1 asks for 17 KB at L = 10, more than 22 KB beyond L = 23). Larger lattices (beyond
// about 1500 control points of degree 2) or levels (beyond 36 with W1's 27 boxes) run the
// global mode. On devices that give a block less shared memory (sm_75: 64 KB with the
// static part), CudaEvaluator lowers it to what the device's limits leave (plan_limits).
constexpr size_t kInlineSharedBytes = 28 * 1024;
constexpr int kBoxPoints = 512;  // control values that fit k_inline's ctrl table (32 patches)


// edge_control_points (stages.hpp) of patch edge k (ends a, b at corners ka, kb) from the
// patch's record: the same operations in the same order, so both patches of an edge still
// compute bitwise the same control points.
__device__ __forceinline__ void edge_control_points_rec(const InlinePatch& r, int k, int ka, int kb, V3 Pa, V3 Pb,
                                                        V3 Q1, V3 Q2, const float* Ja, const float* Jb, V3 c[2]) {
  const float s6 = 1.0f / 6.0f;
  c[0] = s6 * (-5.0f * Pa + 18.0f * Q1 - 9.0f * Q2 + 2.0f * Pb);
  c[1] = s6 * (2.0f * Pa - 9.0f * Q1 + 18.0f * Q2 - 5.0f * Pb);
  const uint32_t ef = (r.flags >> (12 + 4 * k)) & 15u;
  if (ef & 4u) return;  // non-manifold: left as fitted
  const bool has1 = (ef & 8u) != 0, self1 = ((r.flags >> (24 + k)) & 1u) != 0;
  for (int end = 0; end < 2; ++end) {
    const float* J = end ? Jb : Ja;
    const V3 own = load3(r.adjust + 3 * (end ? kb : ka)), across = load3(r.nb[k] + 3 * end);
    const V3 m0 = self1 ? across : own, m1 = self1 ? own : across;  // sides 0 and 1
    const V3 n0 = normalized_or(cofactor_apply(J, m0), m0);
    const V3 n1 = has1 ? normalized_or(cofactor_apply(J, m1), m1) : n0;
    c[end] = adjust_control_point(c[end], end ? Pb : Pa, n0, n1, has1, (ef >> end) & 1u);
  }
}

// F = p + w value and J = I + w (dF/dt) A', A' = the pieces' maps (rows m[a] = dt_a/dp):
// compose_deformation (lattice/tensor_eval.hpp) with the derivatives in the pieces' own t.
__device__ __forceinline__ void compose_inline(float4 pw, const float m[3][3], const float val[3], const float gu[3],
                                               const float gv[3], const float gw[3], float F[3], float J[9]) {
  const float p[3] = {pw.x, pw.y, pw.z};
#pragma unroll
  for (int r = 0; r < 3; ++r) {
    F[r] = p[r] + pw.w * val[r];
#pragma unroll
    for (int c = 0; c < 3; ++c) {
      const float g = gu[r] * m[0][c] + gv[r] * m[1][c] + gw[r] * m[2][c];
      J[3 * r + c] = (r == c ? 1.0f : 0.0f) + pw.w * g;
    }
  }
}

// Where sample_inline reads the control values: a point offset o (InlinePiece::off) gives
// its three coordinates. SharedControls: the block's float4 copy in shared memory (the
// weights mode); GlobalControls: the frame's upload, 3 floats a point (the global mode).
struct SharedControls {
  const float4* v;
  __device__ __forceinline__ V3 operator()(int o) const {
    const float4 q = v[o];
    return v3(q.x, q.y, q.z);
  }
};
struct GlobalControls {
  const float* __restrict__ v;
  __device__ __forceinline__ V3 operator()(int o) const {
    const float* q = v + 3 * (long long)o;
    return v3(__ldg(q), __ldg(q + 1), __ldg(q + 2));
  }
};

// F and J at one sample from the inline tables: sample_point (stages.hpp) with the axis
// pieces in power form, t from the folded map, the tensor contraction of tensor_eval_fixed in
// the same order, and J = I + w (dF/dt) A' with A' = the pieces' maps (dt/dp). piece: the
// sample's piece of each axis (indices into pcs).
template <int C, class Piece, class Controls>
__device__ __forceinline__ void sample_inline(const Controls& D, const Piece* __restrict__ pcs, float4 pw,
                                              const int piece[3], float F[3], float J[9]) {
  float w[3][C], dw[3][C], m[3][3];
  int off[3][C];
#pragma unroll
  for (int a = 0; a < 3; ++a) {
    const Piece& pc = pcs[piece[a]];
    const float4 mp = pc.map;
    int oo[C];
    piece_offsets<C>(pc, oo);
    m[a][0] = mp.x, m[a][1] = mp.y, m[a][2] = mp.z;
    const float t = fmaf(mp.x, pw.x, fmaf(mp.y, pw.y, fmaf(mp.z, pw.z, mp.w)));
#pragma unroll
    for (int k = 0; k < C; ++k) {
      float c[C];
      piece_coefficients<C>(pc, k, c);
      float v = c[C - 1], d = 0.0f;
#pragma unroll
      for (int q = C - 2; q >= 0; --q) {
        d = fmaf(d, t, v);
        v = fmaf(v, t, c[q]);
      }
      w[a][k] = v;
      dw[a][k] = d;
      off[a][k] = oo[k];
    }
  }
  float val[3] = {0, 0, 0}, gu[3] = {0, 0, 0}, gv[3] = {0, 0, 0}, gw[3] = {0, 0, 0};
#pragma unroll
  for (int a = 0; a < C; ++a) {
    float av[3] = {0, 0, 0}, avd[3] = {0, 0, 0}, awd[3] = {0, 0, 0};
#pragma unroll
    for (int b = 0; b < C; ++b) {
      const int row = off[0][a] + off[1][b];
      float bw[3] = {0, 0, 0}, bwd[3] = {0, 0, 0};
#pragma unroll
      for (int c = 0; c < C; ++c) {
        const V3 d4 = D(row + off[2][c]);
        const float d[3] = {d4.x, d4.y, d4.z};
#pragma unroll
        for (int r = 0; r < 3; ++r) {
          bw[r] += w[2][c] * d[r];
          bwd[r] += dw[2][c] * d[r];
        }
      }
#pragma unroll
      for (int r = 0; r < 3; ++r) {
        av[r] += w[1][b] * bw[r];
        avd[r] += dw[1][b] * bw[r];
        awd[r] += w[1][b] * bwd[r];
      }
    }
#pragma unroll
    for (int r = 0; r < 3; ++r) {
      val[r] += w[0][a] * av[r];
      gu[r] += dw[0][a] * av[r];
      gv[r] += w[0][a] * avd[r];
      gw[r] += w[0][a] * awd[r];
    }
  }
  compose_inline(pw, m, val, gu, gv, gw, F, J);
}

// The lattice boxes of ia.box_list in power form: the C^3 coefficient vectors
// A[i][j][k] of F's polynomial part sum A t_u^i t_v^j t_w^k, each the tensor product of the
// three pieces' weight coefficients with the control values. Computed once a block a frame,
// so that a sample is three nested Horner schemes (about half the multiply-adds of the basis
// weights and their contraction).
template <int C>
__device__ __forceinline__ void convert_boxes(const InlineArgs& ia, const int4* box_list, const float4* __restrict__ D4,
                                              const InlinePiece* __restrict__ pcs, float4* __restrict__ boxes) {
  // One thread a (box, i, j): T[c] = sum over a, b of the u and v coefficients times the
  // control values, then A[i][j][k] = sum over c of the w coefficients times T[c] (about a
  // third of the multiply-adds and loads of one full sum a coefficient).
  constexpr int C2 = C * C;
  for (int item = threadIdx.x; item < ia.boxes * C2; item += blockDim.x) {
    const int box = item / C2, ij = item - box * C2;
    const int i = ij / C, j = ij - i * C;
    const int4 b = box_list[box];
    const InlinePiece& pu = pcs[b.x];
    const InlinePiece& pv = pcs[b.y];
    const InlinePiece& pw = pcs[b.z];
    const int ou[4] = {pu.off.x, pu.off.y, pu.off.z, pu.off.w}, ov[4] = {pv.off.x, pv.off.y, pv.off.z, pv.off.w},
              ow[4] = {pw.off.x, pw.off.y, pw.off.z, pw.off.w};
    float T[C][3];
#pragma unroll
    for (int c = 0; c < C; ++c) T[c][0] = T[c][1] = T[c][2] = 0.0f;
#pragma unroll
    for (int a = 0; a < C; ++a) {
      const float4 cu4 = pu.coef[a];
      const float cu = i == 0 ? cu4.x : i == 1 ? cu4.y : i == 2 ? cu4.z : cu4.w;
#pragma unroll
      for (int bb = 0; bb < C; ++bb) {
        const float4 cv4 = pv.coef[bb];
        const float cuv = cu * (j == 0 ? cv4.x : j == 1 ? cv4.y : j == 2 ? cv4.z : cv4.w);
        const float4* row = D4 + ou[a] + ov[bb];
#pragma unroll
        for (int c = 0; c < C; ++c) {
          const float4 d = row[ow[c]];
          T[c][0] += cuv * d.x;
          T[c][1] += cuv * d.y;
          T[c][2] += cuv * d.z;
        }
      }
    }
    float4* out = boxes + (size_t)box * (C * C2) + ij * C;
#pragma unroll
    for (int k = 0; k < C; ++k) {
      float acc[3] = {0, 0, 0};
#pragma unroll
      for (int c = 0; c < C; ++c) {
        const float4 cw4 = pw.coef[c];
        const float cw = k == 0 ? cw4.x : k == 1 ? cw4.y : k == 2 ? cw4.z : cw4.w;
#pragma unroll
        for (int r = 0; r < 3; ++r) acc[r] += cw * T[c][r];
      }
      out[k] = make_float4(acc[0], acc[1], acc[2], 0.0f);
    }
  }
}

// One Horner step of a polynomial and its derivative in t, from the highest power down: step
// `from_top` 0 starts the value at c, step 1 starts the derivative at the value (what
// d * t + v gives from d = 0, without the multiply by zero), later steps are both updates.
__device__ __forceinline__ void horner_step(float& v, float& d, float c, float t, int from_top) {
  if (from_top == 0) {
    v = c;
  } else {
    d = from_top == 1 ? v : fmaf(d, t, v);
    v = fmaf(v, t, c);
  }
}

// Value and the three derivatives (in the pieces' own t) of a box polynomial (convert_boxes):
// Horner over k (w), then j (v), then i (u), each carrying its derivative along; the
// derivatives along the inner axes are Horner schemes of their own in the outer variable.
template <int C>
__device__ __forceinline__ void eval_box(const float4* __restrict__ A, float tu, float tv, float tw, float val[3],
                                         float gu[3], float gv[3], float gw[3]) {
  float qv[3], qdv[3], qdw[3], v[3], d[3];
#pragma unroll
  for (int r = 0; r < 3; ++r) gu[r] = qdv[r] = d[r] = 0.0f;  // C = 1: no derivative steps
#pragma unroll
  for (int i = C - 1; i >= 0; --i) {
#pragma unroll
    for (int j = C - 1; j >= 0; --j) {
      const float4* a = A + (i * C + j) * C;
#pragma unroll
      for (int k = C - 1; k >= 0; --k) {
        const float4 ak = a[k];
        const float c[3] = {ak.x, ak.y, ak.z};
#pragma unroll
        for (int r = 0; r < 3; ++r) horner_step(v[r], d[r], c[r], tw, C - 1 - k);
      }
#pragma unroll
      for (int r = 0; r < 3; ++r) {
        horner_step(qv[r], qdv[r], v[r], tv, C - 1 - j);
        if (j == C - 1) qdw[r] = d[r];
        else qdw[r] = fmaf(qdw[r], tv, d[r]);
      }
    }
#pragma unroll
    for (int r = 0; r < 3; ++r) {
      horner_step(val[r], gu[r], qv[r], tu, C - 1 - i);
      if (i == C - 1) {
        gv[r] = qdv[r];
        gw[r] = qdw[r];
      } else {
        gv[r] = fmaf(gv[r], tu, qdv[r]);
        gw[r] = fmaf(gw[r], tu, qdw[r]);
      }
    }
  }
}

// F and J at one sample from the box polynomials: sample_inline's result up to rounding.
template <int C>
__device__ __forceinline__ void sample_box(const float4* __restrict__ boxes, const InlinePiece* __restrict__ pcs,
                                           float4 pw, uint2 box, float F[3], float J[9]) {
  float t[3], m[3][3];
#pragma unroll
  for (int a = 0; a < 3; ++a) {
    const float4 mp = pcs[(box.x >> (10 * a)) & 1023u].map;
    m[a][0] = mp.x, m[a][1] = mp.y, m[a][2] = mp.z;
    t[a] = fmaf(mp.x, pw.x, fmaf(mp.y, pw.y, fmaf(mp.z, pw.z, mp.w)));
  }
  float val[3], gu[3], gv[3], gw[3];
  eval_box<C>(boxes + (size_t)box.y * (C * C * C), t[0], t[1], t[2], val, gu, gv, gw);
  compose_inline(pw, m, val, gu, gv, gw, F, J);
}

// The inline kernel's three ways of reading the lattice and the plan's tables, chosen per
// plan by CudaEvaluator (the device's shared memory and the plan's sizes decide):
//   kInlineBoxes:   tables in shared memory, samples from the lattice boxes in power form;
//   kInlineWeights: tables and control values in shared memory, samples from the per-axis
//                   weights (the boxes do not fit);
//   kInlineGlobal:  the tables stay in device memory (read through the caches), each sample's
//                   position and pieces come from the plan, the control values from the
//                   frame's upload: any plan (up to kMaxTerms terms an axis, any level, any
//                   lattice), where the tables do not fit in shared memory or the patch records
//                   cannot hold the plan's columns.
enum InlineMode { kInlineBoxes = 0, kInlineWeights = 1, kInlineGlobal = 2 };

// The group's boundary points (corners and edge points) for tessellate_group: from the
// group's list (shared-memory modes) or all of them, one after the other (kInlineGlobal;
// the points no patch of the group writes are skipped).
struct ListedBoundary {
  const uint16_t* list;
  int items;
  __device__ __forceinline__ int count() const { return items; }
  __device__ __forceinline__ void item(int i, int& q, int& w) const {
    const uint32_t e = list[i];
    q = e & 31u, w = e >> 5;
  }
  static constexpr bool kAll = false;
};
struct AllBoundary {
  int patches, points;  // points: the walk's boundary points
  float inv_points;
  __device__ __forceinline__ int count() const { return patches * points; }
  __device__ __forceinline__ void item(int i, int& q, int& w) const {
    q = div_small(i, points, inv_points), w = i - q * points;
  }
  static constexpr bool kAll = true;
};

// The tessellation of k_inline's group of patches (ctrl, already with their fallback normals
// and in power form), in the walk order of the grid (gi: the boundary points' GridInfo, st:
// every point's (s, t)): first the boundary points the group writes (BL: ListedBoundary or
// AllBoundary; sbound: the patches' PatchBoundary tables), one thread a point, so that no
// thread idles beside the others on a point another patch owns; then the interior points,
// which every patch writes, two a thread where no pair straddles two patches, stored straight
// from registers.
template <int kThreads, class BL>
__device__ __forceinline__ void tessellate_group(const PlanView& pv, const FrameView& fv, const GridInfo* __restrict__ gi,
                                                 const WalkST& st, const PatchCtrl* ctrl, const PatchBoundary* sbound,
                                                 const BL& boundary, int base, long long render_shift,
                                                 float* __restrict__ normals) {
  const int L = pv.level;
  const int np = min(kThreads / 4, pv.patches - base);
  const int IG = (L - 1) * (L - 2) / 2;
  const int items = boundary.count();
  for (int i = threadIdx.x; i < items; i += kThreads) {
    int q, w;
    boundary.item(i, q, w);
    const GridInfo t = gi[w];
    int o = -1, r;
    if (t.kind == 0) {
      r = sbound[q].corner[t.which];
    } else {
      const int4 b = sbound[q].edge[t.which];
      o = b.x + t.step * b.y;
      r = b.z + t.step * b.w;
    }
    if (BL::kAll && r < 0 && o < 0) continue;
    V3 x, n;
    const float2 p = st.st[w];
    eval_point(p.x, p.y, ctrl[q][0], ctrl[q][1], load3(ctrl[q].fallback), x, n);
    if (r >= 0) store3(normals + 3 * (long long)r, n);
    if (o >= 0) store3(fv.positions + 3 * (long long)o, x);
  }
  if (IG == 0) return;
  const long long o0 = pv.sub_vertices + (long long)pv.edges * (L - 1) + (long long)base * IG;
  // The warps whose threads took one boundary point more take their interior runs last.
  if (IG % 2 == 0)
    tessellate_interior<2, kThreads>(fv, st, ctrl, np * IG, IG, o0, render_shift, normals);
  else
    tessellate_interior<1, kThreads>(fv, st, ctrl, np * IG, IG, o0, render_shift, normals);
}

// One kernel a frame, persistent: each block stages the lattice tables once (MODE: where they
// live, InlineMode), then takes groups of PB patches (group, group + gridDim.x, ...). LANES
// threads a patch:
// 1 + 3. each lane evaluates its share of the columns (sample, Jacobian, deformed
//    interpolated normal) and accumulates the centre row over the free columns; the 9
//    constraint columns go to shared memory with the corners' Jacobians;
// 2. lanes 0-2: component c of the constraint products (M_r's last 9 columns from the launch
//    parameters), then edge c (edge_control_points_rec); lane 3 copies the tessellation's
//    per-patch tables out of the patch records;
// 4. lane 0: finish_patch_from; then the block tessellates its patches, and meanwhile the
//    next group's patch records (InlinePatch) arrive in shared memory (cp.async).
template <int C, int MODE, int PB, int LANES, int MINB>
__global__ void __launch_bounds__(PB* LANES, MINB)
    k_inline(PlanView pv, FrameView fv, InlineArgs ia, InlineControls dparam, long long render_shift,
             float* __restrict__ normals) {
  static_assert(LANES == 4, "lanes 0-2 take a component / an edge each, lane 3 the tables");
  static_assert(MODE == kInlineGlobal || C <= 4, "the shared-memory tables hold 4 terms an axis");
  constexpr bool BOXES = MODE == kInlineBoxes, SHARED = MODE != kInlineGlobal;
  using Piece = typename std::conditional<SHARED, InlinePiece, InlinePieceWide>::type;
  extern __shared__ float4 lattice_shared[];
  __shared__ PatchCtrl ctrl[PB];
  __shared__ float stage[PB][9][6];       // constraint column j: x (0-2), n (3-5)
  __shared__ float corner_jac[PB][3][9];  // Jacobians at the corners (constraint columns 0-2)
  __shared__ float geo[PB][2][3];         // fitted centre, sum of the fitted edge control points
  __shared__ InlinePatch srec[PB];        // the group's patch records
  __shared__ PatchBoundary sbound[PB];    // their boundary tables (srec is refilled meanwhile)
  const int K = pv.columns, K0 = K - 9;
  static_assert(sizeof(ctrl) >= 16 * kBoxPoints, "the control values fit in ctrl");
  // The tables: in shared memory (laid out as InlineArgs::shared_units counts them), or
  // where they are in device memory (kInlineGlobal).
  float4* sD = nullptr;
  const Piece* sP;
  const InlineColumn* sCol;
  const float2* sST;  // ia.grid_st: (s, t) in walk order
  const GridInfo* sGi;
  float4* sBox = nullptr;
  const int4* sBoxList = nullptr;
  uint16_t* sList = nullptr;  // a group's boundary list
  const ColumnMap* sMap;
  if constexpr (SHARED) {
    sD = BOXES ? reinterpret_cast<float4*>(&ctrl[0]) : lattice_shared;
    InlinePiece* P = reinterpret_cast<InlinePiece*>(lattice_shared + (BOXES ? 0 : ia.points));
    InlineColumn* Col = reinterpret_cast<InlineColumn*>(P + ia.n_pieces);
    float2* ST = reinterpret_cast<float2*>(Col + K);
    GridInfo* Gi = reinterpret_cast<GridInfo*>(reinterpret_cast<float4*>(Col + K) + (ia.st_count + 1) / 2);
    float4* Box = reinterpret_cast<float4*>(Gi + ia.walk_boundary);  // BOXES: boxes x C^3
    int4* BoxList = reinterpret_cast<int4*>(Box + (BOXES ? ia.boxes * C * C * C : 0));
    sList = reinterpret_cast<uint16_t*>(BoxList + ia.box_count);
    ColumnMap* Map = reinterpret_cast<ColumnMap*>(sList + ia.list_stride);
    // The control values: from the launch's parameters indexed directly (constant-bank loads;
    // a pointer into the parameters made these generic loads, which waited on a slow path: 2%
    // of the stall samples), or from device memory.
    if (ia.D) {
      for (int i = threadIdx.x; i < ia.points; i += blockDim.x)
        sD[i] = make_float4(ia.D[3 * i], ia.D[3 * i + 1], ia.D[3 * i + 2], 0.0f);
    } else {
      for (int i = threadIdx.x; i < ia.points; i += blockDim.x)
        sD[i] = make_float4(dparam.v[3 * i], dparam.v[3 * i + 1], dparam.v[3 * i + 2], 0.0f);
    }
    // The plan's tables, as asynchronous copies: all of them in flight at once (as plain loads
    // and stores, each table's loop waited for its loads before the next one's were issued:
    // 2.7% of W1's frame).
    auto copy16 = [&](void* dst, const void* src, int n16) {
      for (int i = threadIdx.x; i < n16; i += blockDim.x)
        __pipeline_memcpy_async(static_cast<int4*>(dst) + i, static_cast<const int4*>(src) + i, 16);
    };
    copy16(P, ia.pieces, 6 * ia.n_pieces);
    copy16(Col, ia.column, 2 * K);
    copy16(ST, ia.grid_st, (ia.st_count + 1) / 2);
    copy16(Gi, ia.grid_walk, ia.walk_boundary);
    copy16(BoxList, ia.box_list, ia.box_count);
    for (int i = threadIdx.x; i < (int)(sizeof(ColumnMap) / 4); i += blockDim.x)
      __pipeline_memcpy_async(reinterpret_cast<int*>(Map) + i, reinterpret_cast<const int*>(ia.column_map) + i, 4);
    __pipeline_commit();
    sP = reinterpret_cast<const Piece*>(P), sCol = Col, sST = ST, sGi = Gi, sBox = Box, sBoxList = BoxList, sMap = Map;
  } else {
    sP = reinterpret_cast<const Piece*>(ia.pieces_wide), sCol = ia.column, sST = ia.grid_st, sGi = ia.grid_walk;
    sMap = ia.column_map;
  }
  // The group's patch records, copied asynchronously (no registers held, no wait until
  // __pipeline_wait_prior before the barrier that precedes their use).
  auto fetch_patch_records = [&](int grp) {
    if (grp < ia.groups) {
      const int n = kPatchChunks * min(PB, pv.patches - grp * PB);
      const int4* src = reinterpret_cast<const int4*>(ia.patch_rec + (long long)grp * PB);
      int4* dst = reinterpret_cast<int4*>(srec);
      for (int i = threadIdx.x; i < n; i += blockDim.x) __pipeline_memcpy_async(dst + i, src + i, 16);
    }
    __pipeline_commit();
  };
  const int lp = threadIdx.x / LANES, lane = threadIdx.x % LANES;
  fetch_patch_records(blockIdx.x);  // the first group's, committed last: not waited for yet
  if (SHARED) __pipeline_wait_prior(1);  // the tables
  __syncthreads();
  const int n_cols = sMap->n_cols;
  auto column = [&](int i) { return (int)sMap->order[i]; };
  if constexpr (BOXES) convert_boxes<C>(ia, sBoxList, sD, reinterpret_cast<const InlinePiece*>(sP), sBox);
  __pipeline_wait_prior(0);  // the first group's patch records, which arrived meanwhile
  __syncthreads();           // and ctrl (the staged control values) is free again
  // Block b takes groups b, b + gridDim.x, ...: at any time the blocks work on neighbouring
  // groups, whose samples and tables share cache lines. (Handing out groups from an atomic
  // counter instead, to even out the SMs' busy time, measured 5% slower.)
  for (int group = blockIdx.x; group < ia.groups; group += gridDim.x) {
    const int base = group * PB;
    const int p = base + lp;
    const bool live = p < pv.patches;

    // 1 + 3. Sampling and the constrained fit's centre row over the free columns.
    V3 gc = v3(0, 0, 0), nc = v3(0, 0, 0);
    const InlinePatch& rec = srec[lp];
    if constexpr (SHARED) {
      // The group's boundary list, on its way during the sampling (waited for before the
      // barrier that precedes the tessellation).
      const int4* src = reinterpret_cast<const int4*>(ia.boundary_list + (long long)group * ia.list_stride);
      for (int i = threadIdx.x; i < (srec[0].bound.items + 7) / 8; i += blockDim.x)
        __pipeline_memcpy_async(reinterpret_cast<int4*>(sList) + i, src + i, 16);
      __pipeline_commit();
    }
    if (live) {
      const float4 P0 = rec.corner[0], P1 = rec.corner[1], P2 = rec.corner[2];
      for (int i = lane; i < n_cols; i += LANES) {
        const int k = column(i);
        const InlineColumn& cl = sCol[k];
        float F[3], J[9];
        float4 pw;
        if constexpr (SHARED) {
          pw = inline_sample_point(cl, rec.flags, P0, P1, P2);
          const int b = rec.box[i];
          const uint32_t packed = (uint32_t)sBoxList[b].w;
          if constexpr (BOXES) {
            sample_box<C>(sBox, reinterpret_cast<const InlinePiece*>(sP), pw, make_uint2(packed, (uint32_t)b), F, J);
          } else {
            const int piece[3] = {(int)(packed & 1023u), (int)((packed >> 10) & 1023u), (int)(packed >> 20)};
            sample_inline<C>(SharedControls{sD}, sP, pw, piece, F, J);
          }
        } else {
          // The sample as the plan has it: its position, vertex weight and pieces.
          const long long s = pv.patch_samples[(long long)p * K + k];
          pw = make_float4(__ldg(pv.sample_position + 3 * s), __ldg(pv.sample_position + 3 * s + 1),
                           __ldg(pv.sample_position + 3 * s + 2), __ldg(pv.sample_weight + s));
          const uint32_t packed = __ldg(pv.sample_piece + s);
          int piece[3];
#pragma unroll
          for (int a = 0; a < 3; ++a) piece[a] = pv.axis_offset[a] + (int)((packed >> (10 * a)) & 1023u);
          sample_inline<C>(GlobalControls{ia.D}, sP, pw, piece, F, J);
        }
        const float4 col = cl.bary;
        const V3 x = v3(F[0], F[1], F[2]);
        // deformed_column_normal (stages.hpp) with the column's point from the column table.
        const float* rn = rec.rest;
        const V3 rn0 = load3(rn);
        const V3 n0 = col.x * rn0 + col.y * load3(rn + 3) + col.z * load3(rn + 6);
        const V3 n = normalized_or(normalized_or(cofactor_apply(J, n0), n0), rn0);
        int con = k - K0;
        if (k < K0) {
          gc += col.w * x;
          nc += col.w * n;
          con = sMap->con_of[k];
        }
        if (con >= 0) {
          float* st = stage[lp][con];
          store3(st, x);
          store3(st + 3, n);
          if (con < 3)
#pragma unroll
            for (int q = 0; q < 9; ++q) corner_jac[lp][con][q] = J[q];
        }
      }
    }
    gc = lanes_sum<LANES>(gc);
    nc = lanes_sum<LANES>(nc);
    __syncwarp();  // a patch's lanes share a warp: its stage and corner_jac are written
    if (live && lane < 3) {
      // 3. Component c of the normal patch (all rows), of the fitted centre and of the
      // fitted edge control points' sum, from the constraint columns.
      const int c = lane;
      float xs[9], ns[9];
#pragma unroll
      for (int q = 0; q < 9; ++q) xs[q] = stage[lp][q][c], ns[q] = stage[lp][q][3 + c];
      const float gcc = c == 0 ? gc.x : c == 1 ? gc.y : gc.z, ncc = c == 0 ? nc.x : c == 1 ? nc.y : nc.z;
      // In power form for the tessellation (eval_point), and the fallback normal's component
      // (set_fallback_normal's sum of the corners, normalized by lane 0 below).
      float acc[10], pf[10];
#pragma unroll
      for (int r = 0; r < 10; ++r) {
        acc[r] = r == kCentre ? ncc : 0.0f;
#pragma unroll
        for (int q = 0; q < 9; ++q) acc[r] += ia.mrow[r][q] * ns[q];
      }
      ctrl[lp].fallback[c] = acc[0] + acc[1] + acc[2];
      cubic_power_form(acc, pf);
#pragma unroll
      for (int r = 0; r < 10; ++r) ctrl[lp][1][3 * r + c] = pf[r];
      float cen = gcc, esum = 0.0f;
#pragma unroll
      for (int q = 0; q < 9; ++q) {
        cen += ia.mrow[kCentre][q] * xs[q];
        esum += ia.mrow[10][q] * xs[q];
      }
      geo[lp][0][c] = cen;
      geo[lp][1][c] = esum;
      // 2. Edge k = c of the patch (corner k -> k + 1) from its own constraint columns:
      // corners are columns 0-2, the points at 1/3 and 2/3 from corner k are columns 3 + 2k
      // and 4 + 2k (plan/fit_matrix.hpp), in the edge's own a -> b order as adjust_edge has
      // them. Both patches of an edge evaluate the same samples with the same instructions:
      // bitwise the same edge control points, a watertight surface.
      const int k = c, k1 = (k + 1) % 3;
      const bool rev = (rec.flags >> (3 + k)) & 1u;
      const int ka = rev ? k1 : k, kb = rev ? k : k1;
      const int q1 = rev ? 4 + 2 * k : 3 + 2 * k, q2 = rev ? 3 + 2 * k : 4 + 2 * k;
      V3 cp[2];
      edge_control_points_rec(rec, k, ka, kb, load3(stage[lp][ka]), load3(stage[lp][kb]), load3(stage[lp][q1]),
                              load3(stage[lp][q2]), corner_jac[lp][ka], corner_jac[lp][kb], cp);
      // Straight into the geometry patch (finish_patch_from's corner and edge rows).
      float* g = ctrl[lp][0];
      store3(g + 3 * k, load3(stage[lp][k]));
      store3(g + 3 * edge_control_index(k, false), rev ? cp[1] : cp[0]);
      store3(g + 3 * edge_control_index(k, true), rev ? cp[0] : cp[1]);
    } else if (live) {
      // The tessellation's tables, out of the record (which the next group's overwrites).
      sbound[lp] = rec.bound;
    }
    __syncwarp();
    if (live && lane == 0) {
      // finish_patch_from (stages.hpp): exact corners, adjusted edges (lanes 0-2 put both
      // in place), the centre moved with the edges; then the patch in power form for the
      // tessellation (eval_point), written back in one pass.
      const uint32_t mine = rec.flags >> 8;
      V3 b[10], a[10];
      load_field(ctrl[lp][0], b);
      V3 adjusted = v3(0, 0, 0);
      for (int k = 0; k < 3; ++k) {
        adjusted += b[edge_control_index(k, false)] + b[edge_control_index(k, true)];
        if ((mine >> k) & 1) store3(fv.positions + 3 * (long long)rec.vertex[k], b[k]);
      }
      b[kCentre] = load3(geo[lp][0]) + 0.25f * (adjusted - load3(geo[lp][1]));
      cubic_power_form(b, a);
      store_field(ctrl[lp][0], a);
      // The fallback normal from the corners' sum (lanes 0-2), before the barrier below.
      store3(ctrl[lp].fallback, normalized_or(load3(ctrl[lp].fallback), v3(0, 0, 1)));
    }
    if (SHARED) __pipeline_wait_prior(0);  // the boundary list
    __syncthreads();
    // 4. Tessellation.
    fetch_patch_records(group + gridDim.x);
    const WalkST st{sST, ia.st_interior};
    if constexpr (SHARED) {
      tessellate_group<PB * LANES>(pv, fv, sGi, st, ctrl, sbound, ListedBoundary{sList, sbound[0].items}, base,
                                   render_shift, normals);
    } else {
      const int np = min(PB, pv.patches - base);
      tessellate_group<PB * LANES>(pv, fv, sGi, st, ctrl, sbound,
                                   AllBoundary{np, ia.walk_boundary, 1.0f / (float)ia.walk_boundary}, base,
                                   render_shift, normals);
    }
    __pipeline_wait_prior(0);
    __syncthreads();  // the next group's records are in; it overwrites the block's tables
  }
}

// Output positions of the sub-vertices that no patch has (loose input vertices), which the
// inline kernel therefore does not write.
template <int C>
__global__ void __launch_bounds__(256) k_loose_vertices(PlanView pv, FrameView fv, const float* __restrict__ D,
                                                        const int* __restrict__ loose, int count) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i >= count) return;
  const int v = loose[i];
  float F[3], J[9];
  sample_point_c<C>(pv, D, v, F, J);
  store3(fv.positions + 3 * (long long)v, v3(F[0], F[1], F[2]));
}
