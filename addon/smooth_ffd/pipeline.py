"""The one update path of a Smooth FFD modifier: read its inputs (gather) -> find or build its
plan (plans) -> run the core's frame (plans.frame) -> write the result mesh (write) and the
status (status). The handlers, the operators and the scripting API call update_modifier;
nothing here calls back up to them."""
import time

import numpy as np

from . import frames, gather, holds, inputs, linked, live, objects, plans, stack_input, state, \
    statusline, write


def _output_digest(st, res, material_index):
    """The digest of a result's output topology (its triangles, face indices, vertex count and
    faces' materials): the last one's where these equal its arrays value for value. A follow
    whose sharp edges changed gives new arrays of the same triangles on every frame of a
    waving character, and comparing them costs about a fortieth of hashing them (0.09 against
    3.6 ms at 134k triangles)."""
    parts = (res.triangles, res.face_index, material_index)
    last = st.output_arrays
    if last is not None and last[0] == len(res.positions) and all(
            np.array_equal(a, b) for a, b in zip(parts, last[1])):
        return last[2]
    digest = inputs.digest(res.triangles, res.face_index, len(res.positions), material_index)
    st.output_arrays = (len(res.positions), parts, digest)
    return digest


def update_modifier(obj, mod, p):
    """Brings one modifier's result up to date for the round p (a state.Pass); returns True
    when it wrote new geometry.

    Errors never propagate: they go to the status line and the console, and the modifier
    passes the source geometry through (the source mesh itself is never written).

    p.early (depsgraph_update_pre, before Blender evaluates the edit, gather.early_inputs):
    computes from the original data only where that provably equals what the evaluation will
    give, else does nothing; never reports errors (the post handler, which checks every input
    again against the evaluated data, does). The result's frame range (nodegroup) is written
    from p.scene's frame.
    """
    st = None
    if obj.library is not None:   # linked data are never written (linked.py)
        linked.report(obj, mod)
        return False
    early, render, force = p.early, p.render, p.force
    try:
        linked.prepare_override(obj, mod)
        ro = objects.result_object(obj, mod, create=not early)
        if ro is None:
            return False
        st = state.of_result(ro, create=True)
        stack = stack_input.Stack(obj, mod, render and not early, own=p.own_input)
        # Vertex groups on the result are for the modifiers below and Apply: with the stack's
        # geometry as input they are carried where a modifier is below (it may read them),
        # for render, Apply and Bake, and always without modifiers above.
        groups = not stack.reads_stack or bool(stack.below) or render or force
        got = gather.early_inputs(obj, mod, st, stack, groups) if early else \
            gather.evaluated_inputs(obj, mod, st, p, stack, groups)
        if got is None:
            return False
        st.lattice_gone = None
        st.deferred = False
        exact = got.exact
        key = exact_key = inputs.digest(got.key, groups)
        now = live.now()
        if live.positions_only(st, exact_key, exact, render or force, got.settings, now):
            exact = False
            key = inputs.digest(key, "positions only")
            live.schedule_settle(now)
        frame = frames.scene_frame(p.scene, p.depsgraph)
        shown = gather.result_frames(obj, got.settings.lattice, frame, stack)
        tess = got.tess
        if tess.adaptive:   # counts held over frames (holds.py) are part of the inputs
            key = inputs.digest(key, holds.stamp(ro, st, render, frame))
        if not force and key == st.last_key and write.result_matches(ro.data, st):
            # Same inputs as the result holds: it is right for this frame too.
            if st.status_base is not None:
                statusline.set_ok(obj, mod, st, st.status_base, shown, frame, scene=p.scene)
            return False
        rest, pts, interp, weights = got.lattice
        t0 = time.perf_counter()
        # weights: the lattice's vertex group; a per-frame value like the points (adding or
        # removing it changes the lattice's structure key, so that replans).
        lattice = plans.lattice(st, rest, pts, interp, got.l2o, got.settings.strength, weights)
        st.pieces_note = None
        plans.ensure_plan(st, got.source, lattice, got.level, got.backend, tess,
                          plans.hold_pieces(st, render, frame))
        hold, hold_note = holds.lookup(ro, st, render, frame, holds.token(st.pieces_token),
                                       tess.setting) if tess.adaptive else (None, None)
        if tess.adaptive and render and hold is None and hold_note is None and \
                p.scene is not None and holds.motion_blur(p.scene):
            hold_note = ("motion blur: counts not held over the shutter (renders hold them "
                         "when started in the main thread: command line, scripts; else Hold "
                         "Tessellation)")
        res = plans.frame(st, lattice, exact, hold)
        # The fit error bound (a face attribute, its maximum in the status): with exact
        # results, not while an animation plays (it costs about one more CPU frame).
        fit_error = plans.fit_errors(st) if exact and (render or force or not live.playing()) else None
        t1 = time.perf_counter()
        if st.output[0] is not st.plan_key or tess.adaptive:
            # A new plan may have the output topology of the last one (a source edited without
            # changing its faces' knot-plane cuts): then only positions and what lies on the
            # input move. A plan that followed a new pose keeping its topology kept this too
            # (plans.follow). An adaptive frame may change it on any update. The sharp edges
            # apart: where only they change (a follow that held the pieces while an edge's
            # normals split or joined) the mesh keeps its triangles and gets the new flags.
            output = _output_digest(st, res, got.source.material_index)
            sharp = inputs.digest(res.sharp_edges)
            if tess.adaptive and (output, sharp) != (st.output[1], st.sharp):
                st.scratch = (None, {})   # write_normals' per-topology facts
            st.output, st.sharp = (st.plan_key, output), sharp
        times = write.write_result(obj, mod, ro, res, got.source, st.topology_token, exact,
                                   st, groups, fit_error)
        normals = times.pop("normals")
        t2 = time.perf_counter()
        st.last_key = key
        if not (render or force):   # live editing follows the viewport's results
            if exact_key != st.exact_key:
                st.changed_at = now
            st.exact_key = exact_key
        used = res.stats.get("device", got.backend) if isinstance(res.stats, dict) \
            else got.backend
        tail = (f"{len(res.triangles)} tris, deform {1e3 * (t1 - t0):.1f} ms, "
                f"write {1e3 * (t2 - t1):.1f} ms ({normals} normals)")
        head = f"OK {used}, level {got.level}"
        if tess.adaptive:
            head, tail = _adaptive_status(used, got, res, hold_note, tail)
        if fit_error is not None:
            tail += f", fit error \u2264 {float(fit_error.max(initial=0.0)):.3g}"
        if st.pieces_note is not None:
            tail += f", {st.pieces_note}"
        statusline.set_ok(obj, mod, st, (head, tail), shown, frame,
                      wrote_result=True, scene=p.scene)
        state.timings[state.uid(ro)] = {
            "deform_ms": 1e3 * (t1 - t0), "write_ms": 1e3 * (t2 - t1), "normals": normals,
            "level": got.level, "triangles": len(res.triangles), "stats": res.stats,
            "fit_error": None if fit_error is None else float(fit_error.max(initial=0.0)),
            "early": early, **times}
        state.counters["computed"] += 1
        state.counters["early" if early else "post"] += 1
        stack_input.wrote(obj, mod)
        return True
    except stack_input.Deferred:
        # The stack's geometry is read on the next evaluation (stack_input.defer).
        if st is not None:
            st.deferred = True
        return False
    except Exception as e:   # a bug or a core error: report it, never take Blender down
        if early:
            # Left to the post handler, which reads the same inputs again and reports what
            # fails. st.last_key only changes after a complete write, so a result left half
            # written here never matches the next key (or its topology token) and is redone.
            state.counters["early_errors"] += 1
            return False
        message = str(e) if isinstance(e, inputs.SmoothFFDError) else f"{type(e).__name__}: {e}"
        if st is not None and st.lattice_gone:
            message += f" (the lattice object {st.lattice_gone!r} was deleted)"
        statusline.fail(obj, mod, st, message)
    return False


def _adaptive_status(used, got, res, hold_note, tail):
    """(head, tail) of an adaptive update's status: the tolerance it was computed to, whether
    every triangle met it, and what held its counts."""
    tess, stats = got.tess, res.stats
    head = f"OK {used}, tolerance {tess.tolerance:.3g}"
    if tess.pixel is not None:
        head += f" ({tess.setting[3]:g} px)"
    met = "tolerance met" if stats.get("tolerance_met") else \
        f"tolerance not met at max level {tess.max_level}"
    notes = [n for n in (hold_note, tess.note) if n]
    tail = tail.replace(" tris,", f" tris, {met},", 1)
    return head, tail + "".join(f", {n}" for n in notes)


def tessellation_counts(obj, mod, p):
    """(plan token, tessellation setting, counts) of this modifier's adaptive tessellation
    for the frame and settings of the Pass p, without writing anything; None where p's
    settings (render or viewport) are a fixed level. Raises SmoothFFDError when there is no
    valid input."""
    ro = objects.result_object(obj, mod, create=True)
    st = state.of_result(ro, create=True)
    stack = stack_input.Stack(obj, mod, p.render, own=p.own_input)
    groups = not stack.reads_stack or bool(stack.below) or p.render or p.force
    got = gather.evaluated_inputs(obj, mod, st, p, stack, groups)
    if got is None:
        raise inputs.SmoothFFDError("no input to tessellate")
    if not got.tess.adaptive:
        return None
    rest, pts, interp, weights = got.lattice
    lattice = plans.lattice(st, rest, pts, interp, got.l2o, got.settings.strength, weights)
    hold = plans.hold_pieces(st, p.render, frames.scene_frame(p.scene, p.depsgraph))
    plans.ensure_plan(st, got.source, lattice, got.level, got.backend, got.tess, hold)
    return holds.token(st.pieces_token), got.tess.setting, plans.counts(st, lattice)


def forget(obj=None, mod=None, ro=None):
    """Drops the in-memory state (plan, source) of one modifier, or of all. ro: the
    modifier's result object, when the modifier is already gone (Apply frees it)."""
    if obj is None and ro is None:
        state.forget()
        return
    if ro is None:
        ro = objects.result_object(obj, mod, create=False)
    if ro is not None:
        state.forget(ro)


def last_timing(obj, mod):
    """The timings of the modifier's last computed result (None: none yet)."""
    ro = objects.result_object(obj, mod, create=False)
    return state.timings.get(state.uid(ro)) if ro is not None else None
