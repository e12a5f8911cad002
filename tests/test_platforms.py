"""The wheels of the other platforms (dist/, scripts/package.sh), run as their users run them
wherever this Linux x86-64 machine can, and checked without running where it cannot:

* Windows x64: each wheel for CPython 3.10, 3.11 and 3.12 installed into a Windows CPython
  (PyPI's QEnvPython3XY) under Wine, with numpy 1.26.4 for win_amd64 and pytest; the core's
  suites run there from the installed wheel. The Windows extension zip installed into PyPI's
  bpy 4.2 for Windows (Blender as a module) under Wine, from disk and from dist/repository,
  and a modifier works. CPython 3.13's wheel has no Windows interpreter here: every name it
  imports from python313.dll is one that 3.13's headers declare.
* Linux aarch64: the cp311 wheel installed into Debian 12's arm64 Python 3.11 (its own numpy
  and pytest) under qemu-aarch64; the core's suites run there (about a minute emulated): the
  module's load, the NEON code of the per-frame stages, the worker threads, the command line.
* macOS arm64 and x86-64: the Mach-O module's CPU, minimum macOS version, code signature
  (arm64), the libraries it loads (the system's only) and its undefined symbols (the system
  libraries' or, looked up in the interpreter at load time, Python's, each declared by that
  CPython version's headers). These wheels are built, not run.
* Every platform that runs here gives the same deformation as this machine's wheel (the
  command line on the vase with its sample lattice: positions and normals within float
  rounding) and the same command-line behaviour on an error (exit status and message).

scripts/setup_platforms.sh prepares Wine, the Windows Pythons and the arm64 root under the
cache folder; without them (or without dist/) these tests skip, except in scripts/test.sh's
artefact run (SMOOTHFFD_TEST_INSTALLED=1), where anything missing fails.
"""

import glob
import os
import re
import shutil
import struct
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

import smoothffd
from smoothffd import io as sio

ROOT = Path(__file__).resolve().parent.parent
DIST = ROOT / "dist"
CACHE = Path(os.environ.get("SMOOTHFFD_CACHE") or os.path.expanduser("~/.cache/smoothffd"))
INSTALLED = os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1"
WINE = "/usr/lib/wine/wine64"
# One Wine prefix and one arm64 root serve every test here: under pytest-xdist (the test
# command's -n) they run one after another on one worker.
pytestmark = pytest.mark.xdist_group("platforms")
# The core's suites that run on every platform (the cp313 wheel runs the same set natively).
CORE_SUITES = ["test_deform_basics.py", "test_lattices.py", "test_cli.py", "test_sphere_and_sharp.py"]


def _missing(what):
    if INSTALLED:
        pytest.fail(f"{what} is missing: scripts/package.sh and scripts/setup_platforms.sh make it")
    pytest.skip(f"{what} is missing (scripts/package.sh, scripts/setup_platforms.sh)")


def _wheel(py, plat):
    found = sorted(DIST.glob(f"smoothffd-*-{py}-{py}-{plat}.whl"))
    if not found:
        _missing(f"dist/smoothffd-*-{py}-{py}-{plat}.whl")
    assert len(found) == 1, found
    return found[0]


def _install(wheel, dest):
    """A wheel installed as pip installs a platform wheel: its files unpacked into site-packages."""
    site = dest / "site"
    with zipfile.ZipFile(wheel) as z:
        z.extractall(site)
    return site


# The case each platform computes: the command line on the sample vase and its bent lattice
# (level 3), then a missing input (an error the command line must report the same way).
CASE = r'''
import os, subprocess, sys
import smoothffd
data = os.path.join(os.path.dirname(smoothffd.__file__), "data")
out = sys.argv[1]
run = lambda *a: subprocess.run([sys.executable, "-m", "smoothffd", *a], capture_output=True, text=True)
ok = run("deform", os.path.join(data, "vase.obj"), "--lattice", os.path.join(data, "vase_bend.json"),
         "-o", os.path.join(out, "vase.obj"), "--level", "3", "--threads", "2", "--quiet")
bad = run("deform", os.path.join(out, "no-such.obj"), "--lattice", os.path.join(data, "vase_bend.json"),
          "-o", os.path.join(out, "never.obj"))
with open(os.path.join(out, "case.txt"), "w") as f:
    f.write(f"{ok.returncode}\n{bad.returncode}\n{bad.stderr.strip().splitlines()[-1]}\n")
from smoothffd.deform import _available_memory
print("cpu_isa", smoothffd._core.cpu_isa(), "memory", _available_memory(), "ok stderr:", ok.stderr.strip()[-300:])
'''


def _case_here(tmp_path):
    out = tmp_path / "here"
    out.mkdir()
    script = tmp_path / "case.py"
    script.write_text(CASE)
    subprocess.run([sys.executable, str(script), str(out)], check=True, capture_output=True, text=True)
    return out


def _run_case(run, tmp_path):
    """CASE run by `run(args)` (another platform's interpreter) into tmp_path/there; its
    result and that folder."""
    out = tmp_path / "there"
    out.mkdir()
    (tmp_path / "case.py").write_text(CASE)
    r = run([str(tmp_path / "case.py"), str(out)])
    assert r.returncode == 0, r.stdout + r.stderr
    return r, out


def _compare_case(theirs, here):
    """The other platform's command line did what this one did."""
    rc_ok, rc_bad, msg = (theirs / "case.txt").read_text().splitlines()
    h_ok, h_bad, h_msg = (here / "case.txt").read_text().splitlines()
    assert (rc_ok, rc_bad) == (h_ok, h_bad) == ("0", "2") or (rc_ok, rc_bad) == (h_ok, h_bad)
    assert rc_ok == "0"
    # The message names the missing file by its own path; the rest is the same words.
    strip = lambda m: re.sub(r"\S*no-such\.obj\S*", "FILE", m)
    assert strip(msg) == strip(h_msg)
    a, b = sio.read_obj(str(theirs / "vase.obj")), sio.read_obj(str(here / "vase.obj"))
    assert a.positions.shape == b.positions.shape and a.face_offsets.tolist() == b.face_offsets.tolist()
    diag = float(np.linalg.norm(b.positions.max(0) - b.positions.min(0)))
    # Float rounding of a level-3 frame: the platforms' compilers contract multiply-adds
    # differently; measured at most 2e-7 of the diagonal (OBJ text keeps 9 digits).
    assert float(np.abs(a.positions - b.positions).max()) <= 2e-6 * diag
    assert a.corner_normals is not None and a.corner_normals.shape == b.corner_normals.shape
    assert float(np.abs(a.corner_normals - b.corner_normals).max()) <= 2e-5


def _core_suites_args():
    """pytest's arguments for the core's suites, from the source tree's tests/."""
    return ["-m", "pytest", "-q", "-p", "no:cacheprovider", "-ra"] + [str(ROOT / "tests" / s) for s in CORE_SUITES]


def _assert_suites_passed(r):
    tail = (r.stdout + r.stderr)[-4000:]
    assert r.returncode == 0, tail
    assert re.search(r"\d+ passed", r.stdout), tail
    print(tail.strip().splitlines()[-1])


# --- Windows under Wine -----------------------------------------------------------------------

def _windows_python(tag):
    py = CACHE / "windows" / f"python{tag}"
    if not (py / ".complete").exists() or not os.access(WINE, os.X_OK):
        _missing(f"Wine and the Windows CPython {tag[0]}.{tag[1:]} ({py})")
    return py


def _wine(py, args, site, cwd, timeout):
    env = dict(os.environ, WINEPREFIX=str(CACHE / "wine-prefix"), WINEDEBUG="-all",
               PYTHONPATH="Z:" + str(site).replace("/", "\\"),
               PYTHONDONTWRITEBYTECODE="1", PYTHONUTF8="1")
    env.pop("PYTHONHOME", None)
    return subprocess.run([WINE, str(py / "python.exe"), *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.mark.parametrize("tag", ["310", "311", "312"])
def test_windows_wheel_under_wine(tag, tmp_path):
    py = _windows_python(tag)
    wheel = _wheel(f"cp{tag}", "win_amd64")
    site = _install(wheel, tmp_path)
    r, out = _run_case(lambda args: _wine(py, args, site, tmp_path, 600), tmp_path)
    assert "cpu_isa x86-64-v" in r.stdout, r.stdout
    # The memory check before a plan asks Windows (GlobalMemoryStatusEx): a positive number.
    assert int(re.search(r"memory (\S+)", r.stdout).group(1)) > 0, r.stdout
    _compare_case(out, _case_here(tmp_path))


def test_windows_core_suites_under_wine(tmp_path):
    """The core's suites from the installed cp311 wheel, in Windows' CPython 3.11."""
    py = _windows_python("311")
    site = _install(_wheel("cp311", "win_amd64"), tmp_path)
    _assert_suites_passed(_wine(py, _core_suites_args(), site, tmp_path, 1800))


def _bpy_under_wine(script, arg, tmp_path):
    """Runs tests/blender/`script` `arg` in PyPI's bpy 4.2 for Windows (Blender as a Python
    module, CPython 3.11) under Wine, in a private Blender profile."""
    py = _windows_python("311")
    bpy_dir = CACHE / "windows" / "bpy-4.2"
    if not (bpy_dir / ".complete").exists():
        _missing(f"bpy 4.2 for Windows ({bpy_dir})")
    win = lambda p: "Z:" + str(p).replace("/", "\\")
    profile = tmp_path / "profile"
    env = dict(os.environ, WINEPREFIX=str(CACHE / "wine-prefix"), WINEDEBUG="-all", PYTHONPATH=win(bpy_dir),
               PYTHONDONTWRITEBYTECODE="1", BLENDER_USER_RESOURCES=win(profile),
               BLENDER_USER_SCRIPTS=win(profile / "scripts"), BLENDER_USER_CONFIG=win(profile / "config"),
               BLENDER_USER_EXTENSIONS=win(profile / "extensions"))
    r = subprocess.run([WINE, str(py / "python.exe"), str(ROOT / "tests" / "blender" / script), str(arg)],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=900,
                       stdin=subprocess.DEVNULL)
    out = r.stdout + r.stderr
    assert r.returncode == 0 and " passed, 0 failed" in out, out[-3000:]
    assert "FAIL" not in r.stdout, out[-3000:]


def _version():
    return re.search(r'__version__ = "(.*)"', (ROOT / "python" / "smoothffd" / "__init__.py").read_text()).group(1)


def test_windows_extension_in_blender_under_wine(tmp_path):
    """The Windows extension zip installed into Blender for Windows (bpy 4.2) as *Install from
    Disk* does; the add-on runs its bundled core (the cp311 win_amd64 wheel, which Blender
    unpacks into the extension's site-packages) and a Smooth FFD modifier works."""
    ext = DIST / f"smooth_ffd-{_version()}-windows_x64.zip"
    if not ext.exists():
        _missing(f"dist/{ext.name}")
    _bpy_under_wine("check_install.py", ext, tmp_path)


def test_windows_repository_in_blender_under_wine(tmp_path):
    """dist/repository added to Blender for Windows as a remote repository (file:///Z:/...),
    synced, and the add-on installed from it: Blender picks the windows_x64 zip."""
    repo = DIST / "repository"
    if not (repo / "index.json").exists():
        _missing("dist/repository/index.json")
    _bpy_under_wine("check_repository.py", repo, tmp_path)


def _pe_imports(path):
    """{dll name: [imported names]} of a PE file (objdump -p)."""
    text = subprocess.run(["objdump", "-p", str(path)], capture_output=True, text=True, check=True).stdout
    imports, current = {}, None
    for line in text.splitlines():
        m = re.match(r"\s*DLL Name: (\S+)", line)
        if m:
            current = imports.setdefault(m.group(1).lower(), [])
            continue
        m = re.match(r"\s+[0-9a-f]+\s+(?:<none>\s+)?[0-9a-f]+\s+(\w+)$", line)
        if current is not None and m:
            current.append(m.group(1))
    return imports


def _declared(version):
    """The names CPython `version`'s public headers declare (PyAPI_FUNC / PyAPI_DATA)."""
    sys.path.insert(0, str(ROOT / "scripts"))
    try:
        import cross_wheels
    finally:
        sys.path.pop(0)
    return set(cross_wheels.header_exports(cross_wheels.header_dir(version, str(CACHE))))


@pytest.mark.parametrize("tag", ["310", "311", "312", "313"])
def test_windows_module_imports(tag, tmp_path):
    """A .pyd for CPython 3.XY loads only python3XY.dll and Windows' own DLLs (the UCRT and
    KERNEL32: no MinGW or C++ runtime DLL to ship), and every name it takes from the
    interpreter is one that version declares."""
    wheel = _wheel(f"cp{tag}", "win_amd64")
    with zipfile.ZipFile(wheel) as z:
        names = [n for n in z.namelist() if n.endswith(".pyd")]
        assert names == [f"smoothffd/_core.cp{tag}-win_amd64.pyd"], names
        (tmp_path / "m.pyd").write_bytes(z.read(names[0]))
    imports = _pe_imports(tmp_path / "m.pyd")
    assert f"python{tag}.dll" in imports, imports.keys()
    others = set(imports) - {f"python{tag}.dll"}
    assert all(d == "kernel32.dll" or d.startswith("api-ms-win-") for d in others), sorted(others)
    assert any(d.startswith("api-ms-win-crt-") for d in others), sorted(others)  # the UCRT
    version = f"{tag[0]}.{tag[1:]}"
    undeclared = set(imports[f"python{tag}.dll"]) - _declared(version)
    assert not undeclared, sorted(undeclared)
    dll = CACHE / "windows" / f"python{tag}" / f"python{tag}.dll"
    if dll.exists():   # and the real interpreter exports them
        exported = set(re.findall(r"^\s*\[\s*\d+\]\s+(\S+)$", subprocess.run(
            ["objdump", "-p", str(dll)], capture_output=True, text=True, check=True).stdout, flags=re.M))
        assert not set(imports[f"python{tag}.dll"]) - exported


# --- Linux aarch64 under qemu ----------------------------------------------------------------

def _arm64_root():
    root = CACHE / "arm64-root"
    if not (root / ".complete").exists() or not shutil.which("qemu-aarch64"):
        _missing(f"qemu-aarch64 and the Debian arm64 root ({root})")
    return root


def _qemu(root, args, site, cwd, timeout):
    env = {"PATH": "/usr/bin:/bin", "HOME": str(cwd), "PYTHONDONTWRITEBYTECODE": "1",
           "PYTHONPATH": f"{site}:/usr/lib/python3/dist-packages", "QEMU_LD_PREFIX": str(root)}
    if INSTALLED:
        env["SMOOTHFFD_TEST_INSTALLED"] = "1"
    # qemu-aarch64 runs the arm64 interpreter; the children it starts (the command line) are
    # arm64 programs too, so the interpreter is a wrapper that runs qemu again, and it is what
    # the interpreter sees as its own name (qemu's -0), hence sys.executable.
    wrapper = cwd / "python3"
    wrapper.write_text(f'#!/bin/sh\nexec qemu-aarch64 -L {root} -0 "$0" {root}/usr/bin/python3.11 "$@"\n')
    wrapper.chmod(0o755)
    return subprocess.run([str(wrapper), *args], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=timeout, stdin=subprocess.DEVNULL)


def test_arm64_wheel_under_qemu(tmp_path):
    root = _arm64_root()
    site = _install(_wheel("cp311", "manylinux_2_28_aarch64"), tmp_path)
    r, out = _run_case(lambda args: _qemu(root, args, site, tmp_path, 1200), tmp_path)
    assert "cpu_isa armv8-a" in r.stdout, r.stdout
    _compare_case(out, _case_here(tmp_path))


def test_arm64_core_suites_under_qemu(tmp_path):
    root = _arm64_root()
    site = _install(_wheel("cp311", "manylinux_2_28_aarch64"), tmp_path)
    _assert_suites_passed(_qemu(root, _core_suites_args(), site, tmp_path, 2400))


# --- macOS: checked without running -----------------------------------------------------------

LC_LOAD_DYLIB, LC_CODE_SIGNATURE, LC_BUILD_VERSION = 0xC, 0x1D, 0x32
LC_VERSION_MIN_MACOSX, LC_DYLD_INFO, LC_REQ_DYLD = 0x24, 0x22, 0x80000000
CPU = {"arm64": 0x0100000C, "x86_64": 0x01000007}
FLAT_LOOKUP = -2   # BIND_SPECIAL_DYLIB_FLAT_LOOKUP: looked up in the loading process


def _uleb(data, i):
    value = shift = 0
    while True:
        b = data[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, i


def _binds(data, start, size):
    """{symbol: library ordinal} from dyld's bind opcodes (what the loader resolves at load
    time, and against which library: 1.. the load commands' dylibs, -2 the whole process)."""
    out, i, end, ordinal, name = {}, start, start + size, 0, None
    while i < end:
        op, imm = data[i] & 0xF0, data[i] & 0x0F
        i += 1
        if op == 0x10:                       # SET_DYLIB_ORDINAL_IMM
            ordinal = imm
        elif op == 0x20:                     # SET_DYLIB_ORDINAL_ULEB
            ordinal, i = _uleb(data, i)
        elif op == 0x30:                     # SET_DYLIB_SPECIAL_IMM (sign-extended)
            ordinal = imm - 16 if imm else 0
        elif op == 0x40:                     # SET_SYMBOL_TRAILING_FLAGS_IMM + name
            j = data.index(b"\0", i)
            name, i = data[i:j].decode(), j + 1
        elif op in (0x60, 0x70, 0x80, 0xA0):  # SET_ADDEND_SLEB, SET_SEGMENT.., ADD_ADDR.., DO_BIND_ADD..
            _, i = _uleb(data, i)
            if op == 0xA0:
                out[name] = ordinal
        elif op == 0xC0:                     # DO_BIND_ULEB_TIMES_SKIPPING_ULEB
            _, i = _uleb(data, i)
            _, i = _uleb(data, i)
            out[name] = ordinal
        elif op in (0x90, 0xB0):             # DO_BIND, DO_BIND_ADD_ADDR_IMM_SCALED
            out[name] = ordinal
        # 0x00 DONE (ends one lazy-bind entry), 0x50 SET_TYPE_IMM: nothing to read
    return out


def _macho(data):
    """CPU type, file type, minimum macOS, dylibs, code signature, {bound symbol: ordinal}
    of a 64-bit Mach-O file."""
    magic, cputype, _, filetype, ncmds, _, _, _ = struct.unpack_from("<IiiIIIII", data, 0)
    assert magic == 0xFEEDFACF, hex(magic)
    off, dylibs, minos, signed, binds = 32, [], None, False, {}
    for _ in range(ncmds):
        cmd, size = struct.unpack_from("<II", data, off)
        base = cmd & ~LC_REQ_DYLD
        if base == LC_LOAD_DYLIB:
            name_off = struct.unpack_from("<I", data, off + 8)[0]
            dylibs.append(data[off + name_off: off + size].split(b"\0")[0].decode())
        elif cmd == LC_BUILD_VERSION:
            v = struct.unpack_from("<I", data, off + 12)[0]
            minos = (v >> 16, (v >> 8) & 0xFF)
        elif cmd == LC_VERSION_MIN_MACOSX:
            v = struct.unpack_from("<I", data, off + 8)[0]
            minos = (v >> 16, (v >> 8) & 0xFF)
        elif cmd == LC_CODE_SIGNATURE:
            signed = True
        elif base == LC_DYLD_INFO:
            f = struct.unpack_from("<10I", data, off + 8)
            for start, n in ((f[2], f[3]), (f[4], f[5]), (f[6], f[7])):   # bind, weak, lazy
                binds.update(_binds(data, start, n))
        off += size
    return cputype, filetype, minos, dylibs, signed, binds


@pytest.mark.parametrize("plat,arch,minos", [("macosx_11_0_arm64", "arm64", (11, 0)),
                                             ("macosx_10_15_x86_64", "x86_64", (10, 15))])
@pytest.mark.parametrize("tag", ["310", "311", "312", "313"])
def test_macos_module_is_loadable_as_built(tag, plat, arch, minos):
    wheel = _wheel(f"cp{tag}", plat)
    with zipfile.ZipFile(wheel) as z:
        names = [n for n in z.namelist() if n.endswith(".so")]
        assert names == [f"smoothffd/_core.cpython-{tag}-darwin.so"], names
        data = z.read(names[0])
    cputype, filetype, got_minos, dylibs, signed, binds = _macho(data)
    assert cputype == CPU[arch]
    assert filetype == 6   # MH_DYLIB: CPython's dlopen loads it as it loads a bundle
    assert got_minos == minos
    # Only the system's libraries: libSystem, and libc++ where the build links it.
    assert dylibs and set(dylibs) <= {"/usr/lib/libSystem.B.dylib", "/usr/lib/libc++.1.dylib"}, dylibs
    if arch == "arm64":
        assert signed, "arm64 macOS runs no unsigned code: the module needs its ad-hoc signature"
    # Python's names are looked up in the loading interpreter (flat lookup), and that CPython
    # declares each of them; everything else is bound to one of the system libraries above or
    # to the module itself (ordinal 0: its own weak C++ definitions).
    python = {n for n, o in binds.items() if o == FLAT_LOOKUP}
    others = {n for n, o in binds.items() if 0 <= o <= len(dylibs)}
    assert python and python | others == set(binds), sorted(set(binds) - python - others)[:10]
    assert all(n.startswith(("_Py", "__Py")) for n in python), sorted(python)[:10]
    assert not [n for n in others if n.startswith(("_Py", "__Py"))]
    undeclared = {n[1:] for n in python} - _declared(f"{tag[0]}.{tag[1:]}")
    assert not undeclared, sorted(undeclared)
