#include "smoothffd/plan/centre_rows.hpp"

#include <algorithm>
#include <atomic>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/plan/bezier.hpp"

namespace sffd {

void build_centre_rows(Plan& plan, const LatticeSpec& lattice, const FitTables& fit,
                       const std::vector<double>& sample_exact) {
  std::vector<uint64_t>().swap(plan.centre_box);
  std::vector<long long>().swap(plan.centre_start);
  std::vector<float>().swap(plan.centre_row);
  std::vector<float>().swap(plan.centre_constant);
  if (lattice.components != 3) return;
  const int K = fit.columns;
  const long long P = (long long)(plan.patch_samples.size() / K);
  // m_k: the centre row of M_r less a quarter of the six edge rows (the fitted edge points the
  // adjustment replaces).
  std::vector<double> m(K);
  for (int k = 0; k < K; ++k) {
    double edge = 0;
    for (int e = 0; e < 3; ++e)
      for (int end = 0; end < 2; ++end) edge += fit.M_r[(size_t)edge_control_index(e, end) * K + k];
    m[k] = fit.M_r[(size_t)kCentre * K + k] - 0.25 * edge;
  }
  auto piece_of = [&](long long s, int a) -> const AxisPiece& {
    return lattice.axes[a].pieces()[(plan.sample_piece[s] >> (10 * a)) & 1023u];
  };
  // Pass 1: each patch's block, the control indices its samples' pieces weigh (a box, or a
  // few where the rest surface carries samples across a knot plane), and its row's offset.
  std::vector<int> lo(3 * (size_t)P), ext(3 * (size_t)P);
  std::atomic<bool> too_wide{false};
  parallel_for(P, default_threads(), [&](long long b, long long e) {
    for (long long p = b; p < e; ++p) {
      const int* ps = &plan.patch_samples[(size_t)p * K];
      for (int a = 0; a < 3; ++a) {
        int l = 1 << 30, h = -1;
        for (int k = 0; k < K; ++k) {
          const AxisPiece& pc = piece_of(ps[k], a);
          for (int q = 0; q < pc.count; ++q) l = std::min(l, pc.index[q]), h = std::max(h, pc.index[q]);
        }
        lo[3 * p + a] = l;
        ext[3 * p + a] = h - l + 1;
        if (h - l + 1 > kCentreMaxExtent || l > 0xffff) too_wide = true;
      }
    }
  });
  if (too_wide) return;  // not met by any lattice in practice; the fit's centre then
  plan.centre_box.resize(P);
  plan.centre_start.resize(P + 1);
  plan.centre_start[0] = 0;
  for (long long p = 0; p < P; ++p) {
    const long long block = (long long)ext[3 * p] * ext[3 * p + 1] * ext[3 * p + 2];
    plan.centre_start[p + 1] = plan.centre_start[p] + (block + 7) / 8 * 8;  // whole 8-float lanes
    uint64_t box = 0;
    for (int a = 0; a < 3; ++a)
      box |= (uint64_t)lo[3 * p + a] << (16 * a) | (uint64_t)ext[3 * p + a] << (48 + 5 * a);
    plan.centre_box[p] = box;
  }
  plan.centre_row.assign((size_t)plan.centre_start[P], 0.0f);
  plan.centre_constant.resize(3 * (size_t)P);
  // Pass 2: the rows, each sample weighed with its own pieces' polynomials (as the samplers
  // do), in double.
  parallel_for(P, default_threads(), [&](long long b, long long e) {
    std::vector<double> row;
    for (long long p = b; p < e; ++p) {
      const int* ps = &plan.patch_samples[(size_t)p * K];
      const int* L = &lo[3 * p];
      const int* X = &ext[3 * p];
      row.assign((size_t)X[0] * X[1] * X[2], 0.0);
      double c[3] = {0, 0, 0};
      for (int k = 0; k < K; ++k) {
        if (m[k] == 0) continue;
        const long long s = ps[k];
        const double* pos = &sample_exact[3 * s];
        double prm[3], wt[3][kCentreMaxExtent] = {};
        lattice.to_param(pos, prm);
        for (int a = 0; a < 3; ++a) {
          const int pi = (plan.sample_piece[s] >> (10 * a)) & 1023u;
          const AxisPiece& pc = lattice.axes[a].pieces()[pi];
          double w[kMaxTerms], dw[kMaxTerms];
          lattice.axes[a].weights(pi, prm[a], w, dw);
          for (int q = 0; q < pc.count; ++q)
            wt[a][pc.index[q] - L[a]] += w[q];  // clamped stencils repeat an index: their weights add
        }
        const double f = m[k] * plan.sample_weight[s];
        for (int i = 0; i < 3; ++i) c[i] += m[k] * pos[i];
        for (int u = 0; u < X[0]; ++u)
          for (int v = 0; v < X[1]; ++v) {
            const double fuv = f * wt[0][u] * wt[1][v];
            if (fuv == 0) continue;
            double* r = &row[(size_t)(u * X[1] + v) * X[2]];
            for (int w = 0; w < X[2]; ++w) r[w] += fuv * wt[2][w];
          }
      }
      for (int i = 0; i < 3; ++i) plan.centre_constant[3 * p + i] = (float)c[i];
      float* out = &plan.centre_row[(size_t)plan.centre_start[p]];
      for (size_t j = 0; j < row.size(); ++j) out[j] = (float)row[j];
    }
  });
}

}  // namespace sffd
