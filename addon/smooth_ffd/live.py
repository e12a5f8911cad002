"""Live editing (4.5+ viewport). While a result keeps changing (results for new inputs less
than state.SETTLE seconds apart: a lattice point dragged, an animation playing), the core
computes positions only and Blender shades the dense mesh from its own geometry, smooth with
the result's sharp edges, as the 3.4-4.4 viewport always does: well under half the core's
time. SETTLE seconds after the last change a timer (handlers.settle) brings the exact
normals. Never for render, Apply, Bake, forced updates or Exact Normals, nor in background
mode (no timers run there: scripts and farms get exact results); state.LIVE True/False
forces it on/off (tests).

The clock is time.perf_counter, read here only (now): tests replace this module's `time`."""
import time

import bpy

from . import compat, state


def now():
    return time.perf_counter()


def enabled():
    return (not bpy.app.background) if state.LIVE is None else state.LIVE


def positions_only(st, exact_key, exact, render, settings, at):
    """Whether this update computes positions only: new inputs within SETTLE of the last
    change, or the same inputs as a positions-only result of less than SETTLE ago (the post
    handler after an early computation: it stays until the settle timer)."""
    return (exact and not render and not settings.exact and compat.CHEAP_EXACT_NORMALS
            and enabled() and at - st.changed_at < state.SETTLE
            and (exact_key != st.exact_key or st.last_key != exact_key))


def schedule_settle(at):
    """The settle timer runs SETTLE after `at` (the handlers register it after their round,
    in a window)."""
    state.settle_after[0] = at + state.SETTLE
    state.pending_timers.add("settle")


def wait():
    """Seconds until the settle update is due (<= 0: now)."""
    return state.settle_after[0] - now()


def playing():
    """Whether an animation is playing in one of the windows (never in background mode)."""
    wm = getattr(bpy.context, "window_manager", None)
    if wm is None or bpy.app.background:
        return False
    return any(w.screen is not None and w.screen.is_animation_playing for w in wm.windows)
