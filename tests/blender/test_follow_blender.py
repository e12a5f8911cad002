"""Runs check_follow.py (plans that follow a moving source: an Armature and animated shape
keys, Wave and Displace modifiers, an imported rig above Smooth FFD; their pieces held during
playback and over a motion-blur shutter) in each Blender, as tests/test_blender.py runs the other check_*.py
scripts: the same Blenders (SFFD_TEST_BLENDERS), the same private user profile, the source
tree or the installed zips."""
import pytest

from test_blender import RUNNERS, _run, _summary, blender_cmd, blender_env  # noqa: F401


@pytest.mark.parametrize("runner", RUNNERS)
def test_plans_follow_the_pose(runner, blender_env):  # noqa: F811
    rc, out = _run(blender_cmd(runner, "check_follow.py"), extra_env=blender_env(runner))
    assert rc == 0, f"{runner} check_follow.py failed (rc={rc}):\n{_summary(out)}\n--- tail ---\n{out[-3000:]}"
    assert " passed, 0 failed" in out
    # Every frame after the first followed the plan (no new one), on the six scenes; playback
    # and a motion-blur render held the pieces.
    assert out.count(" 5 follows, ") == 6, _summary(out)
    assert "held pieces: playback held the pieces on 5 of 5 follows" in out, _summary(out)
    assert "held wave: 5 of 5 follows held the pieces" in out, _summary(out)
