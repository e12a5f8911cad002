/* Linked into the shipped libsmoothffd_cuda.so only (native/CMakeLists.txt,
 * SMOOTHFFD_CUDA_GLIBC), which is linked for an older glibc than the one its objects were
 * compiled against. GCC's C++ headers read glibc 2.32's __libc_single_threaded to let a
 * reference count skip its atomic operations while the process has one thread; this
 * library's own copy says "not single-threaded", so every count stays atomic: always correct,
 * whatever the process does. Hidden: it is the library's own. */
__attribute__((visibility("hidden"))) char __libc_single_threaded = 0;
