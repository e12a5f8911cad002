"""The shipped artefacts in dist/ (scripts/package.sh), checked as a user receives them:
every wheel's tag and contents, what each Linux ELF file needs (glibc 2.28 and nothing else
of the machine's), the same CUDA library in every Linux x86-64 wheel, the extensions'
manifests and wheels (one zip per platform), the static extension repository, the legacy
zips' vendored core, the sdist, and the runtime dispatch of the shipped module
(scripts/check_isa.py). tests/test_platforms.py runs the other platforms' wheels. Skipped when dist/ holds no build, except in the artefact run of
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
PYTHONS = ("cp310", "cp311", "cp312", "cp313")
# Blender's platform names, the wheel platform tags and module file names of each.
PLATFORMS = {
    "linux-x64": ("manylinux_2_28_x86_64", "_core.cpython-{v}-x86_64-linux-gnu.so"),
    "linux-arm64": ("manylinux_2_28_aarch64", "_core.cpython-{v}-aarch64-linux-gnu.so"),
    "windows-x64": ("win_amd64", "_core.cp{v}-win_amd64.pyd"),
    "macos-arm64": ("macosx_11_0_arm64", "_core.cpython-{v}-darwin.so"),
    "macos-x64": ("macosx_10_15_x86_64", "_core.cpython-{v}-darwin.so"),
}
# What a Linux module may need from the system: the C library's parts (glibc 2.28 and older).
LINUX_LIBS = {"libc.so.6", "libm.so.6", "libpthread.so.0", "libdl.so.2", "librt.so.1",
              "ld-linux-x86-64.so.2", "ld-linux-aarch64.so.1"}


def _one(pattern):
    found = sorted(glob.glob(os.path.join(DIST, pattern)))
    if not found:
        if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
            pytest.fail(f"dist/{pattern} is missing: scripts/package.sh must make it")
        pytest.skip(f"no dist/{pattern} (run scripts/package.sh)")
    assert len(found) == 1, found
    return found[0]


def _wheel(py, platform="linux-x64"):
    return _one(f"smoothffd-*-{py}-{py}-{PLATFORMS[platform][0]}.whl")


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


@pytest.mark.parametrize("platform", list(PLATFORMS))
@pytest.mark.parametrize("py", PYTHONS)
def test_wheel_contents_and_tag(py, platform, tmp_path):
    tag, module = PLATFORMS[platform]
    whl = _wheel(py, platform)
    with zipfile.ZipFile(whl) as z:
        names = z.namelist()
        wheel_meta = z.read(next(n for n in names if n.endswith(".dist-info/WHEEL"))).decode()
        metadata = z.read(next(n for n in names if n.endswith(".dist-info/METADATA"))).decode()
        record = z.read(next(n for n in names if n.endswith(".dist-info/RECORD"))).decode()
    assert f"Tag: {py}-{py}-{tag}" in wheel_meta
    assert "Root-Is-Purelib: false" in wheel_meta
    assert re.search(r"^Requires-Python: >=3\.10$", metadata, flags=re.M), metadata[:500]
    assert f"Version: {_version()}" in metadata
    core = f"smoothffd/{module.format(v=py[2:])}"
    assert core in names, names
    # Every file of the package, each once, and RECORD lists them all.
    for f in ("__init__.py", "deform.py", "cli.py", "io.py", "data/vase.obj", "data/vase_bend.json"):
        assert f"smoothffd/{f}" in names, f
    assert sorted(line.split(",")[0] for line in record.splitlines()) == sorted(names)
    # Nothing of the development tree: no other Python's module, no caches.
    assert [n for n in names if "_core" in n] == [core], names
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")], names
    cuda = "smoothffd/libsmoothffd_cuda.so"
    assert (cuda in names) == (platform == "linux-x64" and _has_cuda()), names
    if platform.startswith("linux"):
        for name in [core] + ([cuda] if cuda in names else []):
            path = _extract(whl, name, tmp_path)
            needed, has_path = _needed(path)
            assert set(needed) <= LINUX_LIBS, (name, needed)   # no C++ runtime, no CUDA, no Python
            assert not has_path, f"{name} carries an RPATH/RUNPATH (a path of the build machine)"
            assert _max_glibc(path) <= (2, 28), (name, _max_glibc(path))


def _has_cuda():
    """Whether package.sh built the CUDA backend (it does where nvcc is found)."""
    return bool(shutil.which("nvcc") or os.path.exists("/usr/local/cuda/bin/nvcc"))


def test_linux_x64_wheels_ship_the_same_cuda_library():
    if not _has_cuda():
        pytest.skip("no nvcc on this machine: the wheels were built without the CUDA backend")
    digests = {}
    for py in PYTHONS:
        with zipfile.ZipFile(_wheel(py)) as z:
            digests[py] = hashlib.sha256(z.read("smoothffd/libsmoothffd_cuda.so")).hexdigest()
    assert len(set(digests.values())) == 1, digests


def _auditwheel():
    exe = shutil.which("auditwheel") or os.path.expanduser("~/.cache/smoothffd/venv-package/bin/auditwheel")
    if not os.path.exists(exe):
        if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
            pytest.fail("auditwheel is missing: scripts/package.sh installs it")
        pytest.skip("auditwheel is not installed (scripts/package.sh installs it)")
    return exe


@pytest.mark.parametrize("platform", ["linux-x64", "linux-arm64"])
@pytest.mark.parametrize("py", PYTHONS)
def test_auditwheel_agrees(py, platform):
    out = subprocess.run([_auditwheel(), "show", _wheel(py, platform)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    text = " ".join(out.stdout.split())
    # The tag the wheel carries, or an older glibc's (auditwheel names the oldest it meets).
    arch = PLATFORMS[platform][0].split("_", 3)[3]
    m = re.search(rf'consistent with the following platform tag: "manylinux_2_(\d+)_{arch}"', text)
    assert m and int(m.group(1)) <= 28, text
    assert "external shared libraries are required" not in text, text


def test_shipped_module_dispatch_is_clean(tmp_path):
    """No AVX2 code outside the x86-64-v3 copy in the module users get, and the copy exists."""
    whl = _wheel("cp311")
    with zipfile.ZipFile(whl) as z:
        core = next(n for n in z.namelist() if n.startswith("smoothffd/_core"))
    path = _extract(whl, core, tmp_path)
    r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "check_isa.py"), path,
                        "--require-v3"], capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def _ext_zip(platform):
    return _one(f"smooth_ffd-{_version()}-{platform.replace('-', '_')}.zip")


@pytest.mark.parametrize("platform", list(PLATFORMS))
def test_extension_zip(platform):
    ext = _ext_zip(platform)
    with zipfile.ZipFile(ext) as z:
        names = z.namelist()
        manifest = tomllib.loads(z.read("blender_manifest.toml").decode())
        # --split-platforms keeps the source manifest (every platform, every wheel) and adds
        # what this zip serves as [build.generated], which Blender reads in its place.
        generated = manifest["build"]["generated"]
        assert generated["platforms"] == [platform]
        assert manifest["blender_version_min"] >= "4.2.0"
        wheels = generated["wheels"]
        # This platform's wheels for Blender's Pythons: 3.11 (4.2-5.0) and 3.13 (5.1 and later).
        assert sorted(os.path.basename(w) for w in wheels) == sorted(
            os.path.basename(_wheel(py, platform)) for py in ("cp311", "cp313"))
        for w in wheels:
            assert w.startswith("./wheels/") and w[2:] in names, (w, names)
            assert z.read(w[2:]) == open(os.path.join(DIST, os.path.basename(w)), "rb").read()
        # The add-on imports the core from the wheels: no copy of it, no sys.path edit.
        assert not [n for n in names if n.endswith((".so", ".pyd"))], names
        for n in names:
            if n.endswith(".py"):
                src = z.read(n).decode()
                assert not re.search(r"sys\.path\s*(\.\s*(insert|append|extend)\b|\[|\+=|=[^=])", src), \
                    f"{n} edits sys.path"
    assert manifest["version"] == _version()


def test_repository_index():
    """dist/repository: Blender's index.json lists every platform's zip with its hash and size."""
    index_path = os.path.join(DIST, "repository", "index.json")
    if not os.path.exists(index_path):
        _one("repository/index.json")
    import json
    index = json.load(open(index_path))
    entries = index["data"]
    assert {e["id"] for e in entries} == {"smooth_ffd"}
    assert sorted(p for e in entries for p in e["platforms"]) == sorted(PLATFORMS)
    for e in entries:
        assert e["version"] == _version()
        path = os.path.join(DIST, "repository", e["archive_url"].lstrip("./"))
        data = open(path, "rb").read()
        assert e["archive_size"] == len(data)
        assert e["archive_hash"] == "sha256:" + hashlib.sha256(data).hexdigest()
        assert data == open(_ext_zip(e["platforms"][0]), "rb").read()


@pytest.mark.parametrize("platform", list(PLATFORMS))
def test_legacy_zip(platform):
    leg = _one(f"smooth_ffd-*-legacy-{platform.replace('-', '_')}.zip")
    with zipfile.ZipFile(leg) as z:
        names = z.namelist()
        init = z.read("smooth_ffd/__init__.py").decode()
    assert "bl_info" in init
    assert "smooth_ffd/blender_manifest.toml" not in names   # a legacy add-on on every version
    module = PLATFORMS[platform][1]
    # Blender 3.4-4.0 (official builds: Python 3.10) and 4.1 / Debian's 3.4.1 (3.11): the
    # wheels' own modules, byte for byte, side by side.
    for py in ("cp310", "cp311"):
        with zipfile.ZipFile(_wheel(py, platform)) as w, zipfile.ZipFile(leg) as z:
            for n in (module.format(v=py[2:]), "deform.py"):
                assert z.read("smooth_ffd/_vendor/smoothffd/" + n) == w.read("smoothffd/" + n), n
    assert len([n for n in names if "/_core" in n]) == 2, names
    assert ("smooth_ffd/_vendor/smoothffd/libsmoothffd_cuda.so" in names) == (platform == "linux-x64" and _has_cuda())


def test_sdist():
    """The sdist holds what a source build needs and nothing of a build."""
    sdist = _one(f"smoothffd-{_version()}.tar.gz")
    import tarfile
    with tarfile.open(sdist) as t:
        names = {n.split("/", 1)[1] for n in t.getnames() if "/" in n}
    for f in ("pyproject.toml", "CMakeLists.txt", "native/CMakeLists.txt", "native/python/bindings.cpp",
              "python/smoothffd/__init__.py", "python/smoothffd/data/vase.obj", "README.md", "PKG-INFO"):
        assert f in names, f
    assert not [n for n in names if n.startswith(("build/", "dist/", "out/")) or n.endswith((".so", ".pyd"))]


def _version():
    src = open(os.path.join(ROOT, "python", "smoothffd", "__init__.py")).read()
    return re.search(r'__version__ = "(.*)"', src).group(1)
