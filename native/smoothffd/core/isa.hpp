// Per-ISA copies of the CPU evaluator's per-frame code (runtime dispatch).
//
// The per-frame translation units (eval/cpu_sampling.cpp, cpu_fitting.cpp, cpu_tessellation.cpp,
// cpu_frame.cpp) are compiled twice: once with the baseline flags (x86-64-v2 by default) and
// once more with -march=x86-64-v3 -DSFFD_ISA_V3 (native/CMakeLists.txt, SMOOTHFFD_DISPATCH);
// CpuEvaluator picks one copy by CPUID (eval/cpu_frame.hpp). Both copies instantiate the same
// header inline functions and templates, and the linker keeps one definition of each
// (COMDAT): AVX2 code could then run on a CPU without it. So every function those units
// compile, their own and the inline ones of the headers they include (core/hd.hpp,
// lattice/tensor_eval.hpp, plan/bezier.hpp, eval/plan_view.hpp, eval/stages.hpp,
// eval/lanes.hpp), sits between SFFD_ISA_BEGIN and SFFD_ISA_END: in the v3 copy that is the
// inline namespace sffd::isa_v3, a name of its own; in the baseline build and in CUDA code
// the macros are empty (names and mangling unchanged). Plain data types (V3, Plan, PlanView,
// FrameView, SampleBatches, FitColumns, GridBasisLanes) stay outside, shared by both copies.
// No std:: (or other shared) function may be emitted out of line in the v3 copy: it would be a
// COMDAT shared with the baseline. So the threads stay in baseline code (CpuEvaluator) and the
// v3 functions read plain views, std::vector only through its trivially inlined accessors.
// scripts/check_isa.py checks the objects and the module: no function outside isa_v3 uses an
// instruction beyond x86-64-v2.
#pragma once

#if defined(SFFD_ISA_V3)
#define SFFD_ISA_BEGIN inline namespace isa_v3 {
#define SFFD_ISA_END }
#define SFFD_ISA_NAME "x86-64-v3"
// 1 in the translation unit that also compiles the ISA-independent parts (plan-time tables,
// dispatch): the baseline copy only.
#define SFFD_ISA_PRIMARY 0
#else
#define SFFD_ISA_BEGIN
#define SFFD_ISA_END
#define SFFD_ISA_PRIMARY 1
// The baseline copy's level, from the flags it is compiled with (x86-64-v2 for shipped
// builds; a -DSMOOTHFFD_ARCH=native build on an AVX-512 machine says x86-64-v4).
#if defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
#define SFFD_ISA_NAME "x86-64-v4"
#elif defined(__AVX2__) && defined(__FMA__) && defined(__BMI2__)
#define SFFD_ISA_NAME "x86-64-v3"
#elif defined(__SSE4_2__) && defined(__POPCNT__)
#define SFFD_ISA_NAME "x86-64-v2"
#elif defined(__x86_64__)
#define SFFD_ISA_NAME "x86-64"
#elif defined(__aarch64__)
// 64-bit Arm: Advanced SIMD (NEON) is part of every ARMv8-A CPU, so the baseline copy is the
// vector code (eval/lanes.hpp's vectors become NEON registers) and there is nothing to choose.
#define SFFD_ISA_NAME "armv8-a"
#else
#define SFFD_ISA_NAME "generic"
#endif
#endif
