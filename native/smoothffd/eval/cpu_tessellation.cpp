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
#endif  // SFFD_ISA_PRIMARY

SFFD_ISA_BEGIN  // per-frame part: one copy per ISA (core/isa.hpp)

void patch_grid_normals(const PlanView& pv, const FrameView& fv, const GridBasisLanes& gb, int p,
                        float* normals) {
  const float* cp = fv.patch_normal + 30 * (long long)p;
  const int P = gb.padded;
  for (int g0 = 0; g0 < pv.grid; g0 += kLanes) {
    Lanes n[3] = {0.0f, 0.0f, 0.0f};
    for (int k = 0; k < 10; ++k) {  // eval_cubic on lanes
      Lanes b;
      for (int l = 0; l < kLanes; ++l) b.set(l, gb.basis[(size_t)k * P + g0 + l]);
      for (int r = 0; r < 3; ++r) n[r] += b * cp[3 * k + r];
    }
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
