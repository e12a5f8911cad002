# Cross-compiling with zig's clang (PyPI's `ziglang`): one toolchain for every platform the
# wheels serve, built on Linux x86-64 (scripts/cross_wheels.sh). zig brings the C library
# headers and link stubs of each target (glibc of a chosen version, mingw-w64 with the UCRT,
# macOS's libSystem) and its own libc++, linked statically, so a module needs nothing from the
# user's machine beyond the C library and the Python that loads it.
#
#   cmake -DCMAKE_TOOLCHAIN_FILE=cmake/zig-toolchain.cmake -DSFFD_ZIG=/path/to/zig \
#         -DSFFD_ZIG_TARGET=aarch64-linux-gnu.2.28 ...
#
# Targets: x86_64-linux-gnu.2.28, aarch64-linux-gnu.2.28, x86_64-windows-gnu,
# aarch64-macos.11.0, x86_64-macos.10.15 (the version after the system is the oldest it runs on).
if(NOT SFFD_ZIG OR NOT SFFD_ZIG_TARGET)
  message(FATAL_ERROR "zig-toolchain.cmake needs -DSFFD_ZIG=<zig executable> -DSFFD_ZIG_TARGET=<target>")
endif()
# try_compile projects see these too.
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES SFFD_ZIG SFFD_ZIG_TARGET)

string(REGEX MATCH "^[^-]+" _arch "${SFFD_ZIG_TARGET}")
if(SFFD_ZIG_TARGET MATCHES "-windows")
  set(CMAKE_SYSTEM_NAME Windows)
elseif(SFFD_ZIG_TARGET MATCHES "-macos")
  set(CMAKE_SYSTEM_NAME Darwin)
  string(REGEX MATCH "[0-9]+\\.[0-9]+$" CMAKE_OSX_DEPLOYMENT_TARGET "${SFFD_ZIG_TARGET}")
else()
  set(CMAKE_SYSTEM_NAME Linux)
endif()
set(CMAKE_SYSTEM_PROCESSOR ${_arch})
if(_arch STREQUAL "x86_64")
  set(CMAKE_SYSTEM_PROCESSOR x86_64)
endif()

# One wrapper script per tool: CMake wants a compiler as a single executable. The compiler
# wrappers also translate GCC's x86-64 level names, which zig spells as its CPU names
# (-march=x86-64-v3 -> -mcpu=x86_64_v3).
set(_dir "${CMAKE_BINARY_DIR}/zig-wrappers")
file(MAKE_DIRECTORY "${_dir}")
set(_translate [=[for a in "$@"; do
  shift
  case "$a" in
    -march=x86-64*) a="-mcpu=$(echo "${a#-march=}" | tr - _)" ;;
  esac
  set -- "$@" "$a"
done
]=])
foreach(tool cc c++ ar ranlib)
  if(tool STREQUAL "cc" OR tool STREQUAL "c++")
    set(_cmd "${_translate}exec \"${SFFD_ZIG}\" ${tool} -target ${SFFD_ZIG_TARGET}")
  else()
    set(_cmd "exec \"${SFFD_ZIG}\" ${tool}")
  endif()
  file(WRITE "${_dir}/zig-${tool}" "#!/bin/sh\n${_cmd} \"$@\"\n")
  file(CHMOD "${_dir}/zig-${tool}" PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)
endforeach()
set(CMAKE_C_COMPILER "${_dir}/zig-cc")
set(CMAKE_CXX_COMPILER "${_dir}/zig-c++")
set(CMAKE_AR "${_dir}/zig-ar" CACHE FILEPATH "" FORCE)
set(CMAKE_RANLIB "${_dir}/zig-ranlib" CACHE FILEPATH "" FORCE)
# macOS: no Apple SDK here; zig's own headers and stubs stand in for it.
set(CMAKE_OSX_SYSROOT "" CACHE STRING "" FORCE)

set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
