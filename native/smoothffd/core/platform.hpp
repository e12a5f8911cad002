// Everything that depends on the operating system or the CPU's vendor, in one place: opening
// shared libraries at run time (the CUDA backend, cuBLAS, the NVIDIA driver), finding the file
// a function lives in, and asking the CPU which instruction sets it runs. A Windows or macOS
// port changes this file (docs/packaging.md says with what); the callers stay as they are.
// Host code only: _core (cuda/cuda_loader.cpp, eval/cpu_evaluator.cpp) and the host side of
// libsmoothffd_cuda.so (cuda/device_status.cpp, cuda/cublas_gemm.cpp).
#pragma once

#include <dlfcn.h>
#include <limits.h>
#include <stdlib.h>
#include <sys/stat.h>

#include <string>

namespace sffd {
namespace platform {

// Opens a shared library by name (the system's search) or path, resolving every symbol now and
// keeping them to itself; nullptr on failure, with the system's reason in *error. Libraries
// opened here are never closed (they hold the CUDA runtime's or cuBLAS's state).
inline void* open_library(const std::string& name_or_path, std::string* error) {
  dlerror();
  void* h = dlopen(name_or_path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!h && error) {
    const char* e = dlerror();
    *error = e ? e : "not found";
  }
  return h;
}

inline void* library_symbol(void* library, const char* name) { return dlsym(library, name); }

// File names the system gives shared libraries: "smoothffd_cuda" -> libsmoothffd_cuda.so, and
// with a major version ("cublas", 13) -> libcublas.so.13.
inline std::string library_file_name(const std::string& base) { return "lib" + base + ".so"; }
inline std::string library_file_name(const std::string& base, int major) {
  return library_file_name(base) + "." + std::to_string(major);
}

// Where a CUDA toolkit installs its libraries when the system's search does not know them.
inline const char* const* cuda_toolkit_library_dirs() {
  static const char* const dirs[] = {"/usr/local/cuda/lib64", "/usr/local/cuda/lib",
                                     "/usr/local/cuda/targets/x86_64-linux/lib", nullptr};
  return dirs;
}

// Absolute folder of the file (executable or shared library) that holds `address`; "" when the
// system cannot tell.
inline std::string directory_of(const void* address) {
  Dl_info info{};
  if (!dladdr(const_cast<void*>(address), &info) || !info.dli_fname) return "";
  std::string file = info.dli_fname;
  char buf[PATH_MAX];
  if (realpath(file.c_str(), buf)) file = buf;
  const size_t slash = file.rfind('/');
  return slash == std::string::npos ? "." : file.substr(0, slash);
}

inline std::string path_join(const std::string& dir, const std::string& name) {
  return dir.empty() || dir.back() == '/' ? dir + name : dir + "/" + name;
}

inline bool file_exists(const std::string& path) {
  struct stat st;
  return stat(path.c_str(), &st) == 0;
}

// Whether the CPU (and the OS: YMM state saved) runs x86-64-v3 code: AVX2 and FMA, and the
// BMI1/BMI2 that -march=x86-64-v3 also lets the compiler use. libgcc's (or compiler-rt's)
// CPUID table, filled once at load time.
inline bool cpu_runs_x86_64_v3() {
#if (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || defined(__i386__))
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
         __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2");
#else
  return false;
#endif
}

}  // namespace platform
}  // namespace sffd
