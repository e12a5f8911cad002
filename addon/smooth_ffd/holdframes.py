"""Computes the adaptive counts held over frames (holds.py): a frame range the user holds,
and a render's motion-blur shutter. Each evaluates the scene on those frames (as the bake
does, with the handlers muted) and takes the largest counts the core's
Deformer.tessellation_counts gives there."""
import threading

import bpy

from . import holds, inputs, objects, pipeline, state

SHUTTER_SAMPLES = 9   # subframes sampled over the shutter: Cycles' motion steps 1-3 among them


def _counts_over(obj, mod, scene, times, kinds):
    """{kind: (plan token, setting, counts)} the largest counts over the (frame, subframe)
    times, for kinds ('render', 'viewport') whose settings are adaptive. Raises RuntimeError
    when the frames do not share one plan (their patches differ)."""
    found = {}
    for f, sub in times:
        scene.frame_set(f, subframe=sub)
        depsgraph = bpy.context.evaluated_depsgraph_get()
        for kind in kinds:
            try:
                got = pipeline.tessellation_counts(
                    obj, mod, state.Pass(depsgraph, scene=scene, render=kind == "render"))
            except inputs.SmoothFFDError as e:
                raise RuntimeError(f"Smooth FFD hold: frame {f + sub:g}: {e}") from None
            if got is None:
                continue
            token, setting, counts = got
            have = found.get(kind)
            if have is not None and (have[0] != token or have[1] != setting):
                raise RuntimeError(
                    f"Smooth FFD hold: frame {f + sub:g} has other patches than the frames "
                    f"before (the lattice object, the object's mesh or the stack above "
                    f"changes): one topology cannot be held over these frames")
            found[kind] = (token, setting, holds.maximum(None if have is None else have[2],
                                                         counts))
    return found


def hold(obj, mod, frame_start, frame_end, scene=None):
    """Holds the adaptive counts of frames frame_start..frame_end (inclusive), for the
    render's and the viewport's settings where they are adaptive: those frames then share
    one topology each (a cache, a bake, motion blur over the range). Returns the kinds held.
    Raises ValueError when neither setting is adaptive, RuntimeError when the frames do not
    share one plan. The caller then updates the modifiers for the frame shown."""
    frame_start, frame_end = int(frame_start), int(frame_end)
    if frame_end < frame_start:
        raise ValueError(f"frame_end {frame_end} is before frame_start {frame_start}")
    scene = scene if scene is not None else bpy.context.scene
    ro = objects.result_object(obj, mod)
    old = (scene.frame_current, scene.frame_subframe)
    try:
        with state.muted():
            found = _counts_over(obj, mod, scene,
                                 [(f, 0.0) for f in range(frame_start, frame_end + 1)],
                                 ("render", "viewport"))
    finally:
        with state.muted():
            scene.frame_set(old[0], subframe=old[1])
    if not found:
        raise ValueError("Smooth FFD hold: neither the viewport nor the render tessellation "
                         "is adaptive (Tolerance or Screen): a level has one topology already")
    holds.clear(ro)
    for kind, (token, setting, counts) in found.items():
        holds.store(ro, kind, frame_start, frame_end, token, setting, counts)
    st = state.of_result(ro)
    if st is not None:
        st.last_key = None
    obj.update_tag()
    return sorted(found)


def clear(obj, mod):
    """Lets every frame take its own counts again; returns whether anything was held."""
    ro = objects.result_object(obj, mod, create=False)
    if ro is None or not holds.clear(ro):
        return False
    st = state.of_result(ro)
    if st is not None:
        st.last_key = None
    obj.update_tag()
    return True


def hold_shutter(scene, modifiers):
    """Before a render with motion blur: each modifier whose render tessellation is adaptive,
    and whose frame no held range covers, gets the counts over the frame's shutter (in memory,
    for this render). Only where the scene may be evaluated on other frames here: the main
    thread (background and command-line renders); a render from a window runs in a job thread
    and gets none (hold the frames instead). Returns {(object name, modifier name): note}
    for the modifiers that got none because of an error."""
    notes = {}
    if not holds.motion_blur(scene) or threading.current_thread() is not threading.main_thread():
        return notes
    lo, hi = holds.shutter(scene)
    # The frame rendered first, as the render evaluates it first: a moving input is clipped
    # there and its shutter's other times hold those pieces (plans.hold_pieces), so that the
    # counts are all per one sub-mesh, the one the render's evaluations then hold.
    times = [(scene.frame_current, scene.frame_subframe)]
    for i in range(SHUTTER_SAMPLES):
        t = lo + (hi - lo) * i / (SHUTTER_SAMPLES - 1)
        f = int(t // 1)
        if abs(t - (scene.frame_current + scene.frame_subframe)) > 1e-6:
            times.append((f, t - f))
    old = (scene.frame_current, scene.frame_subframe)
    try:
        with state.muted():
            for obj, mod in modifiers:
                ro = objects.result_object(obj, mod, create=False)
                if holds.covers(ro, "render", lo) and holds.covers(ro, "render", hi):
                    continue   # a held range covers the whole shutter
                try:
                    found = _counts_over(obj, mod, scene, times, ("render",))
                except Exception as e:   # never stops the render: that frame is not held
                    notes[(obj.name, mod.name)] = f"{type(e).__name__}: {e}"
                    continue
                if "render" not in found:
                    continue
                ro = objects.result_object(obj, mod)
                st = state.of_result(ro, create=True)
                token, setting, counts = found["render"]
                st.shutter = ((lo, hi), token, setting, counts)
                st.last_key = None
    finally:
        with state.muted():
            scene.frame_set(old[0], subframe=old[1])
    return notes


def end_shutter(modifiers):
    """After a render: no shutter holds are kept."""
    for obj, mod in modifiers:
        st = objects.state_of(obj, mod)
        if st is not None and st.shutter is not None:
            st.shutter = None
            st.last_key = None
