// The kernels' launchers, as the host evaluator (cuda_evaluator.cpp) calls them: plain C++
// over device pointers and a stream, like OpenSubdiv's extern "C" functions of
// osd/cudaKernel.cu. The kernels themselves are in inline_kernel.cu (the fused path) and
// reference_kernels.cu (the cuBLAS reference path's sampling, edge, gather, finish, scatter).
// Every launcher throws CudaError when the launch fails.
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>

#include "smoothffd/cuda/device_tables.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {
namespace cuda_impl {

// Largest lattice whose control values ride in the inline kernel's launch parameters (3 KB)
// instead of a copy to the device before it: a frame is then one launch and nothing else.
constexpr int kParamPoints = 256;
struct InlineControls {
  float v[3 * kParamPoints];
};

// The device copies of the DeviceTables k_inline reads, and the launch's own values. A launch
// parameter, so that the products read mrow from the constant bank.
struct InlineArgs {
  const InlinePiece* pieces;           // the shared-memory modes'
  const InlinePieceWide* pieces_wide;  // the global mode's
  const InlineColumn* column;          // K
  const ColumnMap* column_map;
  const float* D;  // control values on the device, or null: from InlineControls (not global)
  int points, n_pieces, groups;
  // The lattice boxes (one piece an axis) that hold samples, box_count of them: each box's
  // three pieces and, w, the three packed 10 bits each. In power form (boxes = box_count) or
  // not used (boxes = 0: the per-sample weights).
  const I4* box_list;
  int box_count, boxes;
  // The tessellation grid in the order tessellate_group walks it (entry w is grid point
  // GridInfo::order of the plan's tables): the boundary points' GridInfo (walk_boundary of
  // them), and every point's (s, t), the interior from index st_interior (the boundary count
  // rounded up to even), st_count entries in all.
  const GridInfo* grid_walk;
  const F2* grid_st;
  int walk_boundary, st_interior, st_count;
  const InlinePatch* patch_rec;  // P
  // Per group of 32 patches, list_stride entries (build_boundary_lists; shared-memory modes).
  // About 40% of a patch's boundary points write nothing (another patch owns them): without
  // the list, their threads idled beside the others.
  const uint16_t* boundary_list;
  int list_stride;
  float mrow[11][9];
};

// ---- inline_kernel.cu: the fused path.
// Static shared memory of k_inline for `terms` terms an axis in InlineMode `mode`.
size_t inline_static_shared(int terms, int mode);
// Resident blocks of that kernel an SM with `smem` bytes of dynamic shared memory, after
// opting in to `optin` bytes (a per-function setting: the real device's budget).
int inline_blocks_per_multiprocessor(int terms, int mode, size_t smem, size_t optin);
// One frame of k_inline: `grid` persistent blocks of 128 threads taking groups of 32 patches.
void launch_inline(int terms, int mode, int grid, size_t smem, const PlanView& pv, const FrameView& fv,
                   const InlineArgs& args, const InlineControls& params, long long render_shift, float* normals,
                   cudaStream_t stream);
// Positions of the sub-vertices in no patch (loose[0 .. count)), which k_inline does not write.
void launch_loose_vertices(int terms, const PlanView& pv, const FrameView& fv, const float* D, const int* loose,
                           int count, cudaStream_t stream);

// ---- reference_kernels.cu: the cuBLAS path's kernels (the SGEMMs are cuda_evaluator.cpp's).
// F and J of every sample into fv's sample buffers, and the sub-vertices' positions.
void launch_sample(int terms, const PlanView& pv, const FrameView& fv, const float* D, cudaStream_t stream);
// adjust_edge of every edge into fv.edge_control.
void launch_edges(const PlanView& pv, const FrameView& fv, cudaStream_t stream);
// X (K x 6P): the deformed samples and normals of every patch's columns.
void launch_gather(const PlanView& pv, const FrameView& fv, float* X, cudaStream_t stream);
// C (10 x 6P) from F = M X: exact corners, adjusted edges, the centre moved with them.
void launch_finish(const PlanView& pv, const FrameView& fv, const float* F, float* C, cudaStream_t stream);
// Q = B C to the welded positions and the render vertices' unit normals.
void launch_scatter(const PlanView& pv, const FrameView& fv, const float* Q, const float* C, const GridInfo* gi,
                    const uint8_t* owns, const PatchRender* render, long long render_shift, float* normals,
                    cudaStream_t stream);
// n floats of NaN from p on (tests: every output element must be written).
void launch_fill_nan(float* p, long long n, cudaStream_t stream);
// cudaFuncGetAttributes of one of this library's kernels: whether the device can run them.
cudaError_t kernel_image_status();

}  // namespace cuda_impl
}  // namespace sffd
