#include "smoothffd/eval/cpu_tessellation.hpp"

#include "smoothffd/eval/lanes.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {

#if SFFD_ISA_PRIMARY  // plan-time part: the baseline copy only
GridBasisLanes make_grid_basis_lanes(const Plan& plan) {
  GridBasisLanes gb;
  const int G = plan.grid;
  gb.padded = (G + kLanes - 1) / kLanes * kLanes;
  gb.basis.assign(10 * (size_t)gb.padded, 0.0f);
  for (int g = 0; g < G; ++g)
    for (int k = 0; k < 10; ++k) gb.basis[(size_t)k * gb.padded + g] = plan.grid_basis[10 * (size_t)g + k];
  return gb;
}

namespace {
// pairs (patch, grid point) per index i -> per patch (grid point, first + i).
OwnedPoints owned_by_patch(int patches, const int* owner, long long count, int first) {
  OwnedPoints o;
  o.start.assign((size_t)patches + 1, 0);
  for (long long i = 0; i < count; ++i) o.start[(size_t)owner[2 * i] + 1]++;
  for (int q = 0; q < patches; ++q) o.start[q + 1] += o.start[q];
  o.pairs.resize(2 * (size_t)count);
  std::vector<int> fill(o.start.begin(), o.start.end() - 1);
  for (long long i = 0; i < count; ++i) {
    const int k = fill[owner[2 * i]]++;
    o.pairs[2 * (size_t)k] = owner[2 * i + 1];
    o.pairs[2 * (size_t)k + 1] = (int)(first + i);
  }
  return o;
}
}  // namespace

OwnedPoints owned_output_vertices(const Plan& plan) {
  return owned_by_patch(plan.patches, plan.output_owner.data(),
                        (long long)plan.output_vertices - plan.sub_vertices, plan.sub_vertices);
}

OwnedPoints owned_render_vertices(const Plan& plan) {
  return owned_by_patch(plan.patches, plan.render_owner.data(), plan.render_vertices, 0);
}
#endif  // SFFD_ISA_PRIMARY

SFFD_ISA_BEGIN  // per-frame part: one copy per ISA (core/isa.hpp)

namespace {
// eval_cubic on lanes: the cubic patch cp (10 x 3 control points) at grid points g0.. g0 + kLanes.
void cubic_on_lanes(const float* cp, const GridBasisLanes& gb, int g0, Lanes x[3]) {
  x[0] = x[1] = x[2] = 0.0f;
  for (int k = 0; k < 10; ++k) {
    Lanes b;
    for (int l = 0; l < kLanes; ++l) b.set(l, gb.basis[(size_t)k * gb.padded + g0 + l]);
    for (int r = 0; r < 3; ++r) x[r] += b * cp[3 * k + r];
  }
}
}  // namespace

void patch_grid_points(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                       float* points) {
  const float* cp = fv.patch_control + 30 * (long long)p;
  const int P = gb.padded;
  for (int g0 = 0; g0 < pv.grid; g0 += kLanes) {
    Lanes x[3];
    cubic_on_lanes(cp, gb, g0, x);
    for (int r = 0; r < 3; ++r)
      for (int l = 0; l < kLanes; ++l) points[r * P + g0 + l] = x[r][l];
  }
}

void patch_grid_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                        float* normals) {
  const float* cp = fv.patch_normal + 30 * (long long)p;
  const int P = gb.padded;
  for (int g0 = 0; g0 < pv.grid; g0 += kLanes) {
    Lanes n[3];
    cubic_on_lanes(cp, gb, g0, n);
    Lanes l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    Lanes inv = Lanes(1.0f) / sqrt(l2);
    for (int l = 0; l < kLanes; ++l) {
      const int g = g0 + l;
      if (l2[l] > 1e-30f && l2[l] <= 3.0e38f) {
        for (int r = 0; r < 3; ++r) normals[r * P + g] = n[r][l] * inv[l];
      } else if (g < pv.grid) {  // unit_patch_normal's fallbacks
        V3 v = tessellate_normal(pv, fv, p, g);
        normals[g] = v.x;
        normals[P + g] = v.y;
        normals[2 * P + g] = v.z;
      }
    }
  }
}

SFFD_ISA_END

}  // namespace sffd
