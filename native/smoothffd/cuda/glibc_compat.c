/* Linked into the shipped libsmoothffd_cuda.so only (native/CMakeLists.txt,
 * SMOOTHFFD_CUDA_GLIBC), which is linked for an older glibc than the one its objects and
 * the static libstdc++ were compiled against. Two names newer than glibc 2.28 are defined
 * here, hidden (the library's own):
 *  - __libc_single_threaded (glibc 2.32): GCC's C++ headers read it to let a reference count
 *    skip its atomic operations while the process has one thread; this copy always says "not
 *    single-threaded", so every count stays atomic: always correct, whatever the process does.
 *  - arc4random (glibc 2.36): libstdc++'s std::random_device can draw from it, and the
 *    archive member holding it comes along with the string code exceptions use; it draws
 *    from the kernel's getrandom (glibc 2.25) here. */
#include <sys/random.h>

__attribute__((visibility("hidden"))) char __libc_single_threaded = 0;

__attribute__((visibility("hidden"))) unsigned int arc4random(void) {
  unsigned int x = 0;
  while (getrandom(&x, sizeof x, 0) != (long)sizeof x) {
  }
  return x;
}
