"""Runs the add-on's Blender scripts (tests/blender/check_*.py) in real Blenders and checks they pass.

Five Blenders, made by scripts/setup_blender.sh (outside the repository, in
${SMOOTHFFD_CACHE:-~/.cache/smoothffd}):

  blender-3.4  Debian's `blender` binary (3.4.1) in background mode
  bpy-4.2      PyPI bpy 4.2.x LTS in venv-bpy-4.2 (the 4.1-4.4 normals_split_custom_set path)
  bpy-4.5      PyPI bpy 4.5.x LTS in venv-bpy-4.5
  bpy-5.0      PyPI bpy 5.0.1 in venv-bpy-5.0
  bpy-5.1      PyPI bpy 5.1.0 (Python 3.13) in the trixie chroot, run through scripts/py313.sh

A test is skipped, with the reason, only when that Blender is not installed (or, for 5.1 from
the source tree, when the core has not been built for Python 3.13: scripts/build_py313.sh).
An installed one that is broken (bpy does not import, or it is another version) fails.
Each script prints PASS/FAIL lines and exits non-zero on failure.

What the scripts test: by default the source tree (addon/ and python/). The *installed* add-on
instead when packaged artefacts are found: SFFD_TEST_EXTENSION_ZIP (Blender 4.2+) and
SFFD_TEST_LEGACY_ZIP (3.4-4.1) name zips, or SFFD_TEST_DIST names a folder holding them
(default: dist/ when it has them; SFFD_TEST_DIST=source forces the source tree). Then every
run gets a fresh private user profile, the zip is installed into it (sffd_testlib reads
SFFD_TEST_ADDON_ZIP) and neither addon/ nor python/ is on any path.
SFFD_TEST_BLENDERS="bpy-4.5 bpy-5.1" restricts the runs to some Blenders.
"""
import functools
import glob
import json
import os
import shutil
import subprocess
import zipfile

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, "tests", "blender")
CACHE = os.environ.get("SMOOTHFFD_CACHE") or os.path.join(os.path.expanduser("~"), ".cache",
                                                           "smoothffd")
CHROOT = os.environ.get("SMOOTHFFD_CHROOT") or os.path.join(CACHE, "trixie")
VENV313 = "/opt/venv-bpy-5.1"   # inside the chroot
TIMEOUT = 900

# name: (major, minor) the environment must report
BLENDERS = {"blender-3.4": (3, 4), "bpy-4.2": (4, 2), "bpy-4.5": (4, 5), "bpy-5.0": (5, 0),
            "bpy-5.1": (5, 1)}
_only = os.environ.get("SFFD_TEST_BLENDERS", "").replace(",", " ").split()
RUNNERS = [b for b in BLENDERS if not _only or b in _only]
SETUP_HINT = "run scripts/setup_blender.sh"


# --- which add-on is tested: the source tree or installed zips ------------------------------

def _classify(path):
    """'extension' (blender_manifest.toml at the zip's top), 'legacy' (a smooth_ffd/ package
    folder) or None."""
    try:
        names = zipfile.ZipFile(path).namelist()
    except (OSError, zipfile.BadZipFile):
        return None
    if "blender_manifest.toml" in names:
        return "extension"
    if "smooth_ffd/__init__.py" in names:
        return "legacy"
    return None


@functools.lru_cache(maxsize=None)
def artefacts():
    """{'extension': zip, 'legacy': zip} to install, or {} to test the source tree."""
    found = {k: os.environ.get(f"SFFD_TEST_{k.upper()}_ZIP") for k in ("extension", "legacy")}
    found = {k: os.path.abspath(v) for k, v in found.items() if v}
    if found:
        return found
    dist = os.environ.get("SFFD_TEST_DIST", os.path.join(ROOT, "dist"))
    if dist in ("", "0", "source") or not os.path.isdir(dist):
        return {}
    zips = sorted(glob.glob(os.path.join(dist, "*.zip")))
    # One extension zip and one legacy zip per platform: this machine's (linux_x64).
    for z in sorted(zips, key=lambda z: ("linux_x64" not in os.path.basename(z).lower(), z)):
        kind = _classify(z)
        if kind and kind not in found:
            found[kind] = os.path.abspath(z)
    return found


def installed_mode():
    """Whether the installed add-on is tested. The test command (SMOOTHFFD_TEST_INSTALLED=1)
    tests what scripts/package.sh made: without its zips in dist/ the run fails, rather than
    quietly testing the source tree instead."""
    if artefacts():
        return True
    if os.environ.get("SMOOTHFFD_TEST_INSTALLED") == "1":
        pytest.fail("SMOOTHFFD_TEST_INSTALLED=1, but dist/ has no add-on zip: scripts/package.sh "
                    "must make them")
    return False


def _zip_for(runner):
    kind = "legacy" if BLENDERS[runner] < (4, 2) else "extension"
    z = artefacts().get(kind)
    if z is None:   # a packaging that made one zip and not the other is broken
        pytest.fail(f"testing installed add-ons ({artefacts()}), but there is no {kind} zip")
    return z


def _source_paths():
    return {os.path.realpath(os.path.join(ROOT, p)) for p in ("python", "addon", ".")}


def _strip_source(pythonpath):
    """PYTHONPATH without the source tree's python/ and addon/ (a relative entry is dropped
    when it names them from pytest's working directory or from ROOT)."""
    keep = [p for p in (pythonpath or "").split(os.pathsep)
            if p and not {os.path.realpath(p), os.path.realpath(os.path.join(ROOT, p))}
            & _source_paths()]
    return os.pathsep.join(keep) or None


@pytest.fixture
def blender_env(tmp_path):
    """Environment for one Blender run: a private user profile (never the real Blender
    configuration) and, when installed artefacts are tested, the zip to install. Returns a
    function runner -> {name: value or None (unset)}."""
    profile = tmp_path / "profile"

    def env_for(runner):
        env = {"BLENDER_USER_RESOURCES": str(profile),
               "BLENDER_USER_SCRIPTS": str(profile / "scripts"),
               "BLENDER_USER_CONFIG": str(profile / "config"),
               "BLENDER_USER_EXTENSIONS": str(profile / "extensions")}
        if installed_mode():
            env.update({"SFFD_TEST_ADDON_ZIP": _zip_for(runner),
                        "PYTHONPATH": _strip_source(os.environ.get("PYTHONPATH"))})
        return env
    return env_for


# --- the Blenders ---------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _probe(runner):
    """(command prefix, None) when this Blender is usable, else (None, why not)."""
    if runner == "blender-3.4":
        exe = shutil.which("blender")
        if exe is None:
            return None, f"Debian's Blender is not installed ({SETUP_HINT})"
        return [exe, "-b", "--factory-startup", "--python-exit-code", "1", "--python"], None
    if runner == "bpy-5.1":
        if not os.path.lexists(os.path.join(CHROOT + VENV313, "bin", "python")):   # a link into the chroot
            return None, f"no Python 3.13 chroot with bpy 5.1 at {CHROOT} ({SETUP_HINT})"
        if not installed_mode() and not glob.glob(
                os.path.join(ROOT, "python", "smoothffd", "_core.cpython-313-*.so")):
            return None, "the core is not built for Python 3.13 (run scripts/build_py313.sh)"
        prefix = ["bash", os.path.join(ROOT, "scripts", "py313.sh"), VENV313 + "/bin/python"]
    else:
        py = os.path.join(CACHE, "venv-" + runner, "bin", "python")
        if not os.path.exists(py):
            return None, f"no {runner} venv at {os.path.dirname(os.path.dirname(py))} ({SETUP_HINT})"
        prefix = [py]
    return prefix, None


@functools.lru_cache(maxsize=None)
def _broken(runner, prefix):
    """Why an installed Blender cannot run the scripts (bpy does not import, or it is another
    version than the one set up), or None."""
    if runner == "blender-3.4":
        code = "import bpy, sys; print(*bpy.app.version[:2]); sys.stdout.flush()"
        cmd = list(prefix[:-1]) + ["--python-expr", code]
    else:
        cmd = list(prefix) + ["-c", "import bpy; print(*bpy.app.version[:2])"]
    probe = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, timeout=TIMEOUT)
    if probe.returncode != 0:
        return f"bpy does not import in {runner}: {(probe.stdout + probe.stderr).strip()[-500:]}"
    words = [w for line in probe.stdout.splitlines() for w in [line.split()]
             if len(w) == 2 and all(x.isdigit() for x in w)]
    got = tuple(int(v) for v in words[-1]) if words else None
    if got != BLENDERS[runner]:
        return f"{runner} has Blender {got}, not {BLENDERS[runner]} ({SETUP_HINT})"
    return None


def blender_cmd(runner, script, *args):
    """The command running `script` (path relative to tests/blender, or absolute) in `runner`.
    Skips only when that Blender is not installed; one that is installed but broken (bpy does
    not import, or reports another version) fails the test."""
    prefix, why = _probe(runner)
    if prefix is None:
        pytest.skip(why)
    broken = _broken(runner, tuple(prefix))
    if broken:
        pytest.fail(broken)
    script = os.path.join(SCRIPTS, script)
    if runner == "blender-3.4":
        return prefix + [script, "--", *args]
    return prefix + [script, *args]


def _run(cmd, timeout=TIMEOUT, extra_env=None):
    # Installed mode: not even the working directory is the source tree.
    cwd = (extra_env or {}).get("BLENDER_USER_RESOURCES") if installed_mode() else ROOT
    env = dict(os.environ)
    for k, v in (extra_env or {}).items():
        if v is None:
            env.pop(k, None)
        else:
            env[k] = v
    env.setdefault("PYTHONUNBUFFERED", "1")
    if cwd:
        os.makedirs(cwd, exist_ok=True)
    # errors="replace": Blender's log quotes what it could not parse, bytes and all.
    proc = subprocess.run(cmd, capture_output=True, text=True, errors="replace", timeout=timeout,
                          env=env, cwd=cwd or ROOT)
    out = proc.stdout + proc.stderr
    # Shown with `pytest -s`, and in the failure message otherwise.
    print(out)
    return proc.returncode, out


def _summary(out):
    lines = [l for l in out.splitlines() if l.startswith(("FAIL", "PASS")) or " passed, " in l]
    return "\n".join(lines[-60:])


@pytest.mark.parametrize("runner", RUNNERS)
def test_update_timing_printed(runner, blender_env):
    """The live-update timing table (printed, not asserted: speed is a benchmark's business): one
    live update of a 46.8k-triangle sphere at viewport levels 4 and 10 beside Lattice +
    Subdivision Surface levels 2 and 3, split into deform / mesh write / normals. Checks only
    that every row and both comparisons were measured; `pytest -s` shows the numbers."""
    # run_bench.py loads the add-on through sffd_testlib, then runs blender_scenes/bench_addon.py.
    rc, out = _run(blender_cmd(runner, "run_bench.py", "1", "noexact"),
                   extra_env=blender_env(runner))
    assert rc == 0, out[-3000:]
    for row in ("Lattice + Subsurf level 2", "Lattice + Subsurf level 3", "Smooth FFD level 4",
                "Smooth FFD level 10", "speedup level 4 vs", "speedup level 10 vs"):
        assert row in out, f"{row!r} missing:\n{out[-3000:]}"
    assert "deform " in out and "mesh write " in out and "normals " in out


@pytest.mark.parametrize("runner", RUNNERS)
@pytest.mark.parametrize("script", ["check_parity.py", "check_normals.py", "check_live.py",
                                    "check_render.py", "check_robustness.py", "check_data.py",
                                    "check_stack.py", "check_linked.py", "check_lattice_weights.py",
                                    "check_stack_input.py", "check_obj_import.py",
                                    "check_adaptive.py"])
def test_blender_script(runner, script, blender_env):
    rc, out = _run(blender_cmd(runner, script), extra_env=blender_env(runner))
    assert rc == 0, f"{runner} {script} failed (rc={rc}):\n{_summary(out)}\n--- tail ---\n{out[-3000:]}"
    assert " passed, 0 failed" in out


def test_command_line_render(tmp_path, blender_env):
    """`blender -b file.blend -a` renders every frame at the render level with that frame's
    lattice (the add-on enabled by --python, as an installed add-on would be)."""
    runner = "blender-3.4"
    if runner not in RUNNERS:
        pytest.skip("SFFD_TEST_BLENDERS leaves out blender-3.4")
    env = blender_env(runner)
    blend = str(tmp_path / "scene.blend")
    rc, out = _run(blender_cmd(runner, "check_render.py", blend), extra_env=env)
    assert rc == 0 and os.path.exists(blend), _summary(out)
    record = str(tmp_path / "frames.json")
    cmd = [shutil.which("blender"), "-b", blend, "--python-exit-code", "1",
           "--python", os.path.join(SCRIPTS, "cli_render_check.py"),
           "-o", str(tmp_path / "frame_####"), "-a", "--", record]
    rc, out = _run(cmd, extra_env=env)
    assert rc == 0, out[-3000:]
    frames = json.load(open(record))
    assert [f["frame"] for f in frames] == [1, 2, 3]
    for f in frames:
        assert f["tris"] == f["patches"] * 3 ** 2, f   # render level 3 in check_render.py
        assert f["err"] < 1e-5 * 1.6, f                     # lattice size 1.6
        assert f["status"].startswith("OK"), f


@pytest.fixture(scope="module")
def addon_zip():
    """The zips users install exist only as dist/'s artefacts (scripts/package.sh)."""
    if not installed_mode():
        pytest.skip("installing the add-on as users do needs dist/'s zips (run scripts/package.sh)")
    return None


@pytest.mark.parametrize("runner", RUNNERS)
def test_install_zip(runner, addon_zip, blender_env):
    """The zip installs (legacy add-on on 3.4, extension on 4.2+) and runs its bundled core."""
    env = blender_env(runner)
    zip_path = addon_zip or env["SFFD_TEST_ADDON_ZIP"]
    env.update({"SFFD_TEST_ADDON_ZIP": None,
                "PYTHONPATH": _strip_source(os.environ.get("PYTHONPATH"))})
    rc, out = _run(blender_cmd(runner, "check_install.py", zip_path), extra_env=env)
    assert rc == 0 and " passed, 0 failed" in out, _summary(out) + out[-2000:]


@pytest.mark.parametrize("runner", [r for r in RUNNERS if BLENDERS[r] >= (4, 2)])
def test_install_from_repository(runner, addon_zip, blender_env, tmp_path):
    """dist/repository as a studio serves it (a shared folder here, file://): added once as a
    remote repository, synced, and the add-on installed from it by Blender's own operators,
    which pick this platform's zip from index.json."""
    repo = os.path.join(os.path.dirname(artefacts()["extension"]), "repository")
    if not os.path.isfile(os.path.join(repo, "index.json")):
        pytest.fail(f"{repo}/index.json is missing: scripts/package.sh makes it")
    env = blender_env(runner)
    env.update({"SFFD_TEST_ADDON_ZIP": None,
                "PYTHONPATH": _strip_source(os.environ.get("PYTHONPATH"))})
    rc, out = _run(blender_cmd(runner, "check_repository.py", repo), extra_env=env)
    assert rc == 0 and " passed, 0 failed" in out, _summary(out) + out[-2000:]
