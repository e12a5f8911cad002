/* pyconfig.h for building CPython 3.10-3.13 extension modules for 64-bit Windows with a
 * clang that targets the MinGW-w64 ABI and the UCRT (zig c++ -target x86_64-windows-gnu),
 * as scripts/cross_wheels.py does. CPython's own Windows pyconfig.h is written for MSVC; this
 * file states the same facts about the interpreter's ABI: 64-bit pointers and size_t, 32-bit
 * long, 16-bit wchar_t, Windows threads, and an interpreter in a DLL (python3XY.dll) whose
 * functions and data are imported with __declspec(dllimport). The public headers read
 * nothing else from it that changes a layout or a call. */
#ifndef Py_CONFIG_H
#define Py_CONFIG_H

#include <limits.h>
#include <stddef.h>
#include <stdint.h>

#define MS_WIN32
#define MS_WIN64
#define MS_WINDOWS
#define NT_THREADS
#define WITH_THREAD
#define PLATFORM "win32"
#define Py_WINVER 0x0602

/* The interpreter is a DLL: Py_ENABLE_SHARED with HAVE_DECLSPEC_DLL makes PyAPI_FUNC and
 * PyAPI_DATA __declspec(dllimport) in extension modules (pyport.h). */
#define MS_COREDLL 1
#define Py_ENABLE_SHARED 1
#define HAVE_DECLSPEC_DLL

/* Sizes of the LLP64 data model. */
#define SIZEOF_SHORT 2
#define SIZEOF_INT 4
#define SIZEOF_LONG 4
#define SIZEOF_LONG_LONG 8
#define SIZEOF_DOUBLE 8
#define SIZEOF_FLOAT 4
#define SIZEOF_LONG_DOUBLE 8
#define SIZEOF_VOID_P 8
#define SIZEOF_SIZE_T 8
#define SIZEOF_UINTPTR_T 8
#define SIZEOF_TIME_T 8
#define SIZEOF_OFF_T 4
#define SIZEOF_FPOS_T 8
#define SIZEOF_HKEY 8
#define SIZEOF_WCHAR_T 2
#define SIZEOF__BOOL 1
#define SIZEOF_PID_T SIZEOF_INT
#define ALIGNOF_SIZE_T 8
#define ALIGNOF_MAX_ALIGN_T 8
#define HAVE_LONG_LONG 1
#define PY_LONG_LONG long long
#define HAVE_USABLE_WCHAR_T 1

/* Py_ssize_t is a 64-bit signed integer. */
typedef long long Py_ssize_t;
#define HAVE_PY_SSIZE_T 1
#define PY_SSIZE_T_MAX LLONG_MAX

/* What the C library offers. */
#define HAVE_STDDEF_H 1
#define HAVE_WCHAR_H 1
#define HAVE_ERRNO_H 1
#define HAVE_SYS_STAT_H 1
#define HAVE_SYS_TYPES_H 1
#define HAVE_SIGNAL_H 1
#define HAVE_IO_H 1
#define HAVE_PROCESS_H 1
#define HAVE_DIRECT_H 1
#define HAVE_CLOCK 1
#define HAVE_STRFTIME 1
#define HAVE_DYNAMIC_LOADING 1
#define HAVE_COPYSIGN 1
#define HAVE_ROUND 1
#define HAVE_HYPOT 1
#define HAVE_DECL_ISINF 1
#define HAVE_DECL_ISNAN 1
#define HAVE_DECL_ISFINITE 1
#define DONT_HAVE_SIG_ALARM
#define DONT_HAVE_SIG_PAUSE
#define LONG_BIT 32
#define WORD_BIT 32
#define WITH_DOC_STRINGS 1
#define WITH_PYMALLOC 1

#endif /* Py_CONFIG_H */
