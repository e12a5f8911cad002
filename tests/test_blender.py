"""Runs the add-on's Blender scripts (tests/blender/) in real Blenders and checks they pass.

Two Blenders: Debian's `blender` binary (3.4.1) in background mode, and PyPI `bpy` (4.5+) in
build/venv-bpy (made by scripts/setup_blender.sh). A test is skipped, with the reason, only when
that Blender is not installed. Each script prints PASS/FAIL lines and exits non-zero on failure.
"""
import json
import os
import shutil
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCRIPTS = os.path.join(ROOT, "tests", "blender")
VENV_PY = os.path.join(ROOT, "build", "venv-bpy", "bin", "python")
TIMEOUT = 900


def _blender_cmd(script, *args):
    exe = shutil.which("blender")
    if exe is None:
        pytest.skip("Debian's Blender is not installed (run scripts/setup_blender.sh)")
    return [exe, "-b", "--factory-startup", "--python-exit-code", "1",
            "--python", os.path.join(SCRIPTS, script), "--", *args]


def _bpy_cmd(script, *args):
    if not os.path.exists(VENV_PY):
        pytest.skip("no bpy venv at build/venv-bpy (run scripts/setup_blender.sh)")
    probe = subprocess.run([VENV_PY, "-c", "import bpy"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip(f"bpy is not installed in build/venv-bpy: {probe.stderr.strip()[-200:]}")
    return [VENV_PY, os.path.join(SCRIPTS, script), *args]


RUNNERS = {"blender": _blender_cmd, "bpy": _bpy_cmd}


def _run(cmd, timeout=TIMEOUT):
    env = dict(os.environ)
    env.setdefault("PYTHONUNBUFFERED", "1")
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=env,
                          cwd=ROOT)
    out = proc.stdout + proc.stderr
    # Shown with `pytest -s`, and in the failure message otherwise.
    print(out)
    return proc.returncode, out


def _summary(out):
    lines = [l for l in out.splitlines() if l.startswith(("FAIL", "PASS")) or " passed, " in l]
    return "\n".join(lines[-60:])


@pytest.mark.parametrize("runner", sorted(RUNNERS))
@pytest.mark.parametrize("script", ["test_parity.py", "test_normals.py", "test_live.py",
                                    "test_render.py"])
def test_blender_script(runner, script):
    rc, out = _run(RUNNERS[runner](script))
    assert rc == 0, f"{runner} {script} failed (rc={rc}):\n{_summary(out)}\n--- tail ---\n{out[-3000:]}"
    assert " passed, 0 failed" in out


def test_command_line_render(tmp_path):
    """`blender -b file.blend -a` renders every frame at the render level with that frame's
    lattice (the add-on enabled by --python, as an installed add-on would be)."""
    blend = str(tmp_path / "scene.blend")
    rc, out = _run(_blender_cmd("test_render.py", blend))
    assert rc == 0 and os.path.exists(blend), _summary(out)
    record = str(tmp_path / "frames.json")
    cmd = [shutil.which("blender"), "-b", blend, "--python-exit-code", "1",
           "--python", os.path.join(SCRIPTS, "cli_render_check.py"),
           "-o", str(tmp_path / "frame_####"), "-a", "--", record]
    rc, out = _run(cmd)
    assert rc == 0, out[-3000:]
    frames = json.load(open(record))
    assert [f["frame"] for f in frames] == [1, 2, 3]
    for f in frames:
        assert f["tris"] == f["patches"] * 3 ** 2, f   # render level 3 in test_render.py
        assert f["err"] < 1e-5 * 1.6, f                     # lattice size 1.6
        assert f["status"].startswith("OK"), f
