"""Builds the smoothffd wheels for every platform and CPython version from this Linux x86-64
machine, with zig's clang as the cross compiler (cmake/zig-toolchain.cmake).

    python scripts/cross_wheels.py --out DIR [--platforms linux-x64,windows-x64,...]
                                   [--pythons 3.10,3.11,...] [--cuda-lib libsmoothffd_cuda.so]

Run it with the Python of scripts/package.sh's tools venv (ziglang, pybind11,
scikit-build-core, auditwheel). For each platform it builds the core library once and one
`_core` module per CPython version over it, then writes one wheel per version:

    platform      zig target               wheel tag                 oldest system
    linux-x64     x86_64-linux-gnu.2.28    manylinux_2_28_x86_64     glibc 2.28 (RHEL/Rocky 8)
    linux-arm64   aarch64-linux-gnu.2.28   manylinux_2_28_aarch64    glibc 2.28
    windows-x64   x86_64-windows-gnu       win_amd64                 Windows 10 (UCRT)
    macos-arm64   aarch64-macos.11.0       macosx_11_0_arm64         macOS 11
    macos-x64     x86_64-macos.10.15       macosx_10_15_x86_64       macOS 10.15

What each module is compiled against:
  * CPython's headers of each version (a Python installed here: pyenv's, Debian's, or the
    Debian 13 chroot's for 3.13), with the target's pyconfig.h: Linux x86-64 as installed;
    Linux aarch64 the same file with the facts that differ on that CPU (no x87/x86-64 inline
    assembly; an unsigned 32-bit wchar_t, which CPython can use); macOS the Linux file with
    the system's feature macros (_DARWIN_C_SOURCE instead of glibc's); Windows
    packaging/pyconfig/windows.h.
  * Windows: an import library for python3XY.dll, made from the exports of the real DLL
    (PyPI's QEnvPython3XY, a repackaged embeddable CPython) where one exists, else from the
    functions and data the version's headers declare (CPython 3.13: no Windows build of it
    can be had here).
The wheels' metadata is the one scikit-build-core writes for `pip wheel .` (pyproject.toml).
Linux wheels are checked and tagged by auditwheel (every symbol version within glibc 2.28).
"""

import argparse
import base64
import glob
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

PLATFORMS = {
    "linux-x64": ("x86_64-linux-gnu.2.28", "manylinux_2_28_x86_64"),
    "linux-arm64": ("aarch64-linux-gnu.2.28", "manylinux_2_28_aarch64"),
    "windows-x64": ("x86_64-windows-gnu", "win_amd64"),
    "macos-arm64": ("aarch64-macos.11.0", "macosx_11_0_arm64"),
    "macos-x64": ("x86_64-macos.10.15", "macosx_10_15_x86_64"),
}
PYTHONS = ["3.10", "3.11", "3.12", "3.13"]


def say(*a):
    print("cross_wheels:", *a, flush=True)


def run(cmd, **kw):
    say("$", " ".join(str(c) for c in cmd) if len(cmd) < 12 else " ".join(str(c) for c in cmd[:6]) + " ...")
    subprocess.run(cmd, check=True, **kw)


def zig_exe():
    import ziglang
    exe = os.path.join(os.path.dirname(ziglang.__file__), "zig")
    if not os.access(exe, os.X_OK):
        sys.exit(f"cross_wheels: no zig executable at {exe} (pip install ziglang)")
    return exe


# --- CPython headers ------------------------------------------------------------------------

def header_dir(version, cache):
    """A folder with CPython `version`'s headers installed on this machine."""
    pyenv = os.environ.get("PYENV_ROOT") or os.path.expanduser("~/.pyenv")
    found = sorted(glob.glob(os.path.join(pyenv, "versions", version + ".*", "include", "python" + version)))
    candidates = found[-1:] + [f"/usr/include/python{version}",
                               os.path.join(cache, "trixie", "usr", "include", "python" + version)]
    for d in candidates:
        if os.path.isfile(os.path.join(d, "Python.h")):
            return d
    sys.exit(f"cross_wheels: no headers of CPython {version} here (looked in {', '.join(candidates)}): "
             f"install that Python (pyenv install {version}) or leave it out with --pythons")


def linux_x86_64_pyconfig(include_dir, version):
    """The text of the x86-64 Linux pyconfig.h (Debian's multiarch one resolved)."""
    text = open(os.path.join(include_dir, "pyconfig.h")).read()
    if "x86_64-linux-gnu" in text and "#include" in text and len(text) < 4000:  # Debian's dispatcher
        base = os.path.dirname(os.path.dirname(include_dir))   # .../usr/include -> .../usr
        text = open(os.path.join(base, "include", "x86_64-linux-gnu", f"python{version}", "pyconfig.h")).read()
    return text


def _set(text, name, value):
    """pyconfig.h with macro `name` defined as `value` (None: undefined)."""
    text = re.sub(rf"^#define {name}\b.*$", f"/* #undef {name} */", text, flags=re.M)
    if value is None:
        return text
    line = f"#define {name} {value}".rstrip()
    if re.search(rf"^/\* #undef {name} \*/$", text, flags=re.M):
        return re.sub(rf"^/\* #undef {name} \*/$", line, text, count=1, flags=re.M)
    return text.replace("#endif /*Py_PYCONFIG_H*/", line + "\n#endif /*Py_PYCONFIG_H*/")


def target_pyconfig(platform, linux_text):
    if platform == "windows-x64":
        return open(os.path.join(ROOT, "packaging", "pyconfig", "windows.h")).read()
    text = linux_text
    if platform == "linux-x64":
        return text
    for name in ("HAVE_GCC_ASM_FOR_X64", "HAVE_GCC_ASM_FOR_X87"):
        if platform != "macos-x64":
            text = _set(text, name, None)
    if platform == "linux-arm64":
        return _set(text, "HAVE_USABLE_WCHAR_T", "1")   # wchar_t is unsigned there
    # macOS: the system's own feature set instead of glibc's, no Linux-only headers.
    for name in ("_GNU_SOURCE", "_POSIX_C_SOURCE", "_XOPEN_SOURCE", "_XOPEN_SOURCE_EXTENDED",
                 "__BSD_VISIBLE", "_NETBSD_SOURCE", "_DARWIN_C_SOURCE"):
        text = _set(text, name, None)
    text = _set(text, "_DARWIN_C_SOURCE", "1")
    for name in re.findall(r"^#define (HAVE_LINUX_\w+|HAVE_SYS_EPOLL_H|HAVE_EPOLL\w*|HAVE_SYS_SENDFILE_H)\b",
                           text, flags=re.M):
        text = _set(text, name, None)
    if platform == "macos-arm64":
        text = _set(text, "SIZEOF_LONG_DOUBLE", "8")
    return text


def stage_headers(platform, version, cache, work):
    src = header_dir(version, cache)
    dst = os.path.join(work, "headers", platform, "cp" + version.replace(".", ""))
    if os.path.isdir(dst):
        shutil.rmtree(dst)
    shutil.copytree(src, dst)
    with open(os.path.join(dst, "pyconfig.h"), "w") as f:
        f.write(target_pyconfig(platform, linux_x86_64_pyconfig(src, version)))
    return dst


# --- Windows import libraries ---------------------------------------------------------------

def windows_python_dir(version, cache):
    """PyPI's QEnvPython3XY unpacked (the embeddable Windows CPython), or None."""
    tag = version.replace(".", "")
    dest = os.path.join(cache, "windows", f"python{tag}")
    if os.path.isfile(os.path.join(dest, "python.exe")):
        return dest
    with tempfile.TemporaryDirectory() as tmp:
        r = subprocess.run([sys.executable, "-m", "pip", "download", "-q", "--no-deps", "--only-binary=:all:",
                            "-d", tmp, f"QEnvPython{tag}"], capture_output=True, text=True)
        wheels = glob.glob(os.path.join(tmp, "*.whl"))
        if r.returncode != 0 or not wheels:
            return None
        with zipfile.ZipFile(wheels[0]) as z:
            prefix = f"QPT_SDK/QEnvPython/python{tag}/"
            for n in z.namelist():
                if n.startswith(prefix) and not n.endswith("/"):
                    out = os.path.join(dest + ".part", n[len(prefix):])
                    os.makedirs(os.path.dirname(out), exist_ok=True)
                    with open(out, "wb") as f:
                        f.write(z.read(n))
    os.replace(dest + ".part", dest)
    return dest


def dll_exports(dll):
    out = subprocess.run(["objdump", "-p", dll], check=True, capture_output=True, text=True).stdout
    table = out.split("[Ordinal/Name Pointer] Table", 1)[1]
    return re.findall(r"^\s*\[\s*\d+\]\s+(\S+)$", table, flags=re.M)


def header_exports(include_dir):
    names = set()
    for path in glob.glob(os.path.join(include_dir, "**", "*.h"), recursive=True):
        if os.sep + "internal" + os.sep in path:
            continue
        text = open(path, errors="replace").read()
        for m in re.finditer(r"PyAPI_(?:FUNC|DATA)\(", text):
            depth, i = 1, m.end()
            while depth and i < len(text):
                depth += {"(": 1, ")": -1}.get(text[i], 0)
                i += 1
            name = re.match(r"\s*\(?\s*\**\s*([A-Za-z_]\w*)", text[i:])
            if name:
                names.add(name.group(1))
    return sorted(names)


def import_library(version, include_dir, cache, work, zig):
    tag = version.replace(".", "")
    pydir = windows_python_dir(version, cache)
    dll = os.path.join(pydir, f"python{tag}.dll") if pydir else None
    names = dll_exports(dll) if dll and os.path.isfile(dll) else header_exports(include_dir)
    src = "its DLL" if dll and os.path.isfile(dll) else "its headers (no Windows build of it here)"
    say(f"import library of python{tag}.dll from {src}: {len(names)} names")
    d = os.path.join(work, "implib")
    os.makedirs(d, exist_ok=True)
    deff = os.path.join(d, f"python{tag}.def")
    with open(deff, "w") as f:
        f.write(f"LIBRARY python{tag}.dll\nEXPORTS\n" + "".join(f"    {n}\n" for n in names))
    lib = os.path.join(d, f"libpython{tag}.a")
    run([zig, "dlltool", "-m", "i386:x86-64", "-d", deff, "-l", lib, "-D", f"python{tag}.dll"])
    return lib


# --- building ---------------------------------------------------------------------------------

def build_platform(platform, versions, cache, work, zig, jobs):
    target = PLATFORMS[platform][0]
    import pybind11
    entries, extra = [], []
    for v in versions:
        inc = stage_headers(platform, v, cache, work)
        tag = "cp" + v.replace(".", "")
        entries.append(f"{tag}={inc}")
        if platform == "windows-x64":
            extra.append(f"-DSMOOTHFFD_PYTHON_IMPLIB_{tag}={import_library(v, inc, cache, work, zig)}")
    bdir = os.path.join(work, "build", platform)
    run(["cmake", "-S", ROOT, "-B", bdir, "-G", "Unix Makefiles",
         f"-DCMAKE_TOOLCHAIN_FILE={os.path.join(ROOT, 'cmake', 'zig-toolchain.cmake')}",
         f"-DSFFD_ZIG={zig}", f"-DSFFD_ZIG_TARGET={target}", "-DCMAKE_BUILD_TYPE=Release",
         "-DSMOOTHFFD_TESTS=OFF", "-DSMOOTHFFD_CUDA=OFF",
         f"-DSMOOTHFFD_PYTHON_HEADERS={';'.join(entries)}",
         f"-DSMOOTHFFD_PYBIND11_INCLUDE={pybind11.get_include()}"] + extra,
        stdout=subprocess.DEVNULL)
    run(["cmake", "--build", bdir, "-j", str(jobs)])
    modules = {}
    for v in versions:
        tag = "cp" + v.replace(".", "")
        found = [f for f in glob.glob(os.path.join(bdir, "modules", tag, "_core.*")) if f.endswith((".so", ".pyd"))]
        if len(found) != 1:
            sys.exit(f"cross_wheels: expected one module for {platform} {tag}, found {found}")
        modules[v] = found[0]
    return modules


# --- wheels -----------------------------------------------------------------------------------

def metadata_dir(work):
    """The .dist-info folder scikit-build-core writes for this project (METADATA, entry points)."""
    from scikit_build_core.build import prepare_metadata_for_build_wheel
    out = os.path.join(work, "metadata")
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    cwd = os.getcwd()
    os.chdir(ROOT)
    try:
        name = prepare_metadata_for_build_wheel(out)
    finally:
        os.chdir(cwd)
    return os.path.join(out, name)


def package_files():
    """The package's tracked files (python/smoothffd), as the wheel's paths."""
    out = subprocess.run(["git", "-C", ROOT, "ls-files", "python/smoothffd"], check=True,
                         capture_output=True, text=True).stdout.split()
    return [(os.path.join(ROOT, p), p[len("python/"):]) for p in out]


def write_wheel(out_dir, dist_info, tag, extra):
    """A wheel of the package's files plus `extra` [(source, path in wheel)], tagged `tag`."""
    name = os.path.basename(dist_info)                       # smoothffd-0.1.0.dist-info
    dist, version = name[: -len(".dist-info")].split("-")
    entries = package_files() + extra
    for f in sorted(os.listdir(dist_info)):
        if f not in ("WHEEL", "RECORD") and os.path.isfile(os.path.join(dist_info, f)):
            entries.append((os.path.join(dist_info, f), f"{name}/{f}"))
    for base, _, files in os.walk(os.path.join(dist_info, "licenses")):
        for f in files:
            p = os.path.join(base, f)
            entries.append((p, f"{name}/{os.path.relpath(p, dist_info)}"))
    wheel_meta = (f"Wheel-Version: 1.0\nGenerator: smoothffd scripts/cross_wheels.py\n"
                  f"Root-Is-Purelib: false\nTag: {tag}\n").encode()
    path = os.path.join(out_dir, f"{dist}-{version}-{tag}.whl")
    record = []

    def add(z, arc, data, executable=False):
        info = zipfile.ZipInfo(arc, date_time=(2020, 1, 1, 0, 0, 0))
        info.compress_type = zipfile.ZIP_DEFLATED
        info.external_attr = (0o755 if executable else 0o644) << 16
        z.writestr(info, data)
        digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
        record.append(f"{arc},sha256={digest},{len(data)}")

    tmp = path + ".part"
    with zipfile.ZipFile(tmp, "w") as z:
        for src, arc in sorted(entries, key=lambda e: e[1]):
            add(z, arc, open(src, "rb").read(), executable=arc.endswith((".so", ".pyd")))
        add(z, f"{name}/WHEEL", wheel_meta)
        record.append(f"{name}/RECORD,,")
        info = zipfile.ZipInfo(f"{name}/RECORD", date_time=(2020, 1, 1, 0, 0, 0))
        info.compress_type = zipfile.ZIP_DEFLATED
        z.writestr(info, "\n".join(record) + "\n")
    os.replace(tmp, path)
    return path


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", required=True)
    ap.add_argument("--platforms", default=",".join(PLATFORMS))
    ap.add_argument("--pythons", default=",".join(PYTHONS))
    ap.add_argument("--cuda-lib", help="libsmoothffd_cuda.so for the linux-x64 wheels")
    ap.add_argument("--work", default=os.path.join(ROOT, "build", "cross"))
    ap.add_argument("--cache", default=os.path.expanduser("~/.cache/smoothffd"))
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 2)
    args = ap.parse_args()
    platforms = args.platforms.split(",")
    versions = args.pythons.split(",")
    for p in platforms:
        if p not in PLATFORMS:
            sys.exit(f"cross_wheels: unknown platform {p!r} (known: {', '.join(PLATFORMS)})")
    os.makedirs(args.out, exist_ok=True)
    os.makedirs(args.work, exist_ok=True)
    zig = zig_exe()
    dist_info = metadata_dir(args.work)
    auditwheel = os.path.join(os.path.dirname(sys.executable), "auditwheel")
    tool_env = dict(os.environ, PATH=os.path.dirname(sys.executable) + os.pathsep + os.environ.get("PATH", ""))
    for platform in platforms:
        say(f"== {platform}: CPython {', '.join(versions)}")
        modules = build_platform(platform, versions, args.cache, args.work, zig, args.jobs)
        plat_tag = PLATFORMS[platform][1]
        for v, module in modules.items():
            py = "cp" + v.replace(".", "")
            extra = [(module, "smoothffd/" + os.path.basename(module))]
            if platform == "linux-x64" and args.cuda_lib:
                extra.append((args.cuda_lib, "smoothffd/libsmoothffd_cuda.so"))
            if platform.startswith("linux"):
                check_manylinux(auditwheel, tool_env, args.work, dist_info, py, plat_tag, extra)
            say("wheel", os.path.basename(write_wheel(args.out, dist_info, f"{py}-{py}-{plat_tag}", extra)))


def check_manylinux(auditwheel, env, work, dist_info, py, plat_tag, extra):
    """auditwheel's verdict on the Linux wheel's files: every symbol version within the tag's
    glibc (zig linked against that glibc's stubs) and no shared library to bundle. Nothing is
    repaired: the wheel needs nothing but the system's C library."""
    raw_dir = os.path.join(work, "raw")
    os.makedirs(raw_dir, exist_ok=True)
    arch = plat_tag.split("_", 3)[3]
    raw = write_wheel(raw_dir, dist_info, f"{py}-{py}-linux_{arch}", extra)
    out = subprocess.run([auditwheel, "show", raw], env=env, capture_output=True, text=True, check=True).stdout
    text = " ".join(out.split())
    m = re.search(r'consistent with the following platform tag: "manylinux_(\d+)_(\d+)_' + arch + '"', text)
    want = tuple(int(x) for x in plat_tag.split("_")[1:3])
    if not m or (int(m.group(1)), int(m.group(2))) > want or "external shared libraries are required" in text:
        sys.exit(f"cross_wheels: {os.path.basename(raw)} does not meet {plat_tag}:\n{out}")


if __name__ == "__main__":
    main()
