#include "smoothffd/eval/cpu_fitting.hpp"

#include "smoothffd/eval/lanes.hpp"
#include "smoothffd/eval/stages.hpp"

namespace sffd {

#if SFFD_ISA_PRIMARY  // plan-time part: the baseline copy only
FitColumns make_fit_columns(const Plan& plan) {
  FitColumns fc;
  const int K = plan.columns;
  fc.centre = K - 9;
  fc.padded = (fc.centre + kLanes - 1) / kLanes * kLanes;
  fc.bary.assign(3 * (size_t)fc.padded, 0.0f);
  fc.weight.assign(fc.padded, 0.0f);
  for (int k = 0; k < fc.padded; ++k) {
    for (int i = 0; i < 3; ++i)
      fc.bary[(size_t)i * fc.padded + k] = k < fc.centre ? plan.column_bary[3 * k + i] : (i == 0);
    if (k < fc.centre) fc.weight[k] = plan.fit_matrix[(size_t)kCentre * K + k];
  }
  fc.cbary.assign(3 * 16, 0.0f);
  fc.crows.assign(16 * 16, 0.0f);
  for (int c = 0; c < 16; ++c) {
    for (int i = 0; i < 3; ++i) fc.cbary[(size_t)i * 16 + c] = c < 9 ? plan.column_bary[3 * (fc.centre + c) + i] : (i == 0);
    if (c < 9)
      for (int r = 0; r < 10; ++r) fc.crows[16 * (size_t)c + r] = plan.fit_matrix[(size_t)r * K + fc.centre + c];
  }
  return fc;
}
#endif  // SFFD_ISA_PRIMARY

SFFD_ISA_BEGIN  // per-frame part: one copy per ISA (core/isa.hpp)

namespace {

// Plans up to this many samples gather their columns with int32 offsets (9 floats a sample).
constexpr int kGatherSamples = 0x7fffffff / 9;

// cofactor_apply (core/hd.hpp) on lanes: n' = n.x (J2 x J3) + n.y (J3 x J1) + n.z (J1 x J2),
// Jc the columns of the row-major J.
void cofactor_apply_lanes(const Lanes J[9], const Lanes n[3], Lanes out[3]) {
  const Lanes *c1[3] = {&J[0], &J[3], &J[6]}, *c2[3] = {&J[1], &J[4], &J[7]}, *c3[3] = {&J[2], &J[5], &J[8]};
  auto cross = [](const Lanes* const a[3], const Lanes* const b[3], int r) {
    int i = (r + 1) % 3, j = (r + 2) % 3;
    return *a[i] * *b[j] - *a[j] * *b[i];
  };
  for (int r = 0; r < 3; ++r) out[r] = n[0] * cross(c2, c3, r) + n[1] * cross(c3, c1, r) + n[2] * cross(c1, c2, r);
}

// Samples and deformed render normals of kLanes columns of one patch: the columns' sample
// indices s[l] (-1: padding, weight 0, finite values, identity Jacobian), their barycentric
// points b (3 x stride floats from bary + l). deformed_column_normal on lanes: the interpolated
// rest normal, its cofactor image, two normalizations; lanes outside normalized_or's plain
// range (a degenerate or huge cofactor) redo the shared scalar code, fallbacks included.
template <bool kNormals, bool kGeometry = true>
void columns_on_lanes(const PlanView& pv, const FrameView& fv, const int* s, const float* bary,
                      int stride, const int* column, const V3 rn[3], Lanes x[3], Lanes n[3]) {
  // Gathered (lanes.hpp) while the element offsets 9 s fit in int32; one load a lane beyond
  // (plans of over 238 M samples). The same floats either way.
  Lanes J[9];
  if (pv.samples <= kGatherSamples) {
    int o3[kLanes], o9[kLanes];
    for (int l = 0; l < kLanes; ++l) {
      o3[l] = s[l] >= 0 ? 3 * s[l] : -1;
      o9[l] = s[l] >= 0 ? 9 * s[l] : -1;
    }
    if (kGeometry)
      for (int r = 0; r < 3; ++r) x[r] = gather_lanes(fv.sample_value + r, o3, 0.0f);
    if (kNormals)
      for (int r = 0; r < 9; ++r) J[r] = gather_lanes(fv.sample_jacobian + r, o9, r % 4 == 0 ? 1.0f : 0.0f);
  } else {
    for (int l = 0; l < kLanes; ++l) {
      const long long q = s[l];
      if (kGeometry)
        for (int r = 0; r < 3; ++r) x[r].set(l, q >= 0 ? fv.sample_value[3 * q + r] : 0.0f);
      if (kNormals)
        for (int r = 0; r < 9; ++r) J[r].set(l, q >= 0 ? fv.sample_jacobian[9 * q + r] : r % 4 == 0 ? 1.0f : 0.0f);
    }
  }
  if (!kNormals) return;
  Lanes b[3], n0[3], c[3];
  for (int i = 0; i < 3; ++i) b[i] = load_lanes(bary + (size_t)i * stride);
  n0[0] = b[0] * rn[0].x + b[1] * rn[1].x + b[2] * rn[2].x;
  n0[1] = b[0] * rn[0].y + b[1] * rn[1].y + b[2] * rn[2].y;
  n0[2] = b[0] * rn[0].z + b[1] * rn[1].z + b[2] * rn[2].z;
  cofactor_apply_lanes(J, n0, c);
  Lanes l2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
  Lanes inv = Lanes(1.0f) / sqrt(l2);
  for (int r = 0; r < 3; ++r) n[r] = inv * c[r];
  Lanes l2b = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
  Lanes inv2 = Lanes(1.0f) / sqrt(l2b);
  for (int r = 0; r < 3; ++r) n[r] = inv2 * n[r];
  if (all_within(l2, 1e-30f, 3.0e38f) && all_within(l2b, 1e-30f, 3.0e38f)) return;
  for (int l = 0; l < kLanes; ++l) {
    if (s[l] < 0 || (l2[l] > 1e-30f && l2[l] <= 3.0e38f && l2b[l] > 1e-30f && l2b[l] <= 3.0e38f)) continue;
    V3 v = deformed_column_normal(pv, column[l], rn, fv.sample_jacobian + 9 * (long long)s[l]);
    n[0].set(l, v.x);
    n[1].set(l, v.y);
    n[2].set(l, v.z);
  }
}

template <bool kNormals, bool kGeometry = true>
void fit_patch_impl(const PlanView& pv, const FrameView& fv, const FitColumns& fc, int p,
                    float* out_g, float* out_n) {
  const int K = pv.columns;
  const int* ps = pv.patch_samples + (long long)p * K;
  V3 rn[3];
  for (int k = 0; k < 3; ++k) rn[k] = load3(pv.patch_render_normal + 9 * (long long)p + 3 * k);
  // The centre columns: the centre row's long sum.
  Lanes gc[3] = {0.0f, 0.0f, 0.0f}, nc[3] = {0.0f, 0.0f, 0.0f};
  int s[kLanes], column[kLanes];
  for (int k0 = 0; k0 < fc.padded; k0 += kLanes) {
    for (int l = 0; l < kLanes; ++l) {
      column[l] = k0 + l;
      s[l] = k0 + l < fc.centre ? ps[k0 + l] : -1;
    }
    Lanes x[3], n[3];
    columns_on_lanes<kNormals, kGeometry>(pv, fv, s, fc.bary.data() + k0, fc.padded, column, rn, x, n);
    const Lanes m = load_lanes(fc.weight.data() + k0);
    if (kGeometry)
      for (int r = 0; r < 3; ++r) gc[r] += m * x[r];
    if (kNormals)
      for (int r = 0; r < 3; ++r) nc[r] += m * n[r];
  }
  // The 9 constraint columns feed every row (as in fit_patch_into): rows on lanes.
  Lanes ag[3][2] = {}, an[3][2] = {};
  for (int c0 = 0; c0 < 16; c0 += kLanes) {
    for (int l = 0; l < kLanes; ++l) {
      column[l] = fc.centre + c0 + l;
      s[l] = c0 + l < 9 ? ps[fc.centre + c0 + l] : -1;
    }
    Lanes x[3], n[3];
    columns_on_lanes<kNormals, kGeometry>(pv, fv, s, fc.cbary.data() + c0, 16, column, rn, x, n);
    for (int l = 0; l < kLanes && c0 + l < 9; ++l) {
      const float* mt = fc.crows.data() + 16 * (c0 + l);
      const Lanes m[2] = {load_lanes(mt), load_lanes(mt + kLanes)};
      for (int h = 0; h < 2; ++h)
        for (int r = 0; r < 3; ++r) {
          if (kGeometry) ag[r][h] += m[h] * x[r][l];
          if (kNormals) an[r][h] += m[h] * n[r][l];
        }
    }
  }
  V3 g[10], nn[10];
  for (int r = 0; r < 10; ++r) {
    g[r] = v3(ag[0][r / kLanes][r % kLanes], ag[1][r / kLanes][r % kLanes], ag[2][r / kLanes][r % kLanes]);
    nn[r] = v3(an[0][r / kLanes][r % kLanes], an[1][r / kLanes][r % kLanes], an[2][r / kLanes][r % kLanes]);
  }
  g[kCentre] += v3(sum(gc[0]), sum(gc[1]), sum(gc[2]));
  nn[kCentre] += v3(sum(nc[0]), sum(nc[1]), sum(nc[2]));
  if (kGeometry) finish_patch(pv, fv, p, g);
  for (int r = 0; r < 10; ++r) {
    if (kGeometry) store3(out_g + 3 * r, g[r]);
    if (kNormals) store3(out_n + 3 * r, nn[r]);
  }
}

}  // namespace

void fit_patch_lanes(const PlanView& pv, const FrameView& fv, const FitColumns& fc, int p,
                     float* out_g, float* out_n) {
  if (!out_g)
    fit_patch_impl<true, false>(pv, fv, fc, p, nullptr, out_n);
  else if (out_n)
    fit_patch_impl<true>(pv, fv, fc, p, out_g, out_n);
  else
    fit_patch_impl<false>(pv, fv, fc, p, out_g, nullptr);
}

int centre_block(const PlanView& pv, const float* D, uint64_t box, float* block) {
  int lo[3], ext[3];
  unpack_centre_box(box, lo, ext);
  const int n = ext[0] * ext[1] * ext[2], S = (n + 7) / 8 * 8;
  int i = 0;
  for (int u = 0; u < ext[0]; ++u)
    for (int v = 0; v < ext[1]; ++v) {
      const float* d = D + 3 * (((long long)(lo[0] + u) * pv.dims[1] + lo[1] + v) * pv.dims[2] + lo[2]);
      for (int w = 0; w < ext[2]; ++w, ++i, d += 3) {
        block[i] = d[0];
        block[S + i] = d[1];
        block[2 * S + i] = d[2];
      }
    }
  for (; i < S; ++i) block[i] = block[S + i] = block[2 * S + i] = 0.0f;
  return S;
}

void geometry_patch_from_row(const PlanView& pv, const FrameView& fv, const float* block, int stride, int p,
                             float* out_g) {
  const float* row = pv.centre_row + pv.centre_start[p];
  Lanes x[3] = {0.0f, 0.0f, 0.0f};
  for (int i = 0; i < stride; i += kLanes) {
    const Lanes a = load_lanes(row + i);
    for (int r = 0; r < 3; ++r) x[r] += a * load_lanes(block + (size_t)r * stride + i);
  }
  const V3 value = load3(pv.centre_constant + 3 * (long long)p) + v3(sum(x[0]), sum(x[1]), sum(x[2]));
  V3 corner[3], cp[3][2], g[10];
  patch_boundary(pv, fv, p, corner, cp);
  patch_from_centre_row(corner, cp, value, g);
  for (int r = 0; r < 10; ++r) store3(out_g + 3 * r, g[r]);
}

SFFD_ISA_END

}  // namespace sffd
