"""Updates one Smooth FFD modifier: gathers its inputs from Blender, runs the core (reusing
its plan, cached per modifier, when only the lattice points moved) and writes the hidden
result mesh; also the modifier's status line and its result object."""
import time
import uuid

import bpy
import numpy as np

from . import carry, compat, core, inputs, latticeio, linked, meshio, nodegroup, stack_input

OWNER_KEY = "smooth_ffd_owner"          # result object -> source object's name_full (a string)
MODIFIER_KEY = "smooth_ffd_modifier"    # result object -> modifier name
UID_KEY = "smooth_ffd_uid"              # result object -> its modifier's in-memory state key
TOPOLOGY_KEY = "smooth_ffd_topology"    # result mesh -> plan that built its topology
NORMALS_KEY = "smooth_ffd_normals"      # result mesh -> "exact" or "fast"
EXTRAS_KEY = "smooth_ffd_extras"        # result mesh -> topology + carried UV maps / groups
OUTPUT_KEY = "smooth_ffd_output"        # result mesh -> its triangles, faces, sharp edges
POINTS_KEY = "smooth_ffd_points"        # points object -> the uid of its result object


class _State:
    """What one modifier computed last; lives in memory only (rebuilt after reload)."""

    def __init__(self):
        self.last_key = None
        self.source = None        # meshio.SourceMesh
        self.source_stamp = None
        self.deformer = None
        self.plan_key = None
        self.result = None        # the last core Result: its arrays are reused (out=)
        self.scratch = (None, {})  # (plan_key, meshio.write_normals' per-plan facts, buffers)
        self.output = (None, None)  # (plan_key, digest of that plan's output topology)
        self.outs = {}            # layout -> the last result in it (out=; LAYOUT may change)
        self.status_base = None   # last "OK ..." status as (head, tail) (_set_ok_status)
        self.source_kind = None   # where st.source was read (stack_input: OWN, EVALUATED, CHAIN)
        self.stack_fp = None      # stack_input.settings_fingerprint when st.source was read
        self.upper_key = None     # CHAIN: the last_key of the Smooth FFD above, when read
        self.source_setting = None  # (vertex group, invert) st.source's weights were read with
        self.mesh_fp = None       # stack_input.mesh_fingerprint of the object's mesh when read
        self.deferred = False     # waiting for the next evaluation to read the stack
        self.lattice_gone = None  # a deleted lattice's name (handlers.release_deleted_lattices)
        self.exact_key = None     # the inputs' key (with exact normals) of the last result
        self.changed_at = -1e9    # when a result for new inputs was last computed (live editing)
        self.lattice = (None, None)  # (_lattice's key, the BlenderLattice last built for it)


_states = {}


def uid(ro):
    """The key of the state belonging to the result object ro, which belongs to one
    modifier: a random id stored on ro, so renaming the object or the modifier keeps the
    plan and the result (before, the key was their names, and a rename replanned)."""
    key = ro.get(UID_KEY)
    if not isinstance(key, str):
        key = ro[UID_KEY] = uuid.uuid4().hex
    return key


def state_of(obj, mod):
    """The in-memory state of a modifier (None when it has no result object yet)."""
    ro = result_object(obj, mod, create=False)
    return _states.get(uid(ro)) if ro is not None else None


def _state(ro):
    key = uid(ro)
    st = _states.get(key)
    if st is None:
        st = _states[key] = _State()
    return st


def invalidate_sources():
    """After undo/redo the source meshes may be older versions: re-read them (plans whose
    source is unchanged stay valid, as they are keyed by the source's content)."""
    for st in _states.values():
        st.source = None


def forget(obj=None, mod=None, ro=None):
    """Drops the in-memory state (plan, source) of one modifier, or of all. ro: the
    modifier's result object, when the modifier is already gone (Apply frees it)."""
    if obj is None and ro is None:
        _states.clear()
        _last_timing.clear()
        return
    if ro is None:
        ro = result_object(obj, mod, create=False)
    if ro is not None:
        _states.pop(uid(ro), None)
        _last_timing.pop(uid(ro), None)


class Settings:
    def __init__(self, mod):
        get = lambda name: compat.get_modifier_input(mod, name)
        self.lattice = get("Lattice")
        self.viewport_level = get("Viewport Level")
        self.render_level = get("Render Level")
        self.backend = get("Backend")
        self.strength = float(get("Strength"))
        self.vertex_group = get("Vertex Group")
        self.invert = bool(get("Invert Vertex Group"))
        self.exact = bool(get("Exact Normals"))


def result_object(obj, mod, create=True):
    """The hidden mesh object whose geometry the modifier's Object Info node shows.

    It belongs to one (object, modifier); a duplicated object or copied modifier still points
    at the original's result, so it gets its own here instead of overwriting that one.
    """
    ro = compat.get_modifier_input(mod, "Result Object")
    if ro is not None and ro.type == 'MESH' and _owned_by(ro, obj, mod):
        return ro
    if not create:
        return None
    name = f"{obj.name}.{mod.name}.result"
    me = bpy.data.meshes.new(name)
    ro = bpy.data.objects.new(name, me)   # never linked to a scene: hidden, yet saved (mod uses it)
    ro[OWNER_KEY] = obj.name_full
    ro[MODIFIER_KEY] = mod.name
    uid(ro)
    compat.set_modifier_input(mod, "Result Object", ro)
    return ro


def points_object(obj, mod, ro, create=True):
    """The hidden mesh object of vertices only through which positions-only updates reach
    the group (its Result Points, nodegroup), one per result object, never linked to a
    scene; None when the modifier has none of its own and create is False."""
    po = compat.get_modifier_input(mod, "Result Points")
    if po is not None and po.type == 'MESH' and po.get(POINTS_KEY) == uid(ro) \
            and linked.local_result(po):
        return po
    if not create:
        return None
    name = f"{obj.name}.{mod.name}.points"
    po = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    po[POINTS_KEY] = uid(ro)
    return po


def _sends_points(mod):
    """Whether this Blender sends positions-only updates through the Result Points (before
    3.6, nodegroup) and this modifier's group has them."""
    return compat.POSITIONS_THROUGH_POINTS and \
        nodegroup.layout(mod.node_group) in nodegroup.POINTS_LAYOUTS


def _set_points(obj, mod, po):
    if compat.get_modifier_input(mod, "Result Points") != po:
        compat.set_modifier_input(mod, "Result Points", po)   # a new relation: re-tag
        obj.update_tag()


def _empty_points(obj, mod, ro):
    """After a write of the whole result: the group shows the result mesh as it is. Its own
    points object is emptied (and kept for the next positions-only update), another's (a
    duplicate's original's) let go."""
    if nodegroup.layout(mod.node_group) not in nodegroup.POINTS_LAYOUTS:
        return
    po = points_object(obj, mod, ro, create=False)
    if po is not None and len(po.data.vertices):
        po.data.clear_geometry()
        po.data.update()
    _set_points(obj, mod, po)


def _lattice(st, rest, pts, interp, l2o, strength, weights):
    """The BlenderLattice of these inputs. Where only the points (and the weights' values)
    changed since the last one (a point dragged, an animation), that one's with_points: the
    same values without building and checking the structure again on every update."""
    key = (np.asarray(rest).tobytes(), tuple(interp), np.asarray(l2o).tobytes(), strength,
           weights is None)
    if st.lattice[0] == key:
        return st.lattice[1].with_points(pts, weights)
    lattice = core.smoothffd().BlenderLattice(rest, pts, interpolation=interp,
                                              lattice_to_object=l2o, strength=strength,
                                              point_weights=weights)
    st.lattice = (key, lattice)
    return lattice


def _owned_by(ro, obj, mod):
    """Whether ro is this modifier's own result (not the original's, reached through a
    duplicated object or a copied modifier).

    The owner is kept by name, not as an ID pointer: a pointer is a user of the object, and
    with the modifier pointing back at the result the two kept each other alive, so an
    object deleted in the UI (bpy.ops.object.delete) stayed in the file, unlinked, with its
    result (found by tests/blender/check_robustness.py). Only this modifier uses ro: it is
    ours, whatever the object and the modifier are called now (a rename keeps the result and,
    through uid, the plan; the names recorded are brought up to date). Shared (a duplicate or
    a copy): the recorded names decide, and the other one gets a result of its own.
    """
    if not linked.local_result(ro):   # the library's result (an override's input): never ours
        return False
    owner = ro.get(OWNER_KEY)
    if isinstance(owner, bpy.types.ID):          # files saved before: a pointer, converted
        if owner != obj:
            return False
        ro[OWNER_KEY] = owner = obj.name_full
    if ro.users <= 1:
        if owner != obj.name_full:
            ro[OWNER_KEY] = obj.name_full
        if ro.get(MODIFIER_KEY) != mod.name:
            ro[MODIFIER_KEY] = mod.name
        return True
    return owner == obj.name_full and ro.get(MODIFIER_KEY) == mod.name


def set_status(obj, mod, text, frames=None, wrote_result=False, report=None):
    """Writes the status and the frames the result belongs to (nodegroup: [from, to); None
    leaves them; nodegroup.NEVER: no valid result, the source is shown) only when they
    change, and re-tags the object for them.

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
    if frames is not None and set_frames(mod, "Result", frames):
        changed = True
    if changed:
        obj.update_tag()
    if report if report is not None else frames == nodegroup.NEVER:
        print(f"Smooth FFD [{obj.name} / {mod.name}]: {text}")


def _has_frames(mod):
    return nodegroup.layout(mod.node_group) in nodegroup.FRAMES_LAYOUTS


def get_frames(mod, which):
    """(from, to) of the "Result" or "Bake" frame range. A group of an older layout (a file
    not yet migrated, nodegroup.migrate) has no bake, and a validity flag for the result."""
    if not _has_frames(mod):
        if which == "Result" and compat.get_modifier_input(mod, "Show Result"):
            return nodegroup.ALWAYS
        return nodegroup.NEVER
    return (float(compat.get_modifier_input(mod, f"{which} From")),
            float(compat.get_modifier_input(mod, f"{which} To")))


def set_frames(mod, which, frames):
    """Writes a frame range when it differs; returns whether it did."""
    frames = tuple(float(f) for f in frames)
    if get_frames(mod, which) == frames:
        return False
    if not _has_frames(mod):
        if which != "Result":
            raise KeyError(f"the group of {mod.name!r} is of an older layout, without a bake")
        compat.set_modifier_input(mod, "Show Result", frames != nodegroup.NEVER)
        return True
    compat.set_modifier_input(mod, f"{which} From", frames[0])
    compat.set_modifier_input(mod, f"{which} To", frames[1])
    return True


def scene_frame(scene=None, depsgraph=None):
    """The frame (with subframe and time remapping) a depsgraph evaluates: what the group's
    Scene Time node compares with the frame ranges."""
    if scene is None:
        scene = depsgraph.scene if depsgraph is not None else bpy.context.scene
    return float(scene.frame_current_final)


def result_frames(obj, lattice_obj, frame, stack=None):
    """The frames a result computed at `frame` is right for: all of them when nothing it
    depends on can change with time (no animation, drivers, parents, constraints, hooks or
    shape keys on the lattice, the object or their data: the conditions of the early path;
    with the stack's geometry as input, stack_input.time_dependent), else this frame only
    (half a frame either side, for motion blur's subframes). A result bound to its frame also
    makes the next frame's first evaluation pass the input through, where the add-on reads
    the stack's geometry (stack_input)."""
    static = (lattice_obj is not None and lattice_obj.type == 'LATTICE'
              and latticeio.evaluates_to_original(lattice_obj)
              and latticeio.basis_matrix(lattice_obj) is not None
              and latticeio.basis_matrix(obj) is not None
              and not latticeio.animated(obj.data)
              and (stack is None or not stack.reads_stack
                   or not stack_input.time_dependent(obj, stack)))
    return nodegroup.ALWAYS if static else (frame - 0.5, frame + 0.5)


def _group_index(obj, settings):
    if not settings.vertex_group:
        return None
    idx = obj.vertex_groups.find(settings.vertex_group)
    # Like Blender's Lattice modifier, an unknown group name means no weighting.
    return idx if idx >= 0 else None


def _source_stamp(obj, group_index, settings):
    mesh = obj.data
    return (group_index, settings.invert, len(mesh.vertices), len(mesh.loops), len(mesh.polygons),
            tuple(g.name for g in obj.vertex_groups), tuple(layer.name for layer in mesh.uv_layers))


def _source(obj, settings, st, mesh_changed):
    group_index = _group_index(obj, settings)
    mesh = obj.data
    stamp = _source_stamp(obj, group_index, settings)
    names = [g.name for g in obj.vertex_groups]
    if st.source is not None and not mesh_changed and st.source_stamp == stamp:
        return st.source
    if obj.mode == 'EDIT':
        # Edit-mode changes live in a BMesh, and a mesh in edit mode hides its UV and other
        # corner data from Python: sync, then read a temporary copy.
        obj.update_from_editmode()
        tmp = mesh.copy()
        try:
            source = meshio.SourceMesh(tmp, group_index, settings.invert, names)
        finally:
            bpy.data.meshes.remove(tmp)
    else:
        source = meshio.SourceMesh(mesh, group_index, settings.invert, names)
    source.keep_normals_of(st.source)
    st.source = source
    st.source_stamp = stamp
    st.source_kind = stack_input.OWN
    return st.source


def update_modifier(obj, mod, depsgraph, render=False, mesh_changed=True, force=False,
                    early=False, scene=None, changed=None, frame_change=False, own_input=False,
                    can_evaluate=True):
    """Brings one modifier's result up to date; returns True when it wrote new geometry.

    Errors never propagate: they go to the status line and the console, and the modifier
    passes the source geometry through (the source mesh itself is never written).

    early: called from depsgraph_update_pre, before Blender evaluates the edit (see
    _early_inputs): computes from the original data only where that provably equals what the
    evaluation will give, else does nothing; never reports errors (the post handler, which
    checks every input again against the evaluated data, does).
    scene: the scene whose frame the result is for (default: the depsgraph's, else the
    context's); the result's frame range (nodegroup) is written from it.
    changed: (geometry, transform) sets of the original IDs the last evaluation updated
    (None: unknown); frame_change: called for a new frame. Both say whether the stack's
    geometry must be read again (stack_input). own_input: take the object's own mesh even
    with modifiers above (Apply, as Blender applies a modifier that is not first).
    can_evaluate: the caller is not inside a depsgraph evaluation's handler, so the
    depsgraph may be evaluated again to see the stack's geometry (stack_input.source).
    """
    st = None
    if obj.library is not None:   # linked data are never written (linked.py)
        linked.report(obj, mod)
        return False
    try:
        linked.prepare_override(obj, mod)
        ro = result_object(obj, mod, create=not early)
        if ro is None:
            return False
        st = _state(ro)
        stack = stack_input.Stack(obj, mod, render and not early, own=own_input)
        # Vertex groups on the result are for the modifiers below and Apply: with the stack's
        # geometry as input they are carried where a modifier is below (it may read them),
        # for render, Apply and Bake, and always without modifiers above.
        groups = not stack.reads_stack or bool(stack.below) or render or force
        gathered = _early_inputs(obj, mod, st, stack, groups) if early else \
            _inputs(obj, mod, st, depsgraph, render, mesh_changed, stack, changed, frame_change,
                    can_evaluate, groups)
        if gathered is None:
            return False
        settings, level, backend, exact, lattice_data, l2o, source, key = gathered
        st.lattice_gone = None
        st.deferred = False
        key = exact_key = inputs.digest(key, groups)
        now = time.perf_counter()
        if _positions_while_changing(st, exact_key, exact, render or force, settings, now):
            exact = False
            key = inputs.digest(key, "positions only")
            _schedule_settle(now)
        frame = scene_frame(scene, depsgraph)
        frames = result_frames(obj, settings.lattice, frame, stack)
        if not force and key == st.last_key and _result_matches(ro.data, st):
            # Same inputs as the result holds: it is right for this frame too.
            if st.status_base is not None:
                _set_ok_status(obj, mod, st, st.status_base, frames, frame, scene=scene)
            return False
        rest, pts, interp, weights = lattice_data
        t0 = time.perf_counter()
        # weights: the lattice's vertex group; a per-frame value like the points (adding or
        # removing it changes the lattice's structure key, so that replans).
        lattice = _lattice(st, rest, pts, interp, l2o, settings.strength, weights)
        plan_key = (source.key, lattice.structure_key(), level, backend)
        if st.deformer is None or st.plan_key != plan_key:
            st.deformer = st.result = None
            st.outs = {}
            with _progress(len(source.corner_vertices) * level * level > 2_000_000):
                st.deformer = core.make_deformer(source, lattice, level, backend)
            st.plan_key = plan_key
            plans_built[0] += 1
        # out=: overwrite the previous update's arrays in place (no fresh pages each edit);
        # incremental: recompute only what the lattice points that moved since reach (the
        # previous update's arrays are read only here and by the writes). Without exact
        # normals (3.4-4.4 viewport: Blender shades the dense mesh from its own geometry,
        # _write_result) the core computes positions only: the same positions in well under
        # half the time (res.normals is None then).
        layout = LAYOUT or _layout(st.deformer.plan)
        res = st.result = st.outs[layout] = st.deformer.deform(
            lattice, out=st.outs.get(layout), normals=exact, layout=layout, incremental=True)
        deform_calls["normals" if exact else "positions_only"] += 1
        t1 = time.perf_counter()
        if st.output[0] is not st.plan_key:
            # A new plan often keeps the output topology (an armature's next pose: the same
            # knot-plane cuts): then only positions and what lies on the input move.
            st.output = (st.plan_key, inputs.digest(res.triangles, res.face_index, res.sharp_edges,
                                                 len(res.positions), source.material_index))
        times = _write_result(obj, mod, ro, res, source, inputs.digest(plan_key), exact, st,
                              groups)
        normals = times.pop("normals")
        t2 = time.perf_counter()
        st.last_key = key
        if not (render or force):   # live editing follows the viewport's results
            if exact_key != st.exact_key:
                st.changed_at = now
            st.exact_key = exact_key
        used = res.stats.get("device", backend) if isinstance(res.stats, dict) else backend
        tail = (f"{len(res.triangles)} tris, deform {1e3 * (t1 - t0):.1f} ms, "
                f"write {1e3 * (t2 - t1):.1f} ms ({normals} normals)")
        _set_ok_status(obj, mod, st, (f"OK {used}, level {level}", tail), frames, frame,
                       wrote_result=True, scene=scene)
        _last_timing[uid(ro)] = {
            "deform_ms": 1e3 * (t1 - t0), "write_ms": 1e3 * (t2 - t1), "normals": normals,
            "level": level, "triangles": len(res.triangles), "stats": res.stats,
            "early": early, **times}
        counters["computed"] += 1
        counters["early" if early else "post"] += 1
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
            counters["early_errors"] += 1
            return False
        message = str(e) if isinstance(e, inputs.SmoothFFDError) else f"{type(e).__name__}: {e}"
        if st is not None and st.lattice_gone:
            message += f" (the lattice object {st.lattice_gone!r} was deleted)"
        _fail(obj, mod, st, message)
    return False


# Live editing (4.5+ viewport). While a result keeps changing (results for new inputs less
# than SETTLE seconds apart: a lattice point dragged, an animation playing), the core computes
# positions only and Blender shades the dense mesh from its own geometry, smooth with the
# result's sharp edges, as the 3.4-4.4 viewport always does: well under half the core's time.
# SETTLE seconds after the last change a timer brings the exact normals. Never for render,
# Apply, Bake, forced updates or Exact Normals, nor in background mode (no timers run there:
# scripts and farms get exact results); LIVE True/False forces it on/off (tests).
LIVE = None
SETTLE = 0.4
_settle_after = [0.0]   # perf_counter time after which the settle timer updates


def _live():
    return (not bpy.app.background) if LIVE is None else LIVE


def _positions_while_changing(st, exact_key, exact, render, settings, now):
    """Whether this update computes positions only (see LIVE): new inputs within SETTLE of
    the last change, or the same inputs as a positions-only result of less than SETTLE ago
    (the post handler after an early computation: it stays until the settle timer)."""
    return (exact and not render and not settings.exact and compat.CHEAP_EXACT_NORMALS
            and _live() and now - st.changed_at < SETTLE
            and (exact_key != st.exact_key or st.last_key != exact_key))


def _schedule_settle(now):
    _settle_after[0] = now + SETTLE
    if not bpy.app.background and not bpy.app.timers.is_registered(settle):
        bpy.app.timers.register(settle, first_interval=SETTLE)


def settle():
    """The timer after live editing: once nothing changed for SETTLE seconds, updates every
    modifier, which computes the exact normals of the results computed without them (their
    key differs); else runs again when that time has come."""
    wait = _settle_after[0] - time.perf_counter()
    if wait > 0:
        return wait
    from . import handlers
    handlers.update_all(bpy.context.scene)
    return None


# The core's output layout (docs/api.md), per plan (_layout); "compact" or "corners" forces
# one (blender_scenes/bench_layout.py measures them against each other).
LAYOUT = None


def _layout(plan):
    """The cheapest layout for this plan's normals. Where no normal splits, "compact": one
    normal per render vertex = per output vertex, which Blender takes as per-vertex custom
    normals (meshio.write_normals), a third to a sixth of the per-corner values. Where normals
    split (more render vertices than output vertices), Blender needs one normal a corner, and
    the core's "corners" layout writes them directly, cheaper than gathering the compact
    normals through render_triangles in numpy (bench_layout.py: at level 10, 89 against 184
    ms on bpy 5.0)."""
    return "corners" if plan.render_vertex_count > plan.output_vertices else "compact"

# How many results were computed, and where (tests and benchmarks read these).
counters = {"computed": 0, "early": 0, "post": 0, "early_errors": 0}
# How many plans were built (a rename must not build one: tests read it).
plans_built = [0]
# How the core was asked: with normals (exact normals: render, Apply, Exact Normals, 4.5+) or
# positions only (viewport on 3.4-4.4). Apart from `counters`, whose exact contents tests compare.
deform_calls = {"normals": 0, "positions_only": 0}


def _level_backend_exact(settings, render):
    level = inputs.parse_level(settings.render_level if render else settings.viewport_level,
                              "render level" if render else "viewport level")
    backend = inputs.parse_backend(settings.backend)
    # Exact custom normals up to 4.4 only when asked for (slow); 4.5+ always exact.
    exact = render or settings.exact or compat.CHEAP_EXACT_NORMALS
    return level, backend, exact


def _key(lattice_key, l2o, settings, source, level, backend, exact):
    return inputs.digest(lattice_key, l2o, settings.strength, source.key, source.extras_key, level,
                        backend, exact)


def _inputs(obj, mod, st, depsgraph, render, mesh_changed, stack, changed, frame_change,
            can_evaluate, groups):
    """Everything one update uses, from the evaluated depsgraph, and its fingerprint."""
    settings = Settings(mod)
    level, backend, exact = _level_backend_exact(settings, render)
    rest, pts, interp, shape, lattice_key, weights = latticeio.read_lattice(settings.lattice, depsgraph)
    l2o = inputs.lattice_to_object(latticeio.world_matrix(obj, depsgraph),
                                  latticeio.world_matrix(settings.lattice, depsgraph))
    if stack.reads_stack:
        source = stack_input.source(obj, mod, settings, st, stack, depsgraph, changed,
                                    frame_change, can_evaluate, groups)
    else:
        stack_input.set_stack_object(obj, mod, None)   # no input check for the own mesh
        stack_input.set_input_copy(obj, mod, stack)
        source = _source(obj, settings, st, mesh_changed)
    key = _key(lattice_key, l2o, settings, source, level, backend, exact)
    return settings, level, backend, exact, (rest, pts, interp, weights), l2o, source, key


def _early_inputs(obj, mod, st, stack, groups):
    """The inputs read before Blender evaluates an edit (depsgraph_update_pre), or None.

    On 3.4 a lattice edit is evaluated twice: the Smooth FFD modifier depends on its Lattice
    input, so Blender re-evaluates it (with the old result) before depsgraph_update_post
    runs, and once more after the post handler wrote the new result. Writing the result in
    depsgraph_update_pre instead leaves one evaluation, of the new result. Before the
    evaluation only the original data are known, so this computes only when they equal the
    evaluated values: a lattice without modifiers (hooks), shape keys or animation, objects
    whose world matrix is their own loc/rot/scale (no parent, constraints, animation, rigid
    body), a source already read, viewport level. The post handler reads the evaluated data
    as always and recomputes if the fingerprint still differs. With the stack's geometry as
    input (stack_input) the last reading is used when the settings above are unchanged; the
    post handler reads it again if the update changed what the stack above uses.
    """
    if st.source is None or st.last_key is None or st.source_kind != stack.kind:
        return None
    if stack.reads_stack:
        if st.stack_fp != stack_input.settings_fingerprint(obj, stack):
            return None
        if stack.kind == stack_input.CHAIN:
            up = state_of(obj, stack.upper)
            if up is None or up.last_key is None or up.last_key != st.upper_key:
                return None
    settings = Settings(mod)
    lat = settings.lattice
    if lat is None or lat.type != 'LATTICE' or not latticeio.evaluates_to_original(lat):
        return None
    obj_matrix, lat_matrix = latticeio.basis_matrix(obj), latticeio.basis_matrix(lat)
    if obj_matrix is None or lat_matrix is None:
        return None
    if not stack.reads_stack:
        group_index = _group_index(obj, settings)
        if st.source_stamp != _source_stamp(obj, group_index, settings):
            return None
    elif st.source_setting is None or \
            (settings.vertex_group, settings.invert) != st.source_setting[:2] or \
            (groups and not st.source_setting[2]):
        return None
    level, backend, exact = _level_backend_exact(settings, False)
    rest, pts, interp, shape, lattice_key, weights = latticeio.read_lattice(lat, None)
    l2o = inputs.lattice_to_object(obj_matrix, lat_matrix)
    key = _key(lattice_key, l2o, settings, st.source, level, backend, exact)
    return settings, level, backend, exact, (rest, pts, interp, weights), l2o, st.source, key


_last_timing = {}


class _progress:
    """Blender's progress cursor around a long first plan (big mesh, high level)."""

    def __init__(self, long):
        wm = getattr(bpy.context, "window_manager", None)
        self.wm = wm if long and wm is not None and not bpy.app.background else None

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, 1)

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()


def last_timing(obj, mod):
    ro = result_object(obj, mod, create=False)
    return _last_timing.get(uid(ro)) if ro is not None else None


def _set_ok_status(obj, mod, st, base, frames, frame, wrote_result=False, scene=None):
    """base: (head, tail) of the "OK ..." text; the frame goes between them when the result
    belongs to this frame only (a file opened without the add-on then says which frame it
    shows), and scene warnings after."""
    st.status_base = base
    head, tail = base
    text = f"{head}, frame {frame:g}, {tail}" if frames != nodegroup.ALWAYS else f"{head}, {tail}"
    notes = lock_notes(scene)
    if notes:
        text += "".join(f" \u2014 {n}" for n in notes)
    set_status(obj, mod, text, frames, wrote_result=wrote_result, report=False)


# --- Render > Lock Interface ------------------------------------------------------------
# Renders started from a window run in a job thread, and so do the handlers that compute the
# render-level result there (render_pre, frame_change_post): they write Blender data, which
# is safe only while the interface is locked (RenderSettings.use_lock_interface; a
# background render runs in the main thread and needs nothing). The add-on turns the
# setting on in one place only, add_smooth_ffd in a window, and says so (operator report,
# console, status); it never turns it on behind the user's back (file load, render), and
# while it is off, the status says what renders from the window do without it.

_lock_turned_on = set()   # names of scenes where add_smooth_ffd turned it on (this session)


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
    _lock_turned_on.add(scene.name_full)
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
    if scene.name_full in _lock_turned_on:
        return ["Render > Lock Interface turned on by Smooth FFD"]
    return []


def _fail(obj, mod, st, message):
    if st is not None:
        st.last_key = None
        st.status_base = None
    try:
        set_status(obj, mod, "Error: " + message, nodegroup.NEVER)
    except Exception as e:   # even the status write failed (e.g. group removed)
        print(f"Smooth FFD [{obj.name}]: {message} (status not written: {e})")


def _result_matches(mesh, st):
    """False when something else (undo, the user) changed the result mesh behind our back."""
    return mesh.get(TOPOLOGY_KEY) == (inputs.digest(st.plan_key) if st.plan_key else None)


def _materials(obj):
    return [slot.material for slot in obj.material_slots] if obj.material_slots else \
        list(obj.data.materials)


def _write_result(obj, mod, ro, res, source, topology_token, exact, st, groups=True):
    """Writes res into the result mesh; returns timings (ms) and the normals path used.
    groups: carry the vertex groups (else the result has none)."""
    mesh = ro.data
    t0 = time.perf_counter()
    mode = "exact" if exact else "fast"
    same = (mesh.get(OUTPUT_KEY) == st.output[1] and mesh.get(TOPOLOGY_KEY) is not None
            and len(mesh.vertices) == len(res.positions)
            and len(mesh.polygons) == len(res.triangles))
    # Going back from exact to fast needs the custom normals gone: on 3.4-4.4 a rebuild, on
    # 4.5+ the attribute removed (below).
    rebuild = not same or (mesh.get(NORMALS_KEY) == "exact" and mode == "fast"
                           and not compat.HAS_FREE_NORMAL_ATTRIBUTE)
    extras_token = inputs.digest(topology_token, source.extras_key, groups)
    if not rebuild and mode == "fast" and mesh.get(NORMALS_KEY) == "fast" \
            and mesh.get(TOPOLOGY_KEY) == topology_token \
            and mesh.get(EXTRAS_KEY) == extras_token and _sends_points(mod) and ro.users == 1:
        # Only the positions change: before 3.6 a write to the result mesh makes the
        # depsgraph copy all of it again, the points object is vertices only (nodegroup).
        # The result mesh gets them too, untagged: it stays the result for everyone who
        # reads it (stack_input, bake, Apply) and in the saved file. Its evaluated copy keeps
        # the old positions, so only while nothing but this modifier evaluates it (users:
        # a Smooth FFD below has it as its Stack Object, stack_input).
        meshio.write_positions(mesh, res)
        po = points_object(obj, mod, ro)
        meshio.write_vertices(po.data, res.positions)
        _set_points(obj, mod, po)
        t1 = time.perf_counter()
        return {"normals": "from geometry", "rebuilt": False, "mesh_write_ms": 1e3 * (t1 - t0),
                "carry_ms": 0.0, "carry_add_calls": 0, "normals_ms": 0.0, "tag_ms": 0.0,
                "points": True}
    if rebuild:
        meshio.write_topology(mesh, res, source, _materials(obj))
        mesh[OUTPUT_KEY] = st.output[1]
    else:
        meshio.write_positions(mesh, res)
        if mesh.get(TOPOLOGY_KEY) != topology_token:
            # Another plan with the same topology: the points on the input moved with it.
            meshio.write_rest_positions(mesh, res)
    mesh[TOPOLOGY_KEY] = topology_token
    # UV maps and vertex groups: with a new topology, or when only they changed.
    carry_ms, carry_calls = 0.0, 0
    if rebuild or mesh.get(EXTRAS_KEY) != extras_token:
        tc = time.perf_counter()
        plan = st.deformer.plan   # where the output lies on the input (docs/api.md)
        carry.write_uv_layers(mesh, res, source, plan)
        if groups:
            carry_calls = carry.write_vertex_groups(ro, source, plan)
        elif len(ro.vertex_groups):
            ro.vertex_groups.clear()
        mesh[EXTRAS_KEY] = extras_token
        carry_ms = 1e3 * (time.perf_counter() - tc)
    t1 = time.perf_counter()
    if exact:
        if st.scratch[0] is not st.plan_key:
            plan = st.deformer.plan
            st.scratch = (st.plan_key, {"splits": plan.render_vertex_count > plan.output_vertices})
        path = meshio.write_normals(mesh, res, st.scratch[1])
    else:
        # 3.4-4.4 viewport, live editing on 4.5+: Blender's own normals of the dense mesh.
        compat.remove_custom_normals(mesh)
        path = "from geometry"
    mesh[NORMALS_KEY] = mode
    t2 = time.perf_counter()
    mesh.update()
    _empty_points(obj, mod, ro)
    t3 = time.perf_counter()
    return {"normals": path, "rebuilt": rebuild, "mesh_write_ms": 1e3 * (t1 - t0),
            "carry_ms": carry_ms, "carry_add_calls": carry_calls,
            "normals_ms": 1e3 * (t2 - t1), "tag_ms": 1e3 * (t3 - t2), "points": False}
