#include "smoothffd/eval/fit_error.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <vector>

#include <Eigen/Dense>

#include "smoothffd/core/parallel.hpp"
#include "smoothffd/eval/plan_view.hpp"
#include "smoothffd/eval/stages.hpp"
#include "smoothffd/plan/fit_error.hpp"

namespace sffd {

namespace {

// Q in float for fitting degree n, built once per degree and kept (a few tens of KB each).
const Eigen::MatrixXf& error_matrix(int n) {
  static std::mutex mutex;
  static std::map<int, Eigen::MatrixXf> cache;
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(n);
  if (it == cache.end()) {
    const FitErrorTable t = build_fit_error_table(build_fit_tables(n));
    Eigen::MatrixXf Q(t.rows, t.columns);
    for (int m = 0; m < t.rows; ++m)
      for (int k = 0; k < t.columns; ++k) Q(m, k) = (float)t.Q[(size_t)m * t.columns + k];
    it = cache.emplace(n, std::move(Q)).first;
  }
  return it->second;
}

}  // namespace

void estimate_fit_errors(const Plan& plan, const float* D, int threads, float* geometry, float* normal_degrees) {
  if (threads <= 0) threads = default_threads();
  const PlanView pv = host_view(plan);
  const int S = plan.samples, P = plan.patches, K = plan.columns;
  std::vector<float> value(3 * (size_t)S), jacobian(9 * (size_t)S);
  parallel_for(S, threads, [&](long long b, long long e) {
    for (long long s = b; s < e; ++s) sample_point(pv, D, (int)s, &value[3 * s], &jacobian[9 * s]);
  });
  const Eigen::MatrixXf& Q = error_matrix(plan.fit_degree);
  const int N = (int)Q.rows();
  constexpr int kBlock = 64;  // patches a product
  parallel_for((P + kBlock - 1) / kBlock, threads, [&](long long b, long long e) {
    Eigen::MatrixXf X(K, 6 * kBlock), E(N, 6 * kBlock);
    for (long long blk = b; blk < e; ++blk) {
      const int p0 = (int)blk * kBlock, count = std::min(kBlock, P - p0);
      X.setZero();
      for (int i = 0; i < count; ++i) {
        const int p = p0 + i;
        V3 rn[3];
        for (int c = 0; c < 3; ++c) rn[c] = load3(pv.patch_render_normal + 9 * (long long)p + 3 * c);
        // Positions relative to the patch's first corner: Q's rows sum to zero (a constant is
        // reproduced exactly), so this changes nothing but the rounding of far-off patches.
        const V3 origin = load3(&value[3 * (size_t)pv.patch_vertex[3 * p]]);
        for (int k = 0; k < K; ++k) {
          const int s = pv.patch_samples[(long long)p * K + k];
          const V3 x = load3(&value[3 * (size_t)s]) - origin;
          const V3 n = deformed_column_normal(pv, k, rn, &jacobian[9 * (size_t)s]);
          X(k, 6 * i + 0) = x.x; X(k, 6 * i + 1) = x.y; X(k, 6 * i + 2) = x.z;
          X(k, 6 * i + 3) = n.x; X(k, 6 * i + 4) = n.y; X(k, 6 * i + 5) = n.z;
        }
      }
      E.noalias() = Q * X;
      for (int i = 0; i < count; ++i) {
        float g = 0.0f, nrm = 0.0f;
        for (int m = 0; m < N; ++m) {
          g = std::max(g, E.block<1, 3>(m, 6 * i).squaredNorm());
          nrm = std::max(nrm, E.block<1, 3>(m, 6 * i + 3).squaredNorm());
        }
        geometry[p0 + i] = std::sqrt(g);
        normal_degrees[p0 + i] = (float)(std::asin(std::min(1.0, std::sqrt((double)nrm))) * 57.29577951308232);
      }
    }
  });
}

}  // namespace sffd
