/* The C boundary between the Python module (_core, no CUDA library needed) and the CUDA
 * backend, libsmoothffd_cuda.so (CUDA runtime linked statically, libstdc++ too, Python-free:
 * one build serves every CPython wheel). The surface of the CUDA backend is declared here and
 * nowhere else: the library fills this table of C function pointers (cuda_api.cpp, over its
 * implementation in cuda_evaluator.hpp), and _core's one C++ proxy, sffd::CudaEvaluator
 * (cuda_proxy/cuda_proxy.hpp), calls it. _core dlopens the library next to its own file when
 * the CUDA backend is first asked for and calls sffd_cuda_api_v1(), the library's only
 * exported symbol, for the table.
 *
 * Rules of the boundary:
 *  - nothing is thrown across it: every call that can fail returns an sffd_cuda_code and fills
 *    the caller's sffd_cuda_error (the library catches everything inside);
 *  - no std:: type crosses it, except that the library reads the caller's `const sffd::Plan*`
 *    (a plain struct of std::vectors, whose layout is the same for every GCC since 5). The
 *    table's abi_version, plan_size (sizeof(sffd::Plan)) and plan_tail (offsetof its last
 *    member) are checked at load; a library built from other sources is refused;
 *  - the library keeps no pointer into caller memory beyond a call, except the plan, which the
 *    caller keeps alive as long as the evaluator made from it.
 * Bump SFFD_CUDA_ABI_VERSION on any change to this file or to sffd::Plan. */
#ifndef SMOOTHFFD_CUDA_API_H
#define SMOOTHFFD_CUDA_API_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SFFD_CUDA_ABI_VERSION 7
#define SFFD_CUDA_ENTRY "sffd_cuda_api_v1"

/* What a failed call raises on the C++ side (cuda_proxy.cpp). */
enum sffd_cuda_code {
  SFFD_CUDA_OK = 0,
  SFFD_CUDA_ERROR = 1,            /* sffd::CudaError (RuntimeError): CUDA / cuBLAS / driver error */
  SFFD_CUDA_OUT_OF_MEMORY = 2,    /* sffd::CudaOutOfMemory (MemoryError) */
  SFFD_CUDA_INVALID_ARGUMENT = 3, /* std::invalid_argument (ValueError) */
  SFFD_CUDA_INTERNAL = 4          /* std::logic_error (RuntimeError): unexpected plan tables etc. */
};

typedef struct sffd_cuda_error {
  int code;
  char message[2048];
} sffd_cuda_error;

/* StageTimes: (name, ms) pairs in order. */
#define SFFD_CUDA_MAX_STAGES 40
typedef struct sffd_cuda_times {
  int count;
  char name[SFFD_CUDA_MAX_STAGES][48];
  double ms[SFFD_CUDA_MAX_STAGES];
} sffd_cuda_times;

/* The shared-memory limits an evaluator plans its launches with (the device's own, or the
 * emulated smaller device's), and what they gave the inline kernel. */
typedef struct sffd_cuda_limits {
  int64_t per_block;          /* cudaDevAttrMaxSharedMemoryPerBlockOptin (or the emulated limit) */
  int64_t per_multiprocessor; /* cudaDevAttrMaxSharedMemoryPerMultiprocessor (or emulated) */
  int64_t reserved_per_block; /* cudaDevAttrReservedSharedMemoryPerBlock */
  int64_t inline_static;      /* static shared memory of the inline kernel chosen for the plan */
  int64_t inline_dynamic_max; /* largest dynamic table the inline kernel may use */
  int64_t inline_dynamic;     /* what this plan's table needs (0 when the inline kernel is not used) */
  int32_t inline_blocks_per_multiprocessor; /* resident blocks of the inline kernel (0 before its first launch) */
  int32_t multiprocessors;
  int32_t registers_per_multiprocessor;
  int32_t compute_capability; /* 10 major + minor */
} sffd_cuda_limits;

typedef struct sffd_cuda_evaluator sffd_cuda_evaluator; /* opaque */

typedef struct sffd_cuda_api {
  uint32_t abi_version;  /* SFFD_CUDA_ABI_VERSION */
  uint32_t api_size;     /* sizeof(sffd_cuda_api) */
  uint64_t plan_size;    /* sizeof(sffd::Plan) in the library */
  uint64_t plan_tail;    /* offsetof(sffd::Plan, build_ms) in the library */
  const char* build_info; /* CUDA runtime version and the architectures built, for messages */

  /* 1 when a CUDA device can run the evaluator, else 0; message: which device, or precisely why
   * not (no driver, driver too old, no device, no kernel image for its architecture, ...). */
  int (*cuda_status)(char* message, size_t message_size);

  /* plan: const sffd::Plan*. path: "fused", "cublas" or "" (fused).
   * shared_memory_limit: 0 (the device's own limits) or the bytes of shared memory a block
   * may opt in to on the device to emulate (at least 48 KiB; a multiprocessor then has that
   * plus the reserved 1 KiB). */
  int (*evaluator_create)(const void* plan, const char* path, int64_t shared_memory_limit,
                          sffd_cuda_evaluator** out, sffd_cuda_error* err);
  void (*evaluator_destroy)(sffd_cuda_evaluator* ev);
  /* corner_normals may be null: positions only. */
  int (*evaluate)(sffd_cuda_evaluator* ev, const float* D, float* positions, float* corner_normals,
                  sffd_cuda_times* times, sffd_cuda_error* err);
  int (*evaluate_device)(sffd_cuda_evaluator* ev, const float* D, sffd_cuda_times* times, sffd_cuda_error* err);
  /* Static strings. */
  const char* (*path)(const sffd_cuda_evaluator* ev);
  /* What runs a frame: "inline (boxes)", "inline (weights)", "inline (global)" or "cublas". */
  const char* (*kernel)(const sffd_cuda_evaluator* ev);
  uint64_t (*output_bytes)(const sffd_cuda_evaluator* ev);
  uint64_t (*device_bytes)(const sffd_cuda_evaluator* ev);
  void (*limits)(const sffd_cuda_evaluator* ev, sffd_cuda_limits* out);
  /* The compact layout: positions N x 3, render-vertex normals R x 3 (null: positions only). */
  int (*evaluate_compact)(sffd_cuda_evaluator* ev, const float* D, float* positions, float* render_normals,
                          sffd_cuda_times* times, sffd_cuda_error* err);
  /* Page-locked host memory (cudaHostAlloc / cudaFreeHost) for output arrays: the device copies
   * into it at the bus's full speed. host_free takes what host_alloc returned. */
  int (*host_alloc)(uint64_t bytes, void** out, sffd_cuda_error* err);
  void (*host_free)(void* ptr);

  /* Adaptive tessellation (eval/adaptive.hpp) on the device: one frame from the control values
   * D (host) to within `tolerance` of the patches, at most max_level segments an edge;
   * min_edge_segments (E) and min_patch_level (P) hold counts (both null: none); corner_uv the
   * input's C x 2 UVs or null; with_normals: also per-corner normals. Writes the output's
   * vertex and triangle counts, the largest bound and the count of edges and patches held at
   * max_level above the tolerance; adaptive_copy then copies the arrays (any null: skipped):
   * positions and rest_positions N x 3, triangles T x 3, face_index and triangle_patch T,
   * corner_normals T x 3 x 3, uvs T x 3 x 2, edge_segments E, patch_level P. */
  int (*adaptive_frame)(sffd_cuda_evaluator* ev, const float* D, double tolerance, int max_level,
                        const int* min_edge_segments, const int* min_patch_level, const float* corner_uv,
                        int with_normals, int64_t* vertices, int64_t* triangles, double* max_bound,
                        int64_t* capped, sffd_cuda_times* times, sffd_cuda_error* err);
  int (*adaptive_copy)(sffd_cuda_evaluator* ev, float* positions, float* rest_positions, int* triangles,
                       int* face_index, int* triangle_patch, float* corner_normals, float* uvs,
                       int* edge_segments, int* patch_level, sffd_cuda_error* err);

  /* Testing (smoothffd._core._testing, not for users): fills the evaluator's device outputs
   * and intermediates with NaN, so that a test sees every element a frame must write. */
  int (*testing_poison)(sffd_cuda_evaluator* ev, sffd_cuda_error* err);
} sffd_cuda_api;

typedef const sffd_cuda_api* (*sffd_cuda_entry_fn)(void);

#ifdef __cplusplus
}
#endif

#endif /* SMOOTHFFD_CUDA_API_H */
