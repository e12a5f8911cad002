// The inline fused path (the CUDA evaluator's default for plans with at most 4 terms an axis):
// one kernel a frame samples, fits, adjusts the edges and tessellates, with nothing going
// through device memory between the stages. Included by cuda_evaluator.cu inside its anonymous
// namespace (it uses GridInfo, PatchRender and tessellate_block from there).
//
// Why: the staged path (k_sample -> k_edge -> k_fit_tessellate_staged) writes every sample's
// value and Jacobian (48 bytes) and gathers them back by index for each patch; the fit then
// waits on those dependent gathers, and the edge kernel is a launch of its own. Here each
// patch evaluates its 37 columns itself (a sample on an edge is evaluated by both patches,
// about 2 evaluations a sample), from the control values and axis pieces staged in shared
// memory, and adjusts its own three edges from its own constraint columns. The two patches of
// an edge evaluate the same samples with the same instructions, so they compute bitwise the
// same edge control points and the surface stays watertight, as with one thread an edge.
#pragma once

// Lattice tables an inline kernel stages in shared memory: the control values padded to
// float4 (one 16-byte load a control point) and the axis pieces.
struct InlineLattice {
  const float* D;  // control values, 3 floats a point (device)
  int points;      // control points
  int pieces;      // axis pieces of the three axes
  size_t shared_bytes() const { return 16 * (size_t)points + sizeof(AxisPieceF) * (size_t)pieces; }
};

// The constraint columns (corners, edge points at 1/3 and 2/3) are usually fitting-grid points
// too (always the corners; the edge points when the fitting degree is a multiple of 3), with
// the same sample: such a column is evaluated once. con_of[k]: constraint column (0-8) that
// grid column k also is, or -1; extra[0 .. n_extra): constraint columns that are no grid point.
constexpr int kMaxInlineGrid = 64;  // fitting-grid columns; C <= 4 gives degree <= 9: 55
struct ColumnMap {
  int8_t con_of[kMaxInlineGrid];
  int8_t extra[9];
  int n_extra;
};

// Largest shared-memory table an inline launch may ask for: with the ~22 KB of static shared
// memory (32 patches a block) it stays under the 48 KB a block gets without an opt-in.
// Larger lattices (beyond about 1000 control points of degree 2) run the staged path.
constexpr size_t kInlineSharedBytes = 24 * 1024;

__device__ __forceinline__ void stage_lattice(const PlanView& pv, const InlineLattice& lat, float4* sD, AxisPieceF* sP) {
  for (int i = threadIdx.x; i < lat.points; i += blockDim.x)
    sD[i] = make_float4(lat.D[3 * i], lat.D[3 * i + 1], lat.D[3 * i + 2], 0.0f);
  const int words = lat.pieces * (int)(sizeof(AxisPieceF) / 4);
  const int* src = reinterpret_cast<const int*>(pv.pieces);
  int* dst = reinterpret_cast<int*>(sP);
  for (int i = threadIdx.x; i < words; i += blockDim.x) dst[i] = src[i];
}

// sample_point (stages.hpp) with C terms an axis, the pieces and float4 control values from
// shared memory and 32-bit indices: tensor_eval_fixed's contraction in the same order of
// operations, so the result is the CPU's up to the compiler's contraction of multiply-adds.
template <int C>
__device__ __forceinline__ void sample_inline(const PlanView& pv, const float4* __restrict__ D4,
                                              const AxisPieceF* pieces, int s, float F[3], float J[9]) {
  float p[3] = {pv.sample_position[3 * s], pv.sample_position[3 * s + 1], pv.sample_position[3 * s + 2]};
  int idx[3][C];
  float w[3][C], dw[3][C];
  sample_weights<C>(pv, p, pv.sample_piece[s], idx, w, dw, pieces);
  const int nv = pv.dims[1], nw = pv.dims[2];
  float val[3] = {0, 0, 0}, gu[3] = {0, 0, 0}, gv[3] = {0, 0, 0}, gw[3] = {0, 0, 0};
#pragma unroll
  for (int a = 0; a < C; ++a) {
    float av[3] = {0, 0, 0}, avd[3] = {0, 0, 0}, awd[3] = {0, 0, 0};
#pragma unroll
    for (int b = 0; b < C; ++b) {
      const int row = (idx[0][a] * nv + idx[1][b]) * nw;
      float bw[3] = {0, 0, 0}, bwd[3] = {0, 0, 0};
#pragma unroll
      for (int c = 0; c < C; ++c) {
        const float4 d4 = D4[row + idx[2][c]];
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
  float grad[9];
#pragma unroll
  for (int r = 0; r < 3; ++r) {
    grad[3 * r] = gu[r];
    grad[3 * r + 1] = gv[r];
    grad[3 * r + 2] = gw[r];
  }
  finish_sample(pv, p, s, val, grad, F, J);
}

// One kernel a frame. LANES threads a patch: each evaluates its share of the K columns
// (sample, Jacobian, deformed interpolated normal) and accumulates the centre row over the
// free columns; the 9 constraint columns go to shared memory with the corners' Jacobians.
// Then the 60 constraint products (lanes interleaved), the three edges (lanes 0-2, see
// edge_control_points), finish_patch_from on lane 0, and the block's tessellation.
// corner_owns[p] bit k: patch p writes the output position of its corner k (each sub-vertex
// is written by the first patch that has it).
template <int C, int PB, int LANES, int MINB>
__global__ void __launch_bounds__(PB* LANES, MINB)
    k_inline(PlanView pv, FrameView fv, InlineLattice lat, ColumnMap cm, const GridInfo* __restrict__ gi,
             const uint8_t* __restrict__ owns, const uint8_t* __restrict__ corner_owns,
             const PatchRender* __restrict__ prender, long long render_shift, float* __restrict__ normals) {
  static_assert(32 % LANES == 0 && LANES >= 4, "lanes of a patch share a warp; 3 of them adjust the edges");
  extern __shared__ float4 lattice_shared[];
  __shared__ __align__(16) float ctrl[PB][2][kCtrlStride];
  __shared__ float stage[PB][9][6];       // constraint column j: x (0-2), n (3-5)
  __shared__ float corner_jac[PB][3][9];  // Jacobians at the corners (constraint columns 0-2)
  __shared__ float edge_cp[PB][3][2][3];  // adjusted edge k: next to corner k, next to corner k+1
  __shared__ float mcon[10][9];           // M_r's last 9 columns
  __shared__ int sedge[PB][3];
  __shared__ uint8_t sflags[PB];  // bits 0-2: owns edge k; bits 3-5: edge k reversed
  __shared__ PatchRender srender[PB];
  float4* sD = lattice_shared;
  AxisPieceF* sP = reinterpret_cast<AxisPieceF*>(lattice_shared + lat.points);
  const int base = blockIdx.x * PB;
  const int lp = threadIdx.x / LANES, lane = threadIdx.x % LANES;
  const int p = base + lp;
  const int K = pv.columns, K0 = K - 9;
  for (int i = threadIdx.x; i < 90; i += PB * LANES) mcon[i / 9][i % 9] = pv.fit_matrix[(i / 9) * K + K0 + i % 9];
  stage_lattice(pv, lat, sD, sP);
  __syncthreads();

  // 1 + 3. Sampling and the constrained fit's centre row.
  V3 gc = v3(0, 0, 0), nc = v3(0, 0, 0);
  if (p < pv.patches) {
    V3 rn[3];
    for (int k = 0; k < 3; ++k) rn[k] = load3(pv.patch_render_normal + 9 * (long long)p + 3 * k);
    for (int i = lane; i < K0 + cm.n_extra; i += LANES) {
      const int k = i < K0 ? i : K0 + cm.extra[i - K0];  // the column
      float F[3], J[9];
      sample_inline<C>(pv, sD, sP, pv.patch_samples[(long long)p * K + k], F, J);
      const V3 x = v3(F[0], F[1], F[2]);
      const V3 n = deformed_column_normal(pv, k, rn, J);
      int con = k - K0;
      if (k < K0) {
        float m = pv.fit_matrix[kCentre * K + k];
        gc += m * x;
        nc += m * n;
        con = cm.con_of[k];
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
#pragma unroll
  for (int off = 1; off < LANES; off <<= 1) {
    gc.x += __shfl_xor_sync(0xffffffffu, gc.x, off);
    gc.y += __shfl_xor_sync(0xffffffffu, gc.y, off);
    gc.z += __shfl_xor_sync(0xffffffffu, gc.z, off);
    nc.x += __shfl_xor_sync(0xffffffffu, nc.x, off);
    nc.y += __shfl_xor_sync(0xffffffffu, nc.y, off);
    nc.z += __shfl_xor_sync(0xffffffffu, nc.z, off);
  }
  __syncthreads();  // stage, corner_jac written
  if (p < pv.patches) {
    // 3. The boundary rows and the rest of the centre row from the constraint columns.
    for (int j = lane; j < 60; j += LANES) {
      const int r = j / 6, c = j - 6 * r;
      float acc = 0.0f;
      if (r == kCentre) acc = c == 0 ? gc.x : c == 1 ? gc.y : c == 2 ? gc.z : c == 3 ? nc.x : c == 4 ? nc.y : nc.z;
#pragma unroll
      for (int q = 0; q < 9; ++q) acc += mcon[r][q] * stage[lp][q][c];
      ctrl[lp][c / 3][3 * r + c % 3] = acc;
    }
    // 2. Edge k of the patch (corner k -> k + 1) from its own constraint columns: corners are
    // columns 0-2, the points at 1/3 and 2/3 from corner k are columns 3 + 2k and 4 + 2k
    // (plan/fit_matrix.hpp), in the edge's own a -> b order as adjust_edge has them.
    if (lane < 3) {
      const int k = lane, k1 = (k + 1) % 3, e = pv.patch_edge[3 * p + k];
      const bool rev = pv.patch_edge_reversed[3 * p + k];
      const int ka = rev ? k1 : k, kb = rev ? k : k1;
      const int q1 = rev ? 4 + 2 * k : 3 + 2 * k, q2 = rev ? 3 + 2 * k : 4 + 2 * k;
      V3 c[2];
      edge_control_points(pv, e, load3(stage[lp][ka]), load3(stage[lp][kb]), load3(stage[lp][q1]),
                          load3(stage[lp][q2]), corner_jac[lp][ka], corner_jac[lp][kb], c);
      store3(edge_cp[lp][k][0], rev ? c[1] : c[0]);
      store3(edge_cp[lp][k][1], rev ? c[0] : c[1]);
    }
  }
  __syncwarp();
  if (p < pv.patches && lane == 0) {
    V3 g[10], corner[3], cp[3][2];
#pragma unroll
    for (int r = 0; r < 10; ++r) g[r] = load3(ctrl[lp][0] + 3 * r);
    const uint8_t mine = corner_owns[p];
    for (int k = 0; k < 3; ++k) {
      corner[k] = load3(stage[lp][k]);
      cp[k][0] = load3(edge_cp[lp][k][0]);
      cp[k][1] = load3(edge_cp[lp][k][1]);
      if ((mine >> k) & 1) store3(fv.positions + 3 * (long long)pv.patch_vertex[3 * p + k], corner[k]);
    }
    finish_patch_from(corner, cp, g);
#pragma unroll
    for (int r = 0; r < 10; ++r) store3(ctrl[lp][0] + 3 * r, g[r]);
    uint8_t f = owns[p];
    for (int k = 0; k < 3; ++k) {
      sedge[lp][k] = pv.patch_edge[3 * p + k];
      f |= uint8_t(pv.patch_edge_reversed[3 * p + k] ? 8u << k : 0u);
    }
    sflags[lp] = f;
    srender[lp] = prender[p];
  }
  __syncthreads();
  // 4. Tessellation.
  tessellate_block<PB, LANES>(pv, fv, gi, ctrl, sedge, sflags, srender, base, render_shift, normals);
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
