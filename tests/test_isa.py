"""Install anywhere: the module runs on any x86-64 CPU since Nehalem (x86-64-v2), and the CPU
evaluator's per-frame code takes its AVX2 + FMA copy (x86-64-v3) where the CPU has it
(runtime dispatch, native/smoothffd/core/isa.hpp).

* the two paths agree to float rounding (in this process);
* scripts/check_isa.py: no code outside the v3 copy needs more than x86-64-v2;
* under qemu-user (Debian: apt-get install qemu-user) a small deformation runs with
  `-cpu Nehalem` (no AVX: baseline path) and `-cpu Haswell` (AVX2 + FMA: v3 path) and matches
  this process's result. A module built with -march=native dies there with SIGILL.

The module under test is the one this process imports: `python_cmd` and `module_root` (below)
say which interpreter and import path the subprocesses get; point them at an installed wheel
to test that instead of the development build.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import smoothffd
from smoothffd import _core

ROOT = Path(__file__).resolve().parent.parent
CHECK_ISA = ROOT / "scripts" / "check_isa.py"

# The deformation each run computes (here, and in the qemu subprocesses): a small octahedron in
# a randomly displaced 4^3 quadratic B-spline lattice, level 4, on the CPU.
DEFORM = r'''
import numpy as np
import smoothffd
from smoothffd import _core


def make_deformer():
    c, r = 0.5, 0.4
    pos = np.array([[c + r, c, c], [c - r, c, c], [c, c + r, c], [c, c - r, c], [c, c, c + r],
                    [c, c, c - r]], dtype=np.float64)
    faces = np.array([[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5],
                      [0, 3, 5]])
    mesh = smoothffd.Mesh(pos, faces)
    lat = smoothffd.BSplineLattice.identity((0, 0, 0), (1, 1, 1), shape=(4, 4, 4), degree=(2, 2, 2))
    rng = np.random.default_rng(1)
    lat = lat.with_control_points(lat.control_points + 0.08 * rng.standard_normal(lat.control_points.shape))
    return smoothffd.Deformer(mesh, lat, level=4, device="cpu", threads=1)


def deform_small():
    d = make_deformer()
    res = d.deform()
    out = np.concatenate([res.positions.ravel(), res.corner_normals.ravel()]).astype(np.float32)
    return out, {"cpu_isa": _core.cpu_isa(), "evaluator_isa": d._evaluator.isa}


def adaptive_small():
    """The adaptive frame's bytes (positions, normals, triangles): its decisions and points are
    compiled once, without contraction, so they are the same on every CPU, bit for bit."""
    d = make_deformer()
    r = smoothffd.Deformer(d.mesh, d.lattice, tolerance=2e-3, device="cpu", threads=1).deform()
    return np.concatenate([a.ravel().view(np.uint8) for a in (r.positions, r.corner_normals, r.triangles)])
'''

MAIN = r'''
import json, sys
out, info = deform_small()
np.save(sys.argv[1], out)
np.save(sys.argv[2], adaptive_small())
print("ISA " + json.dumps(info))
'''


@pytest.fixture(scope="module")
def python_cmd():
    """The interpreter the subprocesses run (the one running the tests)."""
    return [sys.executable]


@pytest.fixture(scope="module")
def module_root():
    """PYTHONPATH for the subprocesses: where this process imported smoothffd from."""
    return str(Path(smoothffd.__file__).resolve().parent.parent)


@pytest.fixture(scope="module")
def native_result():
    ns = {}
    exec(DEFORM, ns)
    return ns["deform_small"]() + (ns["adaptive_small"](),)


def _close(a, b, tol=1e-5):
    assert a.shape == b.shape
    return float(np.max(np.abs(a.astype(np.float64) - b.astype(np.float64)))) <= tol


@pytest.fixture(scope="module")
def deformer():
    ns = {}
    exec(DEFORM, ns)
    return ns["make_deformer"]()


def test_evaluator_reports_and_forces_its_path(deformer):
    isa = _core.cpu_isa()
    assert isa in ("x86-64-v2", "x86-64-v3"), f"{isa}: not a shippable build (SMOOTHFFD_ARCH=native?)"
    assert deformer._evaluator.isa == isa
    assert _core.CpuEvaluator(deformer.plan, 1).isa == isa
    assert _core.CpuEvaluator(deformer.plan, 1, isa="auto").isa == isa
    assert _core.CpuEvaluator(deformer.plan, 1, isa="x86-64-v2").isa == "x86-64-v2"
    with pytest.raises(ValueError):
        _core.CpuEvaluator(deformer.plan, 1, isa="x86-64-v9")
    with pytest.raises(TypeError):  # keyword only
        _core.CpuEvaluator(deformer.plan, 1, "x86-64-v2")


def test_paths_agree_in_process(deformer, native_result):
    """The baseline path, forced, against the default one (v3 on an AVX2 machine)."""
    values = np.ascontiguousarray(deformer.lattice.control_values().reshape(-1, 3), dtype=np.float32)
    out, _, _ = native_result
    for isa in ("x86-64-v2", _core.cpu_isa()):
        pos, nrm, _ = _core.CpuEvaluator(deformer.plan, 2, isa=isa).evaluate(values)
        assert _close(np.concatenate([pos.ravel(), nrm.ravel()]), out), isa


def test_static_isa_check():
    """scripts/check_isa.py on the module when it has a symbol table, else on libsmoothffd_core.a
    of its build (SMOOTHFFD_BUILD_DIR, default build/): the link inputs, where a leaked AVX2
    copy of a shared function shows whichever copy the linker keeps."""
    if not shutil.which("objdump"):
        pytest.skip("objdump not found (binutils)")
    module = Path(_core.__file__)
    targets = []
    syms = subprocess.run(["objdump", "-t", str(module)], capture_output=True, text=True).stdout
    if "no symbols" not in syms and ".text" in syms:
        targets.append(module)
    lib = Path(os.environ.get("SMOOTHFFD_BUILD_DIR", ROOT / "build")) / "native" / "libsmoothffd_core.a"
    if not targets and lib.exists():  # a stripped module: its build's link inputs instead
        targets.append(lib)
    if not targets:
        pytest.skip(f"{module.name} is stripped and no libsmoothffd_core.a of its build found "
                    "(SMOOTHFFD_BUILD_DIR)")
    r = subprocess.run([sys.executable, str(CHECK_ISA), *map(str, targets)], capture_output=True, text=True)
    assert r.returncode == 0, (r.stdout + r.stderr + "\n(a build dir configured before x86-64-v2 became "
                               "the default keeps SMOOTHFFD_ARCH=native in its cache: reconfigure it with "
                               "-DSMOOTHFFD_ARCH=x86-64-v2)")


QEMU = shutil.which("qemu-x86_64")


@pytest.mark.skipif(QEMU is None, reason="qemu-x86_64 not installed (apt-get install qemu-user)")
@pytest.mark.parametrize("cpu, isa", [("Nehalem", "x86-64-v2"), ("Haswell", "x86-64-v3")])
def test_under_emulated_cpu(cpu, isa, tmp_path, python_cmd, module_root, native_result):
    script = tmp_path / "deform_small.py"
    script.write_text(DEFORM + MAIN)
    out_file = tmp_path / "out.npy"
    # numpy's OpenBLAS is told the emulated CPU: an OPENBLAS_CORETYPE inherited from the host
    # (Haswell, say) would make numpy itself run AVX2 kernels under -cpu Nehalem and die.
    env = {k: v for k, v in os.environ.items() if not k.startswith("OPENBLAS_")}
    env.update(PYTHONPATH=module_root, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1",
               OPENBLAS_CORETYPE=cpu)
    r = subprocess.run([QEMU, "-cpu", cpu, *python_cmd, str(script), str(out_file), str(tmp_path / "adaptive.npy")],
                       capture_output=True, text=True, env=env, timeout=600)
    assert r.returncode == 0, (f"qemu -cpu {cpu}: exit {r.returncode} (-4: SIGILL, an instruction "
                               f"the CPU lacks)\n{r.stdout}\n{r.stderr[-3000:]}")
    info = json.loads(r.stdout.split("ISA ", 1)[1].splitlines()[0])
    assert info == {"cpu_isa": isa, "evaluator_isa": isa}
    out, _, adaptive = native_result
    assert _close(np.load(out_file), out), f"-cpu {cpu} differs from the native result"
    assert np.array_equal(np.load(tmp_path / "adaptive.npy"), adaptive), \
        f"-cpu {cpu}: the adaptive frame differs from the native one"
