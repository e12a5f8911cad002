// The fused path: k_inline, one persistent kernel a frame in which each patch samples, fits,
// adjusts its edges and tessellates, with nothing going through device memory between the
// stages; and its launchers (kernels.hpp). Its tables are device_tables.hpp's, its helpers
// inline_sampling.cuh and inline_tessellation.cuh.
//
// Why one kernel: a staged pipeline (sampling kernel -> edge kernel -> fit, as the reference
// path runs) writes every sample's value and Jacobian (48 bytes) and gathers them back by
// index for each patch; the fit then waits on those dependent gathers, and the edge kernel is a
// launch of its own (2.8x slower than this kernel on W1 at L = 10, the last time both ran).
// Here each patch evaluates its 37 columns itself (28 evaluations once the constraint columns
// that are grid points are shared; a sample on an edge is evaluated by both patches, about 1.6
// evaluations a sample), and adjusts its own three edges from its own constraint columns. In
// the shared-memory modes it places each sample itself, from the three corner samples in its
// patch record (inline_sample_point), so no per-sample record is gathered. The two patches of
// an edge place and evaluate the same samples with the same instructions, so they compute
// bitwise the same edge control points and the surface stays watertight, as with one thread
// an edge. The tessellation evaluates the patches in power form (eval_point).
//
// Modes (InlineMode, chosen per plan by CudaEvaluator from its tables and the device's shared
// memory): a sample from the lattice boxes in power form (boxes), from the axis pieces'
// weights and the tensor contraction (weights: the boxes do not fit), or, where even those
// tables do not fit or the plan has more than 4 terms an axis, with the tables in device
// memory and each sample's position and pieces from the plan (global). The profiles and
// measurements that led here are in git (docs/benchmarks.md says where).
#include <cuda_pipeline.h>
#include <cuda_runtime.h>

#include <stdexcept>
#include <string>
#include <type_traits>

#include "smoothffd/cuda/device_memory.hpp"
#include "smoothffd/cuda/inline_sampling.cuh"
#include "smoothffd/cuda/inline_tessellation.cuh"
#include "smoothffd/cuda/kernels.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {
namespace cuda_impl {

namespace {

constexpr int kPatchChunks = sizeof(InlinePatch) / 16;

// edge_control_points (stages.hpp) of patch edge k (ends a, b at corners ka, kb) with the
// rest adjustment normals from the patch's record: both patches of an edge run the same
// function on the same operands, so they compute bitwise the same control points.
__device__ __forceinline__ void edge_control_points_rec(const InlinePatch& r, int k, int ka, int kb, V3 Pa, V3 Pb,
                                                        V3 Q1, V3 Q2, const float* Ja, const float* Jb, V3 c[2]) {
  const uint32_t ef = (r.flags >> (12 + 4 * k)) & 15u;
  const bool self1 = ((r.flags >> (24 + k)) & 1u) != 0;  // this patch is the edge's side 1
  // Both normals loaded, then one chosen (independent loads, not a load from a chosen address).
  auto rest = [&](int end, int side) {
    const V3 own = load3(r.adjust + 3 * (end ? kb : ka)), across = load3(r.nb[k] + 3 * end);
    return (side == 1) == self1 ? own : across;
  };
  edge_control_points(Pa, Pb, Q1, Q2, Ja, Jb, ef & 3u, (ef & 4u) != 0, (ef & 8u) != 0, rest, c);
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
  // The tables: in shared memory (laid out as DeviceTables::shared_bytes counts them), or
  // where they are in device memory (kInlineGlobal).
  float4* sD = nullptr;
  const Piece* sP;
  const InlineColumn* sCol;
  const F2* sST;  // ia.grid_st: (s, t) in walk order
  const GridInfo* sGi;
  float4* sBox = nullptr;
  const I4* sBoxList = nullptr;
  uint16_t* sList = nullptr;  // a group's boundary list
  const ColumnMap* sMap;
  if constexpr (SHARED) {
    sD = BOXES ? reinterpret_cast<float4*>(&ctrl[0]) : lattice_shared;
    InlinePiece* P = reinterpret_cast<InlinePiece*>(lattice_shared + (BOXES ? 0 : ia.points));
    InlineColumn* Col = reinterpret_cast<InlineColumn*>(P + ia.n_pieces);
    F2* ST = reinterpret_cast<F2*>(Col + K);
    GridInfo* Gi = reinterpret_cast<GridInfo*>(reinterpret_cast<float4*>(Col + K) + (ia.st_count + 1) / 2);
    float4* Box = reinterpret_cast<float4*>(Gi + ia.walk_boundary);  // BOXES: boxes x C^3
    I4* BoxList = reinterpret_cast<I4*>(Box + (BOXES ? ia.boxes * C * C * C : 0));
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
  if constexpr (BOXES) convert_boxes<C>(ia.boxes, sBoxList, sD, reinterpret_cast<const InlinePiece*>(sP), sBox);
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
      const float4 P0 = ld(rec.corner[0]), P1 = ld(rec.corner[1]), P2 = ld(rec.corner[2]);
      // The columns' boxes through a pointer stepped with i: as rec.box[i], the compiler
      // folded &srec[lp] into the loop's address and rebuilt it every column (S2UR, LEA, IMAD,
      // IADD3 before the box index's load, which starts the sample's dependency chain; 4 more
      // instructions a column than this form on sm_90, bench/sass_compare.sh). With it, the
      // rest normals are loaded above the loop (else they were reloaded every column); the
      // global mode loads them a column (above the loop: 12 bytes of spills with 3 terms).
      const uint8_t* box_of = rec.box + lane;
      V3 rn[3];
      auto load_rest = [&] {
        for (int q = 0; q < 3; ++q) rn[q] = load3(rec.rest + 3 * q);
      };
      if constexpr (SHARED) load_rest();
      for (int i = lane; i < n_cols; i += LANES, box_of += LANES) {
        const int k = column(i);
        const InlineColumn& cl = sCol[k];
        float F[3], J[9];
        float4 pw;
        if constexpr (SHARED) {
          pw = inline_sample_point(cl, rec.flags, P0, P1, P2);
          const int b = *box_of;
          const uint32_t packed = (uint32_t)sBoxList[b].w;
          if constexpr (BOXES) {
            sample_box<C>(sBox, reinterpret_cast<const InlinePiece*>(sP), pw, make_uint2(packed, (uint32_t)b), F, J);
          } else {
            const int piece[3] = {(int)(packed & 1023u), (int)((packed >> 10) & 1023u), (int)(packed >> 20)};
            sample_inline<C>(SharedControls{sD}, sP, pw, piece, F, J);
          }
        } else {
          // The sample as the plan has it: its position, vertex weight, pieces and, for knot
          // spans too small for float positions, its local coordinates.
          const long long s = pv.patch_samples[(long long)p * K + k];
          pw = make_float4(__ldg(pv.sample_position + 3 * s), __ldg(pv.sample_position + 3 * s + 1),
                           __ldg(pv.sample_position + 3 * s + 2), __ldg(pv.sample_weight + s));
          const uint32_t packed = __ldg(pv.sample_piece + s);
          int piece[3];
#pragma unroll
          for (int a = 0; a < 3; ++a) piece[a] = pv.axis_offset[a] + (int)((packed >> (10 * a)) & 1023u);
          sample_inline<C>(GlobalControls{ia.D}, sP, pw, piece, F, J,
                           pv.sample_local ? pv.sample_local + 3 * s : nullptr);
        }
        const float4 col = ld(cl.bary);
        const V3 x = v3(F[0], F[1], F[2]);
        // deformed_column_normal (stages.hpp) with the column's point from the column table.
        if constexpr (!SHARED) load_rest();
        const V3 n = deformed_normal_at(col.x, col.y, col.z, rn, J);
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
      b[kCentre] = moved_centre(load3(geo[lp][0]), load3(geo[lp][1]), adjusted);
      cubic_power_form(b, a);
      store_field(ctrl[lp][0], a);
      // The fallback normal from the corners' sum (lanes 0-2), before the barrier below.
      store3(ctrl[lp].fallback, patch_normal_fallback(load3(ctrl[lp].fallback)));
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
  sample_point_fixed<C>(pv, D, v, F, J);
  store3(fv.positions + 3 * (long long)v, v3(F[0], F[1], F[2]));
}

// Register caps (blocks of 128 an SM): the shared-memory modes 4 with 3 terms (128 registers,
// no spills; 5 blocks spilled and measured 6% slower), 2 with 2 or 4; the global mode the most
// blocks whose cap ptxas meets without spilling on sm_90 (4 terms: 168 registers at 3 blocks,
// where 2 blocks let it take 254; 5 terms: 167 at 3, where 1 or 2 blocks spilled at 255), and
// 4 for kMaxTerms (16 bytes of spills; 1 block spilled more).
constexpr int inline_min_blocks(int C, int mode) {
  return C == 3 ? 4 : mode != kInlineGlobal ? 2 : C == 2 ? 2 : C <= 5 ? 3 : 4;
}

using InlineKernel = void (*)(PlanView, FrameView, InlineArgs, InlineControls, long long, float*);

template <int C>
InlineKernel inline_kernel_c(int mode) {
  if constexpr (C <= 4) {
    if (mode == kInlineBoxes) return k_inline<C, kInlineBoxes, 32, 4, inline_min_blocks(C, kInlineBoxes)>;
    if (mode == kInlineWeights) return k_inline<C, kInlineWeights, 32, 4, inline_min_blocks(C, kInlineWeights)>;
  }
  if (mode == kInlineGlobal) return k_inline<C, kInlineGlobal, 32, 4, inline_min_blocks(C, kInlineGlobal)>;
  throw std::logic_error("CudaEvaluator: no inline kernel for mode " + std::to_string(mode) + " with " +
                         std::to_string(C) + " terms an axis");
}

// k_inline for `terms` terms an axis (kernel_terms) in InlineMode `mode`.
InlineKernel inline_kernel(int terms, int mode) {
  switch (terms) {
    case 2: return inline_kernel_c<2>(mode);
    case 3: return inline_kernel_c<3>(mode);
    case 4: return inline_kernel_c<4>(mode);
    case 5: return inline_kernel_c<5>(mode);
    case kMaxTerms: return inline_kernel_c<kMaxTerms>(mode);
    default: throw std::logic_error("CudaEvaluator: no inline kernel for " + std::to_string(terms) + " terms an axis");
  }
}

}  // namespace

size_t inline_static_shared(int terms, int mode) {
  cudaFuncAttributes a{};
  CK(cudaFuncGetAttributes(&a, inline_kernel(terms, mode)));
  return a.sharedSizeBytes;
}

int inline_blocks_per_multiprocessor(int terms, int mode, size_t smem, size_t optin) {
  const InlineKernel kern = inline_kernel(terms, mode);
  // Opt in to the largest table any plan may bring on this device (a per-function setting,
  // shared by every evaluator), then ask how many blocks of this plan's size fit an SM.
  if (mode != kInlineGlobal) CK(cudaFuncSetAttribute(kern, cudaFuncAttributeMaxDynamicSharedMemorySize, (int)optin));
  int per_sm = 0;
  CK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kern, 128, smem));
  return per_sm;
}

void launch_inline(int terms, int mode, int grid, size_t smem, const PlanView& pv, const FrameView& fv,
                   const InlineArgs& args, const InlineControls& params, long long render_shift, float* normals,
                   cudaStream_t stream) {
  const InlineKernel kern = inline_kernel(terms, mode);
  kern<<<grid, 128, smem, stream>>>(pv, fv, args, params, render_shift, normals);
  CK_LAUNCH(k_inline);
}

void launch_loose_vertices(int terms, const PlanView& pv, const FrameView& fv, const float* D, const int* loose,
                           int count, cudaStream_t stream) {
  if (count <= 0) return;
  const unsigned grid = blocks_for(count, 256);
  switch (terms) {
    case 2: k_loose_vertices<2><<<grid, 256, 0, stream>>>(pv, fv, D, loose, count); break;
    case 3: k_loose_vertices<3><<<grid, 256, 0, stream>>>(pv, fv, D, loose, count); break;
    case 4: k_loose_vertices<4><<<grid, 256, 0, stream>>>(pv, fv, D, loose, count); break;
    case 5: k_loose_vertices<5><<<grid, 256, 0, stream>>>(pv, fv, D, loose, count); break;
    default: k_loose_vertices<kMaxTerms><<<grid, 256, 0, stream>>>(pv, fv, D, loose, count); break;
  }
  CK_LAUNCH(k_loose_vertices);
}

}  // namespace cuda_impl
}  // namespace sffd
