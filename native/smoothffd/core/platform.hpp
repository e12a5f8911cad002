// Everything that depends on the operating system or the CPU's vendor, in one place: opening
// shared libraries at run time (the CUDA backend, cuBLAS, the NVIDIA driver), finding the file
// a function lives in, library file names, and asking the CPU which instruction sets it runs.
// Three systems: Linux and macOS (dlopen) and Windows (LoadLibrary); the callers are the same
// on all of them. Host code only: _core (cuda_proxy/cuda_proxy.cpp, eval/cpu_evaluator.cpp) and
// the host side of the CUDA library (cuda/device_status.cpp, cuda/cublas_gemm.cpp).
#pragma once

#if defined(_WIN32)
#ifndef WIN32_LEAN_AND_MEAN
#define WIN32_LEAN_AND_MEAN
#endif
#ifndef NOMINMAX
#define NOMINMAX
#endif
#include <windows.h>
#if defined(_MSC_VER)
#include <intrin.h>
#endif
#else
#include <dlfcn.h>
#include <limits.h>
#include <stdlib.h>
#include <sys/stat.h>
#endif

#include <cstdlib>
#include <string>
#include <vector>

namespace sffd {
namespace platform {

#if defined(_WIN32)
namespace detail {
inline std::wstring widen(const std::string& s) {
  if (s.empty()) return std::wstring();
  const int n = MultiByteToWideChar(CP_UTF8, 0, s.data(), (int)s.size(), nullptr, 0);
  std::wstring w(n, L'\0');
  MultiByteToWideChar(CP_UTF8, 0, s.data(), (int)s.size(), &w[0], n);
  return w;
}
inline std::string narrow(const std::wstring& w) {
  if (w.empty()) return std::string();
  const int n = WideCharToMultiByte(CP_UTF8, 0, w.data(), (int)w.size(), nullptr, 0, nullptr, nullptr);
  std::string s(n, '\0');
  WideCharToMultiByte(CP_UTF8, 0, w.data(), (int)w.size(), &s[0], n, nullptr, nullptr);
  return s;
}
inline std::string last_error_text() {
  const DWORD code = GetLastError();
  wchar_t* buf = nullptr;
  const DWORD n = FormatMessageW(FORMAT_MESSAGE_ALLOCATE_BUFFER | FORMAT_MESSAGE_FROM_SYSTEM |
                                     FORMAT_MESSAGE_IGNORE_INSERTS,
                                 nullptr, code, 0, reinterpret_cast<wchar_t*>(&buf), 0, nullptr);
  std::string text = n ? narrow(std::wstring(buf, n)) : std::string();
  if (buf) LocalFree(buf);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r' || text.back() == ' ')) text.pop_back();
  return "Windows error " + std::to_string((unsigned long)code) + (text.empty() ? "" : ": " + text);
}
inline bool is_path(const std::string& s) {
  return s.find('/') != std::string::npos || s.find('\\') != std::string::npos;
}
}  // namespace detail
#endif

// Opens a shared library by name (the system's search) or path, resolving every symbol now and
// keeping them to itself; nullptr on failure, with the system's reason in *error. Libraries
// opened here are never closed (they hold the CUDA runtime's or cuBLAS's state).
// On Windows a path also lets the library find the DLLs in its own folder.
inline void* open_library(const std::string& name_or_path, std::string* error) {
#if defined(_WIN32)
  std::wstring w = detail::widen(name_or_path);
  HMODULE h;
  if (detail::is_path(name_or_path)) {
    for (auto& c : w)
      if (c == L'/') c = L'\\';
    h = LoadLibraryExW(w.c_str(), nullptr, LOAD_LIBRARY_SEARCH_DLL_LOAD_DIR | LOAD_LIBRARY_SEARCH_DEFAULT_DIRS);
  } else {
    h = LoadLibraryW(w.c_str());
  }
  if (!h && error) *error = detail::last_error_text();
  return reinterpret_cast<void*>(h);
#else
  dlerror();
  void* h = dlopen(name_or_path.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (!h && error) {
    const char* e = dlerror();
    *error = e ? e : "not found";
  }
  return h;
#endif
}

inline void* library_symbol(void* library, const char* name) {
#if defined(_WIN32)
  return reinterpret_cast<void*>(GetProcAddress(reinterpret_cast<HMODULE>(library), name));
#else
  return dlsym(library, name);
#endif
}

// File names the system gives shared libraries: "smoothffd_cuda" -> libsmoothffd_cuda.so
// (Linux), libsmoothffd_cuda.dylib (macOS), smoothffd_cuda.dll (Windows).
inline std::string library_file_name(const std::string& base) {
#if defined(_WIN32)
  return base + ".dll";
#elif defined(__APPLE__)
  return "lib" + base + ".dylib";
#else
  return "lib" + base + ".so";
#endif
}

// A library of the CUDA toolkit or driver with its major version: ("cublas", 13) ->
// libcublas.so.13 (Linux), cublas64_13.dll (Windows); ("cuda", 1), the driver, ->
// libcuda.so.1 (Linux), nvcuda.dll (Windows).
inline std::string library_file_name(const std::string& base, int major) {
#if defined(_WIN32)
  if (base == "cuda") return "nvcuda.dll";
  return base + "64_" + std::to_string(major) + ".dll";
#elif defined(__APPLE__)
  return "lib" + base + "." + std::to_string(major) + ".dylib";
#else
  return library_file_name(base) + "." + std::to_string(major);
#endif
}

// Folders where a CUDA toolkit keeps its libraries when the system's search does not know
// them; the first is named in messages. Windows: the installer's CUDA_PATH.
inline const std::vector<std::string>& cuda_toolkit_library_dirs() {
  static const std::vector<std::string> dirs = [] {
#if defined(_WIN32)
    const char* root = std::getenv("CUDA_PATH");
    const std::string r = root ? root : "C:\\Program Files\\NVIDIA GPU Computing Toolkit\\CUDA\\v13.0";
    return std::vector<std::string>{r + "\\bin\\x64", r + "\\bin"};
#else
    return std::vector<std::string>{"/usr/local/cuda/lib64", "/usr/local/cuda/lib",
                                    "/usr/local/cuda/targets/x86_64-linux/lib"};
#endif
  }();
  return dirs;
}

// Absolute folder of the file (executable or shared library) that holds `address`; "" when the
// system cannot tell.
inline std::string directory_of(const void* address) {
#if defined(_WIN32)
  HMODULE h = nullptr;
  if (!GetModuleHandleExW(GET_MODULE_HANDLE_EX_FLAG_FROM_ADDRESS | GET_MODULE_HANDLE_EX_FLAG_UNCHANGED_REFCOUNT,
                          reinterpret_cast<LPCWSTR>(address), &h))
    return "";
  std::wstring buf(MAX_PATH, L'\0');
  for (;;) {
    const DWORD n = GetModuleFileNameW(h, &buf[0], (DWORD)buf.size());
    if (n == 0) return "";
    if (n < buf.size()) {
      buf.resize(n);
      break;
    }
    buf.resize(buf.size() * 2);
  }
  const std::string file = detail::narrow(buf);
  const size_t slash = file.find_last_of("\\/");
  return slash == std::string::npos ? "." : file.substr(0, slash);
#else
  Dl_info info{};
  if (!dladdr(const_cast<void*>(address), &info) || !info.dli_fname) return "";
  std::string file = info.dli_fname;
  char buf[PATH_MAX];
  if (realpath(file.c_str(), buf)) file = buf;
  const size_t slash = file.rfind('/');
  return slash == std::string::npos ? "." : file.substr(0, slash);
#endif
}

inline std::string path_join(const std::string& dir, const std::string& name) {
#if defined(_WIN32)
  const char sep = '\\';
  const bool ends = !dir.empty() && (dir.back() == '\\' || dir.back() == '/');
#else
  const char sep = '/';
  const bool ends = !dir.empty() && dir.back() == '/';
#endif
  return dir.empty() || ends ? dir + name : dir + sep + name;
}

inline bool file_exists(const std::string& path) {
#if defined(_WIN32)
  return GetFileAttributesW(detail::widen(path).c_str()) != INVALID_FILE_ATTRIBUTES;
#else
  struct stat st;
  return stat(path.c_str(), &st) == 0;
#endif
}

// Whether the CPU (and the OS: YMM state saved) runs x86-64-v3 code: AVX2 and FMA, and the
// BMI1/BMI2 that -march=x86-64-v3 also lets the compiler use. Asked with CPUID and XGETBV
// directly (not the compilers' __builtin_cpu_supports, whose CPU table lives in a runtime
// library that some toolchains link as a symbol a shared module cannot reach), the same on
// every x86-64 system. Other CPUs: false (their builds have no x86-64-v3 copy).
inline bool cpu_runs_x86_64_v3() {
#if defined(__x86_64__) || defined(__i386__) || defined(_M_X64) || defined(_M_IX86)
  auto cpuid = [](unsigned leaf, unsigned sub, unsigned r[4]) {
#if defined(_MSC_VER)
    int v[4];
    __cpuidex(v, (int)leaf, (int)sub);
    for (int i = 0; i < 4; ++i) r[i] = (unsigned)v[i];
#else
    __asm__ __volatile__("cpuid" : "=a"(r[0]), "=b"(r[1]), "=c"(r[2]), "=d"(r[3]) : "a"(leaf), "c"(sub));
#endif
  };
  unsigned r[4];
  cpuid(0, 0, r);
  if (r[0] < 7) return false;
  cpuid(1, 0, r);
  const bool fma = (r[2] >> 12) & 1, osxsave = (r[2] >> 27) & 1, avx = (r[2] >> 28) & 1;
  if (!(fma && osxsave && avx)) return false;
#if defined(_MSC_VER)
  const unsigned long long xcr0 = _xgetbv(0);
#else
  unsigned lo, hi;
  __asm__ __volatile__("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
  const unsigned long long xcr0 = ((unsigned long long)hi << 32) | lo;
#endif
  if ((xcr0 & 6) != 6) return false;  // the OS saves the XMM and YMM registers
  cpuid(7, 0, r);
  const bool bmi1 = (r[1] >> 3) & 1, avx2 = (r[1] >> 5) & 1, bmi2 = (r[1] >> 8) & 1;
  return bmi1 && avx2 && bmi2;
#else
  return false;
#endif
}

}  // namespace platform
}  // namespace sffd
