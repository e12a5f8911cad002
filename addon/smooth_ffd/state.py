"""What the add-on keeps between updates: each modifier's in-memory state, the custom-property
keys that tie hidden objects to their modifier, the frame ranges' special values, what one
round of updates is asked for (Pass), and every other value the add-on keeps at module level
(the handlers' flags, caches, counters, the live-editing clock's deadline).

Imports no other module of the add-on: every module may import it, and it holds no logic
that needs Blender data beyond reading and writing custom properties.
"""
import contextlib
import uuid

# --- custom-property keys -----------------------------------------------------------------
OWNER_KEY = "smooth_ffd_owner"          # result object -> source object's name_full (a string)
MODIFIER_KEY = "smooth_ffd_modifier"    # result object -> modifier name
UID_KEY = "smooth_ffd_uid"              # result object -> its modifier's in-memory state key
TOPOLOGY_KEY = "smooth_ffd_topology"    # result mesh -> output topology it holds (plan token)
POSE_KEY = "smooth_ffd_pose"            # result mesh -> plan (pose of the source) it was written for
NORMALS_KEY = "smooth_ffd_normals"      # result mesh -> "exact" or "fast"
EXTRAS_KEY = "smooth_ffd_extras"        # result mesh -> topology + carried UV maps / groups
OUTPUT_KEY = "smooth_ffd_output"        # result mesh -> its triangles, faces, vertex count
SHARP_KEY = "smooth_ffd_sharp"          # result mesh -> its sharp edges
POINTS_KEY = "smooth_ffd_points"        # points object -> the uid of its result object
STACK_KEY = "smooth_ffd_stack"          # stack object -> the uid of its modifier's result object
BAKE_KEY = "smooth_ffd_bake"            # "host", "frame" (objects) or "frames" (the host's group)
LEVEL_KEY = "smooth_ffd_bake_level"     # bake host -> the level baked
RANGE_KEY = "smooth_ffd_bake_frames"    # bake host -> [first, last] frame baked

# --- frame ranges -------------------------------------------------------------------------
# A modifier's "Result" and "Bake" ranges [from, to) (nodegroup): the group shows the result
# (the bake) on the frames inside. NEVER, empty (from > to): no frame; ALWAYS: every frame
# Blender allows (MAXFRAME is 1048574).
NEVER = (1.0, 0.0)
ALWAYS = (-1.0e7, 1.0e7)


def covers(frames, frame):
    lo, hi = frames
    return lo <= frame < hi


# --- one modifier's state -----------------------------------------------------------------

class ModifierState:
    """What one modifier computed last; lives in memory only (rebuilt after reload)."""

    def __init__(self):
        self.last_key = None
        self.source = None        # meshio.SourceMesh
        self.source_stamp = None
        self.deformer = None
        self.plan_key = None
        self.faces_key = None     # what a plan can follow across (plans.follow)
        self.topology_token = None  # the plan's output topology: kept while follows keep it
        self.result = None        # the last core Result: its arrays are reused (out=)
        self.scratch = (None, {})  # (topology_token, meshio.write_normals' per-topology facts)
        self.output = (None, None)  # (plan_key, digest of that plan's output topology)
        self.output_arrays = None  # (vertex count, arrays, digest) of the last output digested
        self.sharp = None         # digest of the last result's sharp edges (write.write_result)
        self.outs = {}            # layout -> the last result in it (out=; LAYOUT may change)
        self.status_base = None   # last "OK ..." status as (head, tail) (statusline.set_ok)
        self.source_kind = None   # where st.source was read (stack_input: OWN, EVALUATED, CHAIN)
        self.stack_fp = None      # stack_input.settings_fingerprint when st.source was read
        self.upper_key = None     # CHAIN: the last_key of the Smooth FFD above, when read
        self.source_setting = None  # (vertex group, invert) st.source's weights were read with
        self.mesh_fp = None       # stack_input.mesh_fingerprint of the object's mesh when read
        self.deferred = False     # waiting for the next evaluation to read the stack
        self.lattice_gone = None  # a deleted lattice's name (handlers.release_deleted_lattices)
        self.exact_key = None     # the inputs' key (with exact normals) of the last result
        self.changed_at = -1e9    # when a result for new inputs was last computed (live editing)
        self.lattice = (None, None)  # (plans.lattice's key, the BlenderLattice last built for it)
        self.shutter = None       # ((from, to), plan token, setting, counts) held over a render's
        #                           motion-blur shutter (holds.py)
        self.hold_cache = {}      # holds.lookup: a saved hold's counts as arrays
        self.pieces_for = None    # the render shutter in which the plan's pieces were last cut
        #                           (plans.hold_pieces: its other subframes hold them)
        self.pieces_token = None  # names the plan's pieces, which adaptive counts are per
        #                           (plans.ensure_plan; holds.py)
        self.pieces_note = None   # what holding the pieces did on the last update, for the status


# uid -> ModifierState, and uid -> the last update's timings (pipeline.last_timing)
states = {}
timings = {}


def uid(ro):
    """The key of the state belonging to the result object ro, which belongs to one
    modifier: a random id stored on ro, so renaming the object or the modifier keeps the
    plan and the result."""
    key = ro.get(UID_KEY)
    if not isinstance(key, str):
        key = ro[UID_KEY] = uuid.uuid4().hex
    return key


def of_result(ro, create=False):
    """The state of the modifier whose result object is ro (None for no ro, or none yet and
    not create)."""
    if ro is None:
        return None
    key = uid(ro)
    st = states.get(key)
    if st is None and create:
        st = states[key] = ModifierState()
    return st


def forget(ro=None):
    """Drops one modifier's state (by its result object), or every one's (ro None)."""
    if ro is None:
        states.clear()
        timings.clear()
        return
    states.pop(uid(ro), None)
    timings.pop(uid(ro), None)


def invalidate_sources():
    """After undo/redo the source meshes may be older versions: re-read them (plans whose
    source is unchanged stay valid, as they are keyed by the source's content)."""
    for st in states.values():
        st.source = None


# --- one round of updates -----------------------------------------------------------------

class Pass:
    """What one round of updates is for; every modifier updated in it gets the same.

    depsgraph: the evaluated depsgraph (None: before an evaluation, `early`).
    scene: the scene whose frame the results are for (default: the depsgraph's, else the
    context's). render: the render level and exact normals. force: compute even when the
    inputs are unchanged. early: from depsgraph_update_pre, before Blender evaluates the edit
    (update.early_inputs). changed: (geometry, transform) sets of the original IDs the last
    evaluation updated (None: unknown); changed_meshes: the meshes among them whose data
    changed (None: any may have). frame_change: a new frame. own_input: take the object's own
    mesh even with modifiers above (Apply). can_evaluate: not inside a depsgraph evaluation's
    handler, so the depsgraph may be evaluated again (stack_input)."""

    def __init__(self, depsgraph=None, scene=None, render=False, force=False, early=False,
                 changed=None, changed_meshes=None, frame_change=False, own_input=False,
                 can_evaluate=True):
        self.depsgraph = depsgraph
        self.scene = scene
        self.render = render
        self.force = force
        self.early = early
        self.changed = changed
        self.changed_meshes = changed_meshes
        self.frame_change = frame_change
        self.own_input = own_input
        self.can_evaluate = can_evaluate

    def mesh_changed(self, obj):
        """Whether obj's mesh data may have changed (the object itself is re-evaluated
        whenever its lattice moves: only an update of its mesh means the source changed)."""
        return self.changed_meshes is None or obj.data in self.changed_meshes


# --- the handlers' flags --------------------------------------------------------------------

class _Flags:
    busy = False        # an update runs (or handlers are muted): handlers do nothing
    rendering = False   # between render_init and render_complete/cancel
    render_shutter = None  # (from, to, frame, render): the frame rendered, its motion-blur
    #                        shutter and the render's serial number (render_pre;
    #                        plans.hold_pieces)
    renders = 0            # render_pre calls: each render's serial number


flags = _Flags()


@contextlib.contextmanager
def muted():
    """Handlers do nothing inside: the add-on's own depsgraph updates must neither recurse
    nor put the viewport level back over a render-level result (Apply)."""
    was = flags.busy
    flags.busy = True
    try:
        yield
    finally:
        flags.busy = was


def guarded(fn, *args, **kwargs):
    with muted():
        return fn(*args, **kwargs)


# Lattices seen with a user besides Smooth FFD inputs this session (as_pointer): one that
# later has none was deleted (handlers.release_deleted_lattices).
wanted_lattices = set()
# (object name_full, modifier name) -> status text, between save_pre and save_post.
saved_status = {}
# Timers the handlers register after a round of updates: "settle" (live editing),
# "stack" (a stack reading deferred to the next evaluation, stack_input.defer).
pending_timers = set()

# --- live editing (update.positions_only) ---------------------------------------------------
# While a result keeps changing (results for new inputs less than SETTLE seconds apart: a
# lattice point dragged, an animation playing), the 4.5+ viewport computes positions only;
# SETTLE seconds after the last change a timer (handlers.settle) brings the exact normals.
# LIVE None: on in a window, off in background mode; True/False forces it (tests).
LIVE = None
SETTLE = 0.4
settle_after = [0.0]   # perf_counter time after which the settle timer updates

# The core's output layout (docs/api.md), per plan (plans.layout); "compact" or "corners"
# forces one (blender_scenes/bench_layout.py measures them against each other).
LAYOUT = None

# --- Render > Lock Interface (statusline.ensure_render_lock) -------------------------
lock_turned_on = set()   # names of scenes where add_smooth_ffd turned it on (this session)
# What the last add_smooth_ffd said about Lock Interface (None: nothing changed); the Add
# operator reports it.
lock_message = [None]

# --- the stack's geometry (stack_input) -----------------------------------------------------
# (object as_pointer, modifier name) of Smooth FFD modifiers that, in this round, wrote a
# result or were made to pass their input through (stack_input.force_passthrough): what the
# last evaluation showed below them is not what the next one shows.
stack_changed = set()

# --- linked data (linked.py) ----------------------------------------------------------------
# (object name_full, modifier name) -> the message printed for a linked modifier (once).
linked_reported = {}
linked_scanned = [None]        # what linked.report_scene last scanned (a cheap signature)
overridable_done = set()       # overrides whose inputs were made overridable

# --- caches of lower modules ----------------------------------------------------------------
# compat: (group pointer, session uid, number of interface items) -> {name: (identifier,
# is_menu)}; latticeio: lattice name -> (shape, rest) (edit mode hides the rest positions);
# core: the imported `smoothffd` module.
input_tables = {}
lattice_rest = {}
core_module = [None]

# --- counters (tests and benchmarks read them) ------------------------------------------------
# How many results were computed, and where.
counters = {"computed": 0, "early": 0, "post": 0, "early_errors": 0}
# How many plans were built (a rename must not build one), how many times a plan followed a
# new pose of its source instead (plans.follow), how many of those kept the output topology, and
# how many held the pieces.
plans_built = [0]
plans_followed = [0]
plans_followed_kept = [0]
plans_followed_held = [0]   # follows that held the plan's pieces (plans.hold_pieces)
# How the result mesh was written: its topology rebuilt, or only its values (positions,
# normals, ...) over the topology it had.
mesh_writes = {"topology": 0, "values": 0, "sharp": 0}
# How the core was asked: with normals (exact normals: render, Apply, Exact Normals, 4.5+) or
# positions only (viewport on 3.4-4.4). Apart from `counters`, whose exact contents tests compare.
deform_calls = {"normals": 0, "positions_only": 0}
# How often the stack's geometry was read, and how often that took one more evaluation of the
# depsgraph (force_passthrough) or waited for the next one (defer).
stack_counters = {"forced": 0, "reads": 0, "deferred": 0}
# How many viewport updates skipped a hidden object.
skipped_hidden = [0]


def forget_session():
    """What belongs to the file, dropped on load: plans, linked reports, wanted lattices."""
    forget()
    linked_reported.clear()
    linked_scanned[0] = None
    overridable_done.clear()
    wanted_lattices.clear()
