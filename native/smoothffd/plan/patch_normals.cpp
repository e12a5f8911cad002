#include "smoothffd/plan/patch_normals.hpp"

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/corner_normals.hpp"
#include "smoothffd/plan/rest_surface.hpp"

namespace sffd {

PatchNormals patch_corner_normals(const std::vector<double>& X, const InputSurface& in, const ClipResult& clip,
                                  const std::vector<double>& shade) {
  const int V = (int)(X.size() / 3), P = clip.patches();
  const std::vector<int>& tv = in.tv;
  const std::vector<double>& acn = in.adjust.corner;
  PatchNormals out{std::vector<double>(9 * (size_t)P), std::vector<double>(9 * (size_t)P)};
  // Each patch's own corners: in parallel, the same values.
  parallel_for(P, default_threads(), [&](long long pb, long long pe) {
    for (long long p = pb; p < pe; ++p) {
      int t = clip.patch_tri[p];
      double Pt[9], Nt[9], At[9];
      for (int k = 0; k < 3; ++k)
        for (int i = 0; i < 3; ++i) {
          Pt[3 * k + i] = X[3 * (size_t)tv[3 * t + k] + i];
          Nt[3 * k + i] = shade[9 * (size_t)t + 3 * k + i];
          At[3 * k + i] = acn[9 * (size_t)t + 3 * k + i];
        }
      for (int c = 0; c < 3; ++c) {
        const double* b = &clip.patch_bary[9 * (size_t)p + 3 * c];
        double rn[3], an[3];
        for (int i = 0; i < 3; ++i) rn[i] = b[0] * Nt[i] + b[1] * Nt[3 + i] + b[2] * Nt[6 + i];
        normalize_or(rn, Nt);
        const int v = clip.patch_vertex[3 * p + c];
        if (v < V) {
          const int k = slot_of(tv, t, v);
          for (int i = 0; i < 3; ++i) an[i] = At[3 * k + i];
        } else {
          pn_quadratic_normal(Pt, At, b, an);
        }
        for (int i = 0; i < 3; ++i) {
          out.render[9 * (size_t)p + 3 * c + i] = rn[i];
          out.adjust[9 * (size_t)p + 3 * c + i] = an[i];
        }
      }
    }
  });
  return out;
}

std::vector<uint8_t> bound_patch_normals(Plan& plan, PatchNormals normals, const EdgeTable& sub,
                                         const std::vector<double>& position, const ClipResult& clip,
                                         const std::vector<uint8_t>& tri_flat, double cos_tol) {
  const int P = clip.patches();
  const std::vector<int>& pv = clip.patch_vertex;
  std::vector<double>& render = normals.render;
  std::vector<uint8_t> sharp;
  std::vector<uint8_t> sub_flat(P), check(P), turned(3 * (size_t)P, 0);
  std::vector<int> pieces(tri_flat.size(), 0);
  for (int p = 0; p < P; ++p) pieces[clip.patch_tri[p]]++;
  for (int p = 0; p < P; ++p) {
    sub_flat[p] = tri_flat[clip.patch_tri[p]];
    check[p] = pieces[clip.patch_tri[p]] > 1;
  }
  AdjustNormals sub_adjust(position, pv, normals.adjust, sub_flat);
  RestSurface sub_rest;
  for (int round = 0;; ++round) {
    sharp = classify_sharp_ends(sub, pv, render, cos_tol);
    plan.bounded_sub_vertices =
        bound_adjust_normals(position, pv, sub, sharp, render, sub_adjust, sub_rest, nullptr, nullptr, &check);
    if (round == 7 || !bound_render_normals(sub_adjust, render, &turned)) break;
    check.assign(P, 1);
  }
  plan.turned_sub_normals = 0;
  for (uint8_t f : turned) plan.turned_sub_normals += f;
  plan.patch_adjust_normal.resize(9 * (size_t)P);
  plan.patch_render_normal.resize(9 * (size_t)P);
  parallel_for((long long)plan.patch_adjust_normal.size(), default_threads(), [&](long long b, long long e) {
    for (long long i = b; i < e; ++i) {
      plan.patch_adjust_normal[i] = (float)sub_adjust.corner[i];
      plan.patch_render_normal[i] = (float)render[i];
    }
  });
  return sharp;
}

}  // namespace sffd
