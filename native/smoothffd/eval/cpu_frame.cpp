// The per-frame loops of CpuEvaluator (eval/cpu_frame.hpp), compiled once per ISA.
#include "smoothffd/eval/cpu_frame.hpp"

#include <cstring>

#include "smoothffd/eval/stages.hpp"

namespace sffd {

#if SFFD_ISA_PRIMARY  // plan-time part: the baseline copy only
EdgeEndNormals make_edge_end_normals(const Plan& plan) {
  // Per sub-vertex, the distinct rest normals (bitwise) of the edge ends at it: equal inputs
  // give the same deformed normal, so each is computed once.
  EdgeEndNormals en;
  const int E = plan.edges;
  en.edge_end.assign(4 * (size_t)E, -1);
  std::vector<int> first(plan.sub_vertices, -1), next;  // per vertex: a list of its end normals
  for (int e = 0; e < E; ++e)
    for (int side = 0; side < 2; ++side) {
      const int p = plan.edge_patch[2 * e + side];
      if (p < 0) continue;
      for (int end = 0; end < 2; ++end) {
        const int v = plan.edge_vertex[2 * e + end];
        const float* m = &plan.patch_adjust_normal[9 * (size_t)p + 3 * plan.edge_slot[4 * (size_t)e + 2 * side + end]];
        int id = first[v];
        while (id >= 0 && std::memcmp(&en.rest[3 * (size_t)id], m, 3 * sizeof(float)) != 0) id = next[id];
        if (id < 0) {
          id = (int)en.sample.size();
          en.sample.push_back(v);
          en.rest.insert(en.rest.end(), m, m + 3);
          next.push_back(first[v]);
          first[v] = id;
        }
        en.edge_end[4 * (size_t)e + 2 * side + end] = id;
      }
    }
  return en;
}
#endif  // SFFD_ISA_PRIMARY

SFFD_ISA_BEGIN

namespace {

void sample_range(const PlanView& pv, const float* D, const SampleBatches& sb, long long b,
                  long long e, float* value, float* jacobian, int jacobian_below) {
  const int* order = sb.order.data();
  const int* start = sb.start.data();
  const bool every = jacobian_below >= pv.samples;
  for (long long i = b; i < e; ++i) {
    bool with_jacobian = jacobian && every;
    if (jacobian && !every)
      for (int k = start[i]; k < start[i] + sb.size[i]; ++k) with_jacobian |= order[k] < jacobian_below;
    sample_batch(pv, D, sb, i, value, with_jacobian ? jacobian : nullptr);
  }
}

void end_normals(const FrameView& fv, const EdgeEndNormals& en, long long b, long long e, float* normals) {
  const int* sample = en.sample.data();
  const float* rest = en.rest.data();
  for (long long i = b; i < e; ++i)
    store3(normals + 3 * i, deformed_end_normal(fv.sample_jacobian + 9 * (long long)sample[i], load3(rest + 3 * i)));
}

// adjust_edge (stages.hpp) with the end normals read from normals (end_normals).
void adjust_edges(const PlanView& pv, const FrameView& fv, const EdgeEndNormals& en, const float* normals,
                  long long b, long long e) {
  for (long long i = b; i < e; ++i) {
    const int* ids = en.edge_end.data() + 4 * i;
    adjust_edge_with(pv, fv, (int)i, [&](int end, int side) { return load3(normals + 3 * (long long)ids[2 * side + end]); });
  }
}

void fit_patches(const PlanView& pv, const FrameView& fv, const FitColumns& fc, long long b,
                 long long e) {
  for (long long p = b; p < e; ++p)
    fit_patch_lanes(pv, fv, fc, (int)p, fv.patch_control ? fv.patch_control + 30 * p : nullptr,
                    fv.patch_normal ? fv.patch_normal + 30 * p : nullptr);
}

void row_patches(const PlanView& pv, const FrameView& fv, const float* D, long long b, long long e,
                 float* block) {
  uint64_t box = 0;
  int stride = 0;
  for (long long p = b; p < e; ++p) {
    if (p == b || pv.centre_box[p] != box) stride = centre_block(pv, D, box = pv.centre_box[p], block);
    geometry_patch_from_row(pv, fv, block, stride, (int)p, fv.patch_control + 30 * p);
  }
}

// For each patch of [b, e) that owns points: its grid values (grid(p, scratch): padded x 3,
// SoA) written to out at the indices it owns.
template <class Grid>
void write_owned(const OwnedPoints& owned, int padded, long long b, long long e, float* scratch,
                 float* out, Grid grid) {
  const int* start = owned.start.data();
  const int* pairs = owned.pairs.data();
  for (long long p = b; p < e; ++p) {
    if (start[p] == start[p + 1]) continue;
    grid((int)p, scratch);
    for (int i = start[p]; i < start[p + 1]; ++i) {
      const int g = pairs[2 * i];
      float* o = out + 3 * (size_t)pairs[2 * i + 1];
      o[0] = scratch[g];
      o[1] = scratch[padded + g];
      o[2] = scratch[2 * padded + g];
    }
  }
}

void tessellate_positions(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                          const OwnedPoints& ov, long long b, long long e, float* points) {
  write_owned(ov, gb.padded, b, e, points, fv.positions,
              [&](int p, float* s) { patch_grid_points(pv, fv, gb, p, s); });
}

void tessellate_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                        long long b, long long e, float* normals) {
  const int LL = pv.level * pv.level;
  const int P = gb.padded;
  for (long long p = b; p < e; ++p) {
    patch_grid_normals(pv, fv, gb, (int)p, normals);
    float* out = fv.corner_normals + 9 * p * LL;
    for (int i = 0; i < 3 * LL; ++i) {
      const int g = pv.local_triangles[i];
      out[3 * i] = normals[g];
      out[3 * i + 1] = normals[P + g];
      out[3 * i + 2] = normals[2 * P + g];
    }
  }
}

void tessellate_render_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb,
                               const OwnedPoints& rv, long long b, long long e, float* normals,
                               float* render_normals) {
  write_owned(rv, gb.padded, b, e, normals, render_normals,
              [&](int p, float* s) { patch_grid_normals(pv, fv, gb, p, s); });
}

}  // namespace

SFFD_ISA_END

#if defined(SFFD_ISA_V3)
extern const CpuFrameKernels cpu_frame_kernels_v3 = {
#else
extern const CpuFrameKernels cpu_frame_kernels_baseline = {
#endif
    SFFD_ISA_NAME,        sample_range,         end_normals, adjust_edges, fit_patches, row_patches,
    tessellate_positions, tessellate_normals,   tessellate_render_normals};

}  // namespace sffd
