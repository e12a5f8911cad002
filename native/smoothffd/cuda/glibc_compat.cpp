// Keeps libsmoothffd_cuda.so within the glibc of the shipped wheels (manylinux_2_34): the
// statically linked libstdc++ of GCC 12 on glibc 2.36 refers to arc4random (GLIBC_2.36) from
// std::random_device, which every std exception drags in (stdexcept.o -> cow-string-inst.o ->
// random.o) although the library never asks for a random device. This local definition (the
// version script keeps it unexported) takes the reference instead, on getrandom (glibc 2.25).
#include <sys/random.h>
#include <unistd.h>

#include <cstdint>

extern "C" uint32_t arc4random(void) noexcept {
  uint32_t v = 0;
  for (int tries = 0; tries < 16; ++tries)
    if (getrandom(&v, sizeof(v), 0) == (ssize_t)sizeof(v)) return v;
  return (uint32_t)getpid() * 2654435761u;  // std::random_device is never used here
}
