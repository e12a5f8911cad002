"""Adaptive counts held over frames, so that those frames share one topology (adaptive
tessellation otherwise gives each frame the triangles its own deformation needs).

Two kinds, both the largest counts over their frames (np.maximum of the core's
Deformer.tessellation_counts), passed to the core as deform(hold=...):
- a frame range the user holds (holdframes.hold: Object > Smooth FFD > Hold Tessellation...),
  saved on the hidden result object (custom property HOLD_KEY), for the render's and the
  viewport's settings each;
- a render's motion-blur shutter (holdframes.hold_shutter, from render_pre), in memory only:
  the subframes Blender renders the frame's motion from get one topology.
A hold applies only to the plan and the tessellation setting it was computed for (other
patches or another tolerance setting: the update is not held, and the status says so)."""
import uuid

import numpy as np

from . import inputs

HOLD_KEY = "smooth_ffd_hold"   # result object -> {"render"/"viewport": held counts, frames}
NAMES = ("edge_segments", "patch_level")


def which(render):
    return "render" if render else "viewport"


def store(ro, kind, first, last, plan_token, setting, counts):
    """Saves the counts held over frames first..last (inclusive) for kind ('render' or
    'viewport')."""
    data = dict(ro.get(HOLD_KEY, {}))
    data[kind] = {"from": int(first), "to": int(last), "plan": plan_token,
                  "setting": repr(setting), "serial": uuid.uuid4().hex,
                  **{n: np.asarray(counts[n], np.int32).tolist() for n in NAMES}}
    ro[HOLD_KEY] = data


def clear(ro):
    """Removes the held frame ranges; returns whether there were any."""
    had = HOLD_KEY in ro
    if had:
        del ro[HOLD_KEY]
    return had


def held_range(ro, kind):
    """(first, last) of the frames held for kind, or None."""
    entry = ro.get(HOLD_KEY, {}).get(kind) if ro is not None else None
    return None if entry is None else (int(entry["from"]), int(entry["to"]))


def covers(ro, kind, frame):
    """Whether a held range of kind covers this frame."""
    return ro is not None and _entry(ro, kind, frame) is not None


def _entry(ro, kind, frame):
    entry = ro.get(HOLD_KEY, {}).get(kind)
    if entry is None or not entry["from"] - 0.5 <= frame < entry["to"] + 0.5:
        return None
    return entry


def stamp(ro, st, render, frame):
    """What holds this frame (part of the update's key: a new hold recomputes it). A
    render's shutter hold comes first: it covers every subframe of the frame rendered."""
    sh = st.shutter if render else None
    if sh is not None and sh[0][0] <= frame <= sh[0][1]:
        return ("shutter",) + sh[0] + (sh[1], repr(sh[2]))
    entry = _entry(ro, which(render), frame)
    if entry is not None:
        return ("frames", entry["serial"])
    return None


def lookup(ro, st, render, frame, plan_token, setting):
    """(counts or None, a note for the status or None) for this frame's update."""
    sh = st.shutter if render else None
    if sh is not None and sh[0][0] <= frame <= sh[0][1]:
        (lo, hi), token, sh_setting, counts = sh
        if token == plan_token and sh_setting == setting:
            return counts, f"counts held over the shutter {lo:g}-{hi:g}"
        return None, "counts over the shutter not used (other patches: motion blur may drop)"
    entry = _entry(ro, which(render), frame)
    if entry is not None:
        span = f"frames {entry['from']}-{entry['to']}"
        if entry["plan"] != plan_token or entry["setting"] != repr(setting):
            return None, (f"counts held over {span} not used (other patches or another "
                          f"tessellation setting: hold again)")
        key = entry["serial"]
        cached = st.hold_cache.get(key)
        if cached is None:
            cached = {n: np.asarray(entry[n], np.int32) for n in NAMES}
            st.hold_cache = {key: cached}
        return cached, f"counts held over {span}"
    return None, None


def motion_blur(scene):
    """Whether the scene renders motion blur (Cycles and, from 4.2, EEVEE: render settings;
    EEVEE before 4.2: its own)."""
    eevee = getattr(scene, "eevee", None)
    return bool(scene.render.use_motion_blur or getattr(eevee, "use_motion_blur", False))


def shutter(scene):
    """(first, last) frame times of the shutter of the frame shown."""
    frame = scene.frame_current + scene.frame_subframe
    length = float(scene.render.motion_blur_shutter)
    position = getattr(scene.render, "motion_blur_position", None) or \
        getattr(getattr(scene, "cycles", None), "motion_blur_position", None) or "CENTER"
    if position == 'START':
        return frame, frame + length
    if position == 'END':
        return frame - length, frame
    return frame - length / 2, frame + length / 2


def maximum(a, b):
    return b if a is None else {n: np.maximum(a[n], b[n]) for n in NAMES}


def token(plan_key):
    return inputs.digest(plan_key)
