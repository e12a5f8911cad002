"""The shipped artefacts in dist/ (scripts/package.sh), checked as a user receives them:
wheel tags, what each ELF file needs, the same CUDA library in every wheel, the extension's
manifest and wheels, the legacy zip's vendored core, and the runtime dispatch of the shipped
module (scripts/check_isa.py). Skipped when dist/ holds no build, except in the artefact run of
scripts/test.sh (SMOOTHFFD_TEST_INSTALLED=1), where a missing artefact fails."""
import glob
import hashlib
import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DIST = os.path.join(ROOT, "dist")
TAG = "manylinux_2_34_x86_64"
PYTHONS = ("cp311", "cp313")


def _one(pattern):
    found = sorted(glob.glob(os.path.join(DIST, pattern)))
    if not found:
        if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
            pytest.fail(f"dist/{pattern} is missing: scripts/package.sh must make it")
        pytest.skip(f"no dist/{pattern} (run scripts/package.sh)")
    assert len(found) == 1, found
    return found[0]


def _wheel(py):
    return _one(f"smoothffd-*-{py}-{py}-*.whl")


def _extract(zip_path, name, tmp_path):
    with zipfile.ZipFile(zip_path) as z:
        out = tmp_path / os.path.basename(name)
        out.write_bytes(z.read(name))
    return str(out)


def _needed(path):
    out = subprocess.run(["readelf", "-d", path], capture_output=True, text=True, check=True).stdout
    return re.findall(r"\(NEEDED\)\s+Shared library: \[(.*)\]", out), "RPATH" in out or "RUNPATH" in out


def _max_glibc(path):
    out = subprocess.run(["objdump", "-T", path], capture_output=True, text=True, check=True).stdout
    versions = [tuple(map(int, v.split("."))) for v in re.findall(r"\bGLIBC_(\d+\.\d+(?:\.\d+)?)", out)]
    return max(versions)


@pytest.mark.parametrize("py", PYTHONS)
def test_wheel_contents_and_tag(py, tmp_path):
    whl = _wheel(py)
    assert os.path.basename(whl).endswith(f"-{py}-{py}-{TAG}.whl"), whl
    with zipfile.ZipFile(whl) as z:
        names = z.namelist()
        wheel_meta = z.read(next(n for n in names if n.endswith(".dist-info/WHEEL"))).decode()
    assert f"Tag: {py}-{py}-{TAG}" in wheel_meta
    core = [n for n in names if re.fullmatch(rf"smoothffd/_core\.cpython-{py[2:]}-x86_64-linux-gnu\.so", n)]
    assert len(core) == 1, names
    assert "smoothffd/libsmoothffd_cuda.so" in names
    # Nothing of the development tree: no other Python's module, no caches.
    assert not [n for n in names if "_core" in n and n not in core], names
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")], names
    for name in (core[0], "smoothffd/libsmoothffd_cuda.so"):
        path = _extract(whl, name, tmp_path)
        needed, has_path = _needed(path)
        assert not [n for n in needed if "cuda" in n or "cublas" in n or "python" in n], (name, needed)
        assert not has_path, f"{name} carries an RPATH/RUNPATH (a path of the build machine)"
        assert _max_glibc(path) <= (2, 34), (name, _max_glibc(path))


def test_wheels_ship_the_same_cuda_library():
    digests = {}
    for py in PYTHONS:
        with zipfile.ZipFile(_wheel(py)) as z:
            digests[py] = hashlib.sha256(z.read("smoothffd/libsmoothffd_cuda.so")).hexdigest()
    assert len(set(digests.values())) == 1, digests


@pytest.mark.skipif(shutil.which("auditwheel") is None and not os.path.exists(
    os.path.expanduser("~/.cache/smoothffd/venv-package/bin/auditwheel")),
    reason="auditwheel is not installed (scripts/package.sh installs it)")
@pytest.mark.parametrize("py", PYTHONS)
def test_auditwheel_agrees(py):
    exe = shutil.which("auditwheel") or os.path.expanduser("~/.cache/smoothffd/venv-package/bin/auditwheel")
    out = subprocess.run([exe, "show", _wheel(py)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())
    assert f'consistent with the following platform tag: "{TAG}"' in text, text


def test_shipped_module_dispatch_is_clean(tmp_path):
    """No AVX2 code outside the x86-64-v3 copy in the module users get, and the copy exists."""
    whl = _wheel("cp311")
    with zipfile.ZipFile(whl) as z:
        core = next(n for n in z.namelist() if n.startswith("smoothffd/_core"))
    path = _extract(whl, core, tmp_path)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "check_isa.py"), path,
                        "--require-v3"], capture_output=True, text=True)
    if r.returncode == 2:
        pytest.skip(f"check_isa.py cannot check: {r.stdout}{r.stderr}")
    assert r.returncode == 0, r.stdout + r.stderr


def test_extension_zip():
    ext = _one("smooth_ffd-*-linux_x64.zip")
    with zipfile.ZipFile(ext) as z:
        names = z.namelist()
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
        assert manifest["platforms"] == ["linux-x64"]
        assert manifest["blender_version_min"] >= "4.2.0"
        wheels = manifest["wheels"]
        assert sorted(os.path.basename(w) for w in wheels) == sorted(
            os.path.basename(_wheel(py)) for py in PYTHONS)
        for w in wheels:
            assert w.startswith("./wheels/") and w[2:] in names, (w, names)
            assert z.read(w[2:]) == open(os.path.join(DIST, os.path.basename(w)), "rb").read()
        # The add-on imports the core from the wheels: no copy of it, no sys.path edit.
        assert not [n for n in names if n.endswith(".so")], names
        for n in names:
            if n.endswith(".py"):
                src = z.read(n).decode()
                assert not re.search(r"sys\.path\s*(\.\s*(insert|append|extend)\b|\[|\+=|=[^=])", src), \
                    f"{n} edits sys.path"
    assert manifest["version"] == _version()


def test_legacy_zip():
    leg = _one("smooth_ffd-*-legacy.zip")
    with zipfile.ZipFile(leg) as z:
        names = z.namelist()
        init = z.read("smooth_ffd/__init__.py").decode()
    assert "bl_info" in init
    assert "smooth_ffd/blender_manifest.toml" not in names   # a legacy add-on on every version
    assert "smooth_ffd/_vendor/smoothffd/_core.cpython-311-x86_64-linux-gnu.so" in names
    assert "smooth_ffd/_vendor/smoothffd/libsmoothffd_cuda.so" in names
    # The vendored module is the cp311 wheel's, byte for byte.
    with zipfile.ZipFile(_wheel("cp311")) as w, zipfile.ZipFile(leg) as z:
        for n in ("_core.cpython-311-x86_64-linux-gnu.so", "libsmoothffd_cuda.so", "deform.py"):
            assert z.read("smooth_ffd/_vendor/smoothffd/" + n) == w.read("smoothffd/" + n), n


def _version():
    src = open(os.path.join(ROOT, "python", "smoothffd", "__init__.py")).read()
    return re.search(r'__version__ = "(.*)"', src).group(1)
