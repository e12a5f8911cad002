// The per-frame loops of CpuEvaluator, one copy per ISA (runtime dispatch, core/isa.hpp).
//
// Each function runs one stage over the elements [b, e) of a parallel_for chunk; the threads
// stay in CpuEvaluator (baseline code), so these copies compile no std:: code. The baseline
// build defines the table cpu_frame_kernels_baseline (x86-64-v2 for shipped builds), the
// -DSFFD_ISA_V3 build of the same file cpu_frame_kernels_v3 (AVX2 + FMA); CpuEvaluator takes
// one by CPUID (cpu_isa()). Results of the two agree to float rounding (FMA contraction, the
// sums are the same otherwise); each is bitwise the same for every thread count.
#pragma once

#include <cstdint>
#include <vector>

#include "smoothffd/core/isa.hpp"
#include "smoothffd/eval/cpu_fitting.hpp"
#include "smoothffd/eval/cpu_sampling.hpp"
#include "smoothffd/eval/cpu_tessellation.hpp"
#include "smoothffd/eval/plan_view.hpp"

namespace sffd {

// The edge adjustment's deformed end normals (stages.hpp, deformed_end_normal), each computed
// once a frame: an edge end's normal depends only on its vertex's Jacobian and the rest
// adjustment normal of the patch corner there, and the patches around a smooth vertex share
// that normal, so about twelve edge ends (six edges, two sides) read each one.
struct EdgeEndNormals {
  std::vector<int> sample;   // the sub-vertex (= its sample) of each distinct end normal
  std::vector<float> rest;   // 3 per end normal: the rest adjustment normal
  std::vector<int> edge_end; // 4 per edge, as Plan::edge_slot (2 side + end): its end normal, -1 without side 1
  long long count() const { return (long long)sample.size(); }
};

EdgeEndNormals make_edge_end_normals(const Plan& plan);

struct CpuFrameKernels {
  const char* isa;  // "x86-64-v2", "x86-64-v3", ... (SFFD_ISA_NAME of the copy)
  // Sampling of batches [b, e): F into value; J into jacobian unless it is null, and then
  // only for the batches holding a sample numbered below jacobian_below (>= samples: all).
  void (*sample)(const PlanView& pv, const float* D, const SampleBatches& sb, long long b,
                 long long e, float* value, float* jacobian, int jacobian_below);
  // The deformed end normals [b, e) of en into normals (3 each), then the adjusted control
  // points of edges [b, e) into fv.edge_control from them: bitwise adjust_edge's (stages.hpp).
  void (*end_normals)(const FrameView& fv, const EdgeEndNormals& en, long long b, long long e, float* normals);
  void (*adjust_edges)(const PlanView& pv, const FrameView& fv, const EdgeEndNormals& en, const float* normals,
                       long long b, long long e);
  // Geometry patches into fv.patch_control, normal patches into fv.patch_normal, each unless
  // null.
  void (*fit_patches)(const PlanView& pv, const FrameView& fv, const FitColumns& fc, long long b,
                      long long e);
  // Plans with centre rows: the geometry patches of [b, e) from their centre rows
  // (geometry_patch_from_row) into fv.patch_control, no fitting; block: 3 x the largest row
  // of the plan (Plan::centre_start) floats.
  void (*row_patches)(const PlanView& pv, const FrameView& fv, const float* D, long long b, long long e,
                      float* block);
  // Positions of the output vertices patches [b, e) own (ov) into fv.positions; scratch:
  // 3 * gb.padded floats. The sub-vertices' positions are their samples (copied apart).
  void (*tessellate_positions)(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                               const OwnedPoints& ov, long long b, long long e, float* scratch);
  // Corner normals of patches [b, e) into fv.corner_normals; scratch: 3 * gb.padded floats.
  void (*tessellate_normals)(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                             long long b, long long e, float* scratch);
  // The compact layout's normals (evaluator.hpp) of patches [b, e): each patch's grid normals
  // written to the render vertices it owns (rv).
  void (*tessellate_render_normals)(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                                    const OwnedPoints& rv, long long b, long long e, float* scratch,
                                    float* render_normals);
};

// Data, not code: the tables hold the addresses of the per-ISA functions.
extern const CpuFrameKernels cpu_frame_kernels_baseline;
extern const CpuFrameKernels cpu_frame_kernels_v3;  // only with SFFD_HAVE_ISA_V3 (CMake)

}  // namespace sffd
