// Lanes: kLanes floats computed together (one AVX register with -march=x86-64-v3 or newer, two
// SSE registers without). Arithmetic is element-wise, a float operand is broadcast, so the
// scalar templates of the stages (tensor_eval_fixed, compose_deformation, sample_weights) run
// unchanged on kLanes samples at once: `T x = 0.0f`, `x * w + (T)d` all mean what they mean for
// float. Host only (the CUDA evaluator gets its parallelism from threads).
#pragma once

#include <cmath>
#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "smoothffd/core/isa.hpp"

namespace sffd {

constexpr int kLanes = 8;

SFFD_ISA_BEGIN

// Without AVX a 32-byte vector argument is passed in memory, with AVX in a register, and the
// compilers warn that the ABI differs (-Wpsabi). No call crosses: each copy of Lanes lives in
// its own ISA namespace (core/isa.hpp), and every use is inlined.
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
#endif

#if defined(__GNUC__) || defined(__clang__)
struct Lanes {
  typedef float V __attribute__((vector_size(4 * kLanes)));
  V v;
  Lanes() = default;
  Lanes(float x) : v(V{} + x) {}  // NOLINT: implicit broadcast, as for a float operand
  explicit Lanes(V x) : v(x) {}
  float operator[](int i) const { return v[i]; }
  void set(int i, float x) { v[i] = x; }
  friend Lanes operator+(Lanes a, Lanes b) { return Lanes(a.v + b.v); }
  friend Lanes operator-(Lanes a, Lanes b) { return Lanes(a.v - b.v); }
  friend Lanes operator*(Lanes a, Lanes b) { return Lanes(a.v * b.v); }
  friend Lanes operator/(Lanes a, Lanes b) { return Lanes(a.v / b.v); }
  Lanes& operator+=(Lanes b) { v += b.v; return *this; }
};
#else
// Portable fallback: the same operations as plain loops (compilers vectorize most of them).
struct Lanes {
  float v[kLanes];
  Lanes() = default;
  Lanes(float x) { for (int i = 0; i < kLanes; ++i) v[i] = x; }  // NOLINT
  float operator[](int i) const { return v[i]; }
  void set(int i, float x) { v[i] = x; }
  friend Lanes operator+(Lanes a, Lanes b) { for (int i = 0; i < kLanes; ++i) a.v[i] += b.v[i]; return a; }
  friend Lanes operator-(Lanes a, Lanes b) { for (int i = 0; i < kLanes; ++i) a.v[i] -= b.v[i]; return a; }
  friend Lanes operator*(Lanes a, Lanes b) { for (int i = 0; i < kLanes; ++i) a.v[i] *= b.v[i]; return a; }
  friend Lanes operator/(Lanes a, Lanes b) { for (int i = 0; i < kLanes; ++i) a.v[i] /= b.v[i]; return a; }
  Lanes& operator+=(Lanes b) { for (int i = 0; i < kLanes; ++i) v[i] += b.v[i]; return *this; }
};
#endif

// Element-wise square root (correctly rounded, as sqrtf).
inline Lanes sqrt(Lanes a) {
#if defined(__AVX__) && (defined(__GNUC__) || defined(__clang__))
  static_assert(kLanes == 8, "one AVX register");
  return Lanes((Lanes::V)_mm256_sqrt_ps((__m256)a.v));
#else
  for (int i = 0; i < kLanes; ++i) a.set(i, std::sqrt(a[i]));
  return a;
#endif
}

// kLanes consecutive floats from p (no alignment needed).
inline Lanes load_lanes(const float* p) {
  Lanes a;
  for (int i = 0; i < kLanes; ++i) a.set(i, p[i]);  // one unaligned vector load
  return a;
}

// Lane l = base[idx[l]] where idx[l] >= 0, else `fill`: the values of kLanes scattered
// samples, assembled in registers (a lane-by-lane store and one vector load stalls on store
// forwarding; AVX2's gather was slower still on the development machine's AMD EPYC).
inline Lanes gather_lanes(const float* base, const int* idx, float fill) {
  float x[kLanes];
  for (int i = 0; i < kLanes; ++i) x[i] = idx[i] >= 0 ? base[idx[i]] : fill;
#if defined(__AVX__) && (defined(__GNUC__) || defined(__clang__))
  static_assert(kLanes == 8, "one AVX register");
  return Lanes((Lanes::V)_mm256_setr_ps(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7]));
#else
  Lanes a;
  for (int i = 0; i < kLanes; ++i) a.set(i, x[i]);
  return a;
#endif
}

// Whether lo < a <= hi in every lane (NaN in none).
inline bool all_within(Lanes a, float lo, float hi) {
#if defined(__AVX__) && (defined(__GNUC__) || defined(__clang__))
  const __m256 v = (__m256)a.v;
  const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(v, _mm256_set1_ps(lo), _CMP_GT_OQ),
                                  _mm256_cmp_ps(v, _mm256_set1_ps(hi), _CMP_LE_OQ));
  return _mm256_movemask_ps(ok) == 0xff;
#else
  for (int i = 0; i < kLanes; ++i)
    if (!(a[i] > lo && a[i] <= hi)) return false;
  return true;
#endif
}

// Sum of the lanes, in lane order.
inline float sum(Lanes a) {
  float s = a[0];
  for (int i = 1; i < kLanes; ++i) s += a[i];
  return s;
}

#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic pop
#endif

SFFD_ISA_END

}  // namespace sffd
