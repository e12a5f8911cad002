"""CUDA optional at run time.

The module `_core` needs no CUDA library: the CUDA backend is libsmoothffd_cuda.so next to it
(CUDA runtime linked statically, cuBLAS loaded with dlopen for the "cublas" path only), loaded
the first time CUDA is asked for. These tests run without a GPU (here, CI): the ELF files'
dependencies, the package with the CUDA toolkit hidden (a private mount namespace with an
empty tmpfs over it), the loader's messages when the library is missing or broken, and what
cuda_status() says on a machine without a driver. On a GPU machine they check the other side:
with the toolkit hidden the fused path still runs and the cublas path says what it needs.
"""

import os
import re
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import smoothffd
from smoothffd import _core

PKG = Path(_core.__file__).resolve().parent
CORE = Path(_core.__file__).resolve()
LIB = PKG / "libsmoothffd_cuda.so"
ROOT = Path(__file__).resolve().parents[1]

CUDA_LIBS = re.compile(r"lib(cudart|cublas|cublasLt|cuda)\.so")

# What cuda_status() may say when CUDA cannot be used (cuda_proxy/cuda_proxy.cpp, cuda/device_status.cpp).
REASONS = ("not installed", "failed to load", "built from other smoothffd sources", "no NVIDIA driver",
           "driver is too old", "no CUDA device", "no kernels", "cudaGetDeviceCount failed",
           "context creation failed", "CUDA initialization failed", "did not report")


def needed(path):
    out = subprocess.run(["readelf", "-d", str(path)], capture_output=True, text=True, check=True).stdout
    return re.findall(r"\(NEEDED\)\s+Shared library: \[([^\]]+)\]", out), re.findall(r"\((?:RUNPATH|RPATH)\)\s+.*\[([^\]]*)\]", out)


def readelf_available():
    return shutil.which("readelf") is not None


# ----------------------------------------------------------------------------- ELF files

@pytest.mark.skipif(not readelf_available(), reason="readelf (binutils) not installed")
def test_core_needs_no_cuda_library():
    libs, paths = needed(CORE)
    assert not [n for n in libs if CUDA_LIBS.search(n)], f"_core needs {libs}"
    assert not [p for p in paths if "cuda" in p], f"_core has a CUDA run path: {paths}"


@pytest.mark.skipif(not readelf_available(), reason="readelf (binutils) not installed")
@pytest.mark.skipif(not LIB.exists(), reason=f"CUDA backend not built ({LIB} missing: no nvcc at build time)")
def test_cuda_library_links_cuda_statically():
    libs, paths = needed(LIB)
    # The runtime is static, cuBLAS is dlopened, the driver is loaded by the runtime.
    assert not [n for n in libs if CUDA_LIBS.search(n)], f"libsmoothffd_cuda.so needs {libs}"
    assert not [n for n in libs if "python" in n], f"the CUDA library must not need Python: {libs}"
    # Its only export is the C entry point (everything else is local).
    syms = subprocess.run(["readelf", "--dyn-syms", "-W", str(LIB)], capture_output=True, text=True,
                          check=True).stdout
    exported = set()
    for line in syms.splitlines():
        f = line.split()
        if len(f) >= 8 and f[4] in ("GLOBAL", "WEAK") and f[6] != "UND":
            exported.add(f[7])
    assert exported == {"sffd_cuda_api_v1"}, exported


# ----------------------------------------------------------------------------- loader messages

def small_problem():
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 0.8 - 0.2
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = smoothffd.Mesh(V, F)
    lat = smoothffd.BSplineLattice.identity([-0.5] * 3, [0.9] * 3, shape=(4, 4, 4))
    lat = lat.with_control_points(lat.control_points + 0.02)
    return mesh, lat


def test_cuda_status_says_why():
    """On a machine without a usable GPU (here, CI), cuda_status() says precisely why, an
    evaluator raises RuntimeError with that reason, device='cuda' raises and device='auto'
    runs on the CPU."""
    usable, why = smoothffd.cuda_status()
    assert isinstance(usable, bool) and isinstance(why, str) and why
    if usable:
        pytest.skip(f"a usable CUDA device exists: {why}")
    assert any(r in why for r in REASONS), why
    if not Path("/dev/nvidiactl").exists() and LIB.exists():
        # No driver here: the library loads (static runtime) and finds no libcuda.so.1.
        assert "no NVIDIA driver" in why or "no CUDA device" in why, why
    mesh, lat = small_problem()
    plan = smoothffd.Deformer(mesh, lat, level=3, device="cpu").plan
    with pytest.raises(RuntimeError, match="no usable CUDA"):
        _core.CudaEvaluator(plan)
    with pytest.raises(RuntimeError, match="no usable CUDA device"):
        smoothffd.Deformer(mesh, lat, level=3, device="cuda")
    d = smoothffd.Deformer(mesh, lat, level=3, device="auto")
    assert d.device == "cpu"
    assert np.isfinite(d.deform().positions).all()


def test_evaluators_offer_the_same_frames():
    """CpuEvaluator and CudaEvaluator offer the same frames (eval/evaluator.hpp): the same
    methods with the same arguments, incremental frames and last_frame included, so that
    smoothffd.Deformer never asks which backend it holds."""
    for name in ("evaluate", "evaluate_compact", "evaluate_positions"):
        sigs = {cls.__name__: getattr(cls, name).__doc__.splitlines()[0].replace(cls.__name__, "Evaluator")
                for cls in (_core.CpuEvaluator, _core.CudaEvaluator)}
        assert sigs["CpuEvaluator"] == sigs["CudaEvaluator"], sigs
        assert "incremental: bool = False" in sigs["CpuEvaluator"], sigs
    for cls in (_core.CpuEvaluator, _core.CudaEvaluator):
        assert isinstance(cls.last_frame, property), cls


def package_copy(tmp_path, library=None):
    """The package (with its built _core) copied to tmp_path, with `library` (bytes) as
    libsmoothffd_cuda.so, or without one."""
    dst = tmp_path / "smoothffd"
    shutil.copytree(PKG, dst, ignore=shutil.ignore_patterns("__pycache__", "libsmoothffd_cuda.so"))
    if library is not None:
        (dst / "libsmoothffd_cuda.so").write_bytes(library)
    return tmp_path


def run_python(code, pythonpath, env_extra=None, prefix=()):
    env = dict(os.environ, PYTHONPATH=str(pythonpath))
    env.update(env_extra or {})
    return subprocess.run(list(prefix) + [sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, env=env, timeout=300)


CHECK_CPU = """
    import numpy as np, smoothffd
    from smoothffd import _core
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 0.8 - 0.2
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = smoothffd.Mesh(V, F)
    lat = smoothffd.BSplineLattice.identity([-0.5] * 3, [0.9] * 3, shape=(4, 4, 4))
    lat = lat.with_control_points(lat.control_points + 0.02)
    r = smoothffd.deform(mesh, lat, level=4, device="cpu")
    assert np.isfinite(r.positions).all() and len(r.triangles) >= 4 * 16
    usable, why = smoothffd.cuda_status()
    print("STATUS", usable, why)
    print("COMPILED", _core.cuda_compiled)
    auto = smoothffd.Deformer(mesh, lat, level=3, device="auto")
    print("AUTO", auto.device)
    try:
        smoothffd.Deformer(mesh, lat, level=3, device="cuda")
        print("CUDA ok")
    except RuntimeError as e:
        print("CUDA RuntimeError", e)
"""


def test_library_missing(tmp_path):
    out = run_python(CHECK_CPU, package_copy(tmp_path))
    assert out.returncode == 0, out.stderr
    assert "STATUS False the CUDA backend is not installed" in out.stdout, out.stdout
    assert "COMPILED False" in out.stdout and "AUTO cpu" in out.stdout
    assert re.search(r"CUDA RuntimeError device='cuda': no usable CUDA device \(the CUDA backend is not installed",
                     out.stdout), out.stdout


def test_library_broken(tmp_path):
    out = run_python(CHECK_CPU, package_copy(tmp_path, library=b"not an ELF file\n" * 8))
    assert out.returncode == 0, out.stderr
    assert re.search(r"STATUS False the CUDA backend \S+libsmoothffd_cuda.so failed to load: .*(ELF|too short)",
                     out.stdout), out.stdout
    assert "AUTO cpu" in out.stdout and "CUDA RuntimeError" in out.stdout


# ----------------------------------------------------------------------------- toolkit hidden

def toolkit_dirs():
    """The CUDA toolkit's directories (/usr/local/cuda is a link to /usr/local/cuda-X.Y)."""
    dirs = set()
    if os.path.islink("/usr/local/cuda") or os.path.isdir("/usr/local/cuda"):
        dirs.add(os.path.realpath("/usr/local/cuda"))
    for p in Path("/usr/local").glob("cuda-*"):
        if p.is_dir() and not p.is_symlink():
            dirs.add(str(p))
    return sorted(dirs)


def unshare_works():
    if os.geteuid() != 0 or shutil.which("unshare") is None:
        return False, "needs root and unshare (util-linux)"
    r = subprocess.run(["unshare", "-m", "sh", "-c", "mount -t tmpfs none /mnt"], capture_output=True, text=True)
    if r.returncode != 0:
        return False, f"unshare -m / mount not permitted here: {r.stderr.strip()}"
    return True, ""


HIDDEN = CHECK_CPU + """
    import ctypes
    for name in ("libcudart.so.13", "libcublas.so.13", "libcublasLt.so.13"):
        try:
            ctypes.CDLL(name)
            print("VISIBLE", name)
        except OSError:
            print("HIDDEN", name)
    if usable:  # a GPU machine: the fused path needs no toolkit, the cublas path says what it needs
        import numpy as np
        plan = smoothffd.Deformer(mesh, lat, level=4, device="cpu").plan
        vals = np.ascontiguousarray(lat.control_values().reshape(-1, 3), dtype=np.float32)
        pg, _, _ = _core.CudaEvaluator(plan, "fused").evaluate(vals)
        pc, _, _ = _core.CpuEvaluator(plan).evaluate(vals)
        print("FUSED", float(np.abs(pg - pc).max()))
        try:
            _core.CudaEvaluator(plan, "cublas")
            print("CUBLAS ok")
        except RuntimeError as e:
            print("CUBLAS RuntimeError", e)
"""


def test_import_and_cpu_without_cuda_toolkit():
    """With every CUDA toolkit directory hidden under an empty tmpfs (private mount
    namespace): the package imports, deforms on the CPU, cuda_status() says why CUDA is
    unusable (or, on a GPU machine, the fused path still runs and the cublas path says it
    needs libcublas), device='auto' falls back and device='cuda' raises clearly."""
    ok, why = unshare_works()
    if not ok:
        pytest.skip(why)
    dirs = toolkit_dirs()
    if not dirs:
        pytest.skip("no CUDA toolkit under /usr/local to hide")
    mounts = " && ".join(f"mount -t tmpfs -o ro none '{d}'" for d in dirs)
    script = f"{mounts} && exec \"$0\" \"$@\""
    py = str(CORE.parent.parent)
    out = run_python(HIDDEN, py, prefix=("unshare", "-m", "sh", "-c", script))
    assert out.returncode == 0, out.stdout + out.stderr
    print(out.stdout)
    assert "HIDDEN libcudart.so.13" in out.stdout, f"the toolkit was not hidden ({dirs}): {out.stdout}"
    status = re.search(r"STATUS (True|False) (.*)", out.stdout)
    assert status, out.stdout
    if status.group(1) == "False":
        assert any(r in status.group(2) for r in REASONS), status.group(2)
        assert "AUTO cpu" in out.stdout
        assert "CUDA RuntimeError device='cuda': no usable CUDA device" in out.stdout, out.stdout
    else:
        assert "AUTO cuda" in out.stdout and "CUDA ok" in out.stdout
        fused = float(re.search(r"FUSED (\S+)", out.stdout).group(1))
        assert fused <= 1e-5
        if "HIDDEN libcublas.so.13" in out.stdout:
            assert "CUBLAS RuntimeError the cublas path needs libcublas.so.13 from the CUDA toolkit" in out.stdout, \
                out.stdout
