// Host/device helpers shared by the CPU and CUDA evaluators.
//
// Every per-element stage of the per-frame pipeline (sampling, fitting, adjustment,
// tessellation) is written once as an SFFD_HD inline function over plain pointers, so the
// CPU evaluator and the CUDA kernels run the very same arithmetic (and agree to float
// precision) instead of keeping two copies of the math.
#pragma once

#include <cmath>

#include "smoothffd/core/isa.hpp"

#if defined(__CUDACC__)
#define SFFD_HD __host__ __device__ __forceinline__
#define SFFD_UNROLL _Pragma("unroll")
#else
#define SFFD_HD inline
#define SFFD_UNROLL _Pragma("GCC unroll 16")
#endif

namespace sffd {

struct V3 {
  float x, y, z;
};

SFFD_ISA_BEGIN

SFFD_HD V3 v3(float x, float y, float z) { return V3{x, y, z}; }
SFFD_HD V3 load3(const float* p) { return V3{p[0], p[1], p[2]}; }
SFFD_HD void store3(float* p, V3 v) { p[0] = v.x; p[1] = v.y; p[2] = v.z; }
SFFD_HD V3 operator+(V3 a, V3 b) { return V3{a.x + b.x, a.y + b.y, a.z + b.z}; }
SFFD_HD V3 operator-(V3 a, V3 b) { return V3{a.x - b.x, a.y - b.y, a.z - b.z}; }
SFFD_HD V3 operator*(float s, V3 a) { return V3{s * a.x, s * a.y, s * a.z}; }
SFFD_HD V3& operator+=(V3& a, V3 b) { a.x += b.x; a.y += b.y; a.z += b.z; return a; }
SFFD_HD float dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
SFFD_HD V3 cross(V3 a, V3 b) {
  return V3{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
SFFD_HD float length(V3 a) { return sqrtf(dot(a, a)); }

// Unit vector, or `fallback` when `a` is too short to have a direction.
SFFD_HD V3 normalized_or(V3 a, V3 fallback) {
  float l2 = dot(a, a);
  if (!(l2 > 1e-30f)) return fallback;
  // Robustness: |a| above ~1.8e19 overflows l2 to inf, and 0 * inf would make the result
  // NaN (a lattice scaled by 1e20 would give NaN positions). Rescale finite vectors first; a vector
  // with an inf or NaN component has no direction: fallback.
  if (!(l2 <= 3.0e38f)) {
    float m = fmaxf(fabsf(a.x), fmaxf(fabsf(a.y), fabsf(a.z)));
    if (!(m <= 3.0e38f)) return fallback;
    a = (1.0f / m) * a;
    l2 = dot(a, a);
  }
  return (1.0f / sqrtf(l2)) * a;
}

// Normals transform by the cofactor of the Jacobian (Barr 1984; paper Eq. 3):
// n' ~ cof(J) n, with cof(J) columns (J2 x J3, J3 x J1, J1 x J2) for columns J1..J3.
// `J` is row-major: J[3*r + c] = dF_r / dp_c. No division, and orientation is kept when
// det(J) < 0.
SFFD_HD V3 cofactor_apply(const float* J, V3 n) {
  V3 c1{J[0], J[3], J[6]}, c2{J[1], J[4], J[7]}, c3{J[2], J[5], J[8]};
  return n.x * cross(c2, c3) + n.y * cross(c3, c1) + n.z * cross(c1, c2);
}

SFFD_ISA_END

}  // namespace sffd
