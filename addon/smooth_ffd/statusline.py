"""A modifier's status line (its Status input) and Render > Lock Interface, which the status
speaks of."""
import bpy

from . import compat, frames, linked, objects, state


def set_status(obj, mod, text, result_frames=None, wrote_result=False, report=None):
    """Writes the status and the frames the result belongs to (nodegroup: [from, to); None
    leaves them; state.NEVER: no valid result, the source is shown) only when they change,
    and re-tags the object for them.

    wrote_result: the result mesh was just written, which re-evaluates the object anyway
    (its modifier depends on the result object). Tagging the object too would tag its mesh
    data on 3.4, and the post handler would then re-read the source mesh for nothing.
    report: print the text to the console (default: when no valid result is left).
    A linked modifier's status is never written (linked.py): the console says it once."""
    if obj.library is not None:
        linked.report(obj, mod)
        return
    changed = False
    if compat.get_modifier_input(mod, "Status") != text:
        compat.set_modifier_input(mod, "Status", text)
        changed = not wrote_result
    if result_frames is not None and frames.set_frames(mod, "Result", result_frames):
        changed = True
    if changed:
        obj.update_tag()
    if report if report is not None else result_frames == state.NEVER:
        print(f"Smooth FFD [{obj.name} / {mod.name}]: {text}")


def set_ok(obj, mod, st, base, result_frames, frame, wrote_result=False, scene=None):
    """base: (head, tail) of the "OK ..." text; the frame goes between them when the result
    belongs to this frame only (a file opened without the add-on then says which frame it
    shows), and scene warnings after."""
    st.status_base = base
    head, tail = base
    text = f"{head}, frame {frame:g}, {tail}" if result_frames != state.ALWAYS \
        else f"{head}, {tail}"
    notes = lock_notes(scene)
    if notes:
        text += "".join(f" \u2014 {n}" for n in notes)
    set_status(obj, mod, text, result_frames, wrote_result=wrote_result, report=False)


def fail(obj, mod, st, message):
    """An error: the status says it, the modifier shows its source."""
    if st is not None:
        st.last_key = None
        st.status_base = None
    try:
        set_status(obj, mod, "Error: " + message, state.NEVER)
    except Exception as e:   # even the status write failed (e.g. group removed)
        print(f"Smooth FFD [{obj.name}]: {message} (status not written: {e})")


def baked_text(mod):
    host = objects.bake_object(mod)
    if host is None:
        return "Baked"
    first, last = host.get(state.RANGE_KEY, (0, 0))
    return (f"Baked: frames {first}-{last} show the bake (level "
            f"{host.get(state.LEVEL_KEY, '?')}); edits show there after Clear Bake")


def set_baked(obj, mod, scene):
    """The status of a modifier whose bake covers the frame shown."""
    text = baked_text(mod) + "".join(f" \u2014 {n}" for n in lock_notes(scene))
    set_status(obj, mod, text, report=False)


# --- Render > Lock Interface ------------------------------------------------------------
# Renders started from a window run in a job thread, and so do the handlers that compute the
# render-level result there (render_pre, frame_change_post): they write Blender data, which
# is safe only while the interface is locked (RenderSettings.use_lock_interface; a
# background render runs in the main thread and needs nothing). The add-on turns the
# setting on in one place only, add_smooth_ffd in a window, and says so (operator report,
# console, status); it never turns it on behind the user's back (file load, render), and
# while it is off, the status says what renders from the window do without it.

def window_session():
    """Whether Blender runs with windows (renders from a window use a job thread). Tests
    replace it to check the window behaviour in background mode."""
    return not bpy.app.background


def ensure_render_lock(scene):
    """Turns on Lock Interface for a window session (not in background); returns the
    message saying so, or None when nothing changed."""
    if not window_session() or scene is None or scene.render.use_lock_interface:
        return None
    scene.render.use_lock_interface = True
    state.lock_turned_on.add(scene.name_full)
    message = (f"Smooth FFD turned on Render > Lock Interface in scene {scene.name!r}: the "
               f"add-on computes the render-level result while a render runs")
    print(message)
    return message


def lock_notes(scene=None):
    """What the status says about Lock Interface (nothing in background mode)."""
    scene = scene if scene is not None else bpy.context.scene
    if not window_session() or scene is None:
        return []
    if not scene.render.use_lock_interface:
        return ["warning: Render > Lock Interface is off: renders started from this window "
                "keep the viewport result of the frame shown, and other frames render the "
                "source mesh"]
    if scene.name_full in state.lock_turned_on:
        return ["Render > Lock Interface turned on by Smooth FFD"]
    return []
