"""The stack's geometry as a Smooth FFD modifier's input: what Blender's own
Lattice modifier at the same position would deform, when modifiers or shape keys sit above.

Python cannot read a Geometry Nodes modifier's input, so the add-on reads it where Blender
already shows it. The node group passes its input through unchanged whenever it has no
result for the frame evaluated, or when its input lacks the vertices of the Stack Object
(nodegroup: a hidden mesh object holding the positions of the input the result was
computed from). After such an evaluation, with nothing but Smooth FFD modifiers (passing
through too) below it, the evaluated object *is* the stack's geometry at this position, with
its split normals, UV maps, vertex groups and material indices, and the handler of that
evaluation reads it (source). So:

- playback: a moving input (a pose, animated shape keys) differs from the Stack Object, and
  a result whose inputs change with time belongs to its frame only
  (gather.result_frames), so the first evaluation of a new frame passes the input
  through; frame_change_post reads it there and computes, and Blender's second evaluation of
  that frame (which it runs for any handler that changed data) shows the result: the
  modifiers above are evaluated twice a frame, once more than with Blender's Lattice
  modifier;
- an edit on the same frame that moves vertices passes through in the evaluation the edit
  makes, and is read there; a lattice edit reads nothing (the last reading is kept);
- an edit the check does not see (the mesh's UV maps, materials, sharp edges; settings that
  keep the vertices in place) finds the result shown: outside depsgraph handlers the
  depsgraph is evaluated once more (force_passthrough); inside them that crashes Blender
  after a relations update, so the frame ranges are cleared and the next evaluation reads it
  (defer);
- a Smooth FFD modifier right below another one takes that one's result mesh as its input
  (or its bake on a baked frame), converging in stack order within one handler call;
- with other modifiers below it, the evaluated object shows their output, not this input:
  the modifier's Input Copy is set (nodegroup), so that the group's passed-through geometry
  also carries its input mesh as a hidden instance, and the add-on reads that instance
  (input_copy) in the same evaluations as above: no evaluation more.
"""
import bpy
import numpy as np

from . import compat, frames, inputs, latticeio, meshio, nodegroup, objects, state

OWN, EVALUATED, CHAIN = "own", "evaluated", "chain"

# Modifier types whose output depends on nothing but their settings, the input and the IDs
# they point at (checked separately): their geometry changes with the frame only when those
# are animated. Anything else (Wave, Build, Ocean, simulations, caches, Geometry Nodes that
# may read the scene time...) counts as changing on every frame.
STATIC_TYPES = frozenset((
    'ARMATURE', 'ARRAY', 'BEVEL', 'BOOLEAN', 'CAST', 'CORRECTIVE_SMOOTH', 'CURVE',
    'DATA_TRANSFER', 'DECIMATE', 'DISPLACE', 'EDGE_SPLIT', 'HOOK', 'LAPLACIANDEFORM',
    'LAPLACIANSMOOTH', 'LATTICE', 'MASK', 'MESH_DEFORM', 'MIRROR', 'MULTIRES', 'NORMAL_EDIT',
    'REMESH', 'SCREW', 'SHRINKWRAP', 'SIMPLE_DEFORM', 'SKIN', 'SMOOTH', 'SOLIDIFY', 'SUBSURF',
    'SURFACE_DEFORM', 'TRIANGULATE', 'UV_PROJECT', 'UV_WARP', 'VERTEX_WEIGHT_EDIT',
    'VERTEX_WEIGHT_MIX', 'VERTEX_WEIGHT_PROXIMITY', 'WARP', 'WEIGHTED_NORMAL', 'WELD',
    'WIREFRAME'))

# Types whose output besides positions (UV maps, weights, normals) follows IDs they point at.
NON_POSITIONAL_TYPES = frozenset(('UV_PROJECT', 'UV_WARP', 'VERTEX_WEIGHT_PROXIMITY',
                                  'DATA_TRANSFER', 'NORMAL_EDIT', 'NODES'))

def enabled(m, render):
    return m.show_render if render else m.show_viewport


class Stack:
    """Where one Smooth FFD modifier sits in its object's stack, for the viewport or render:
    the enabled modifiers above and below, shape keys, and which input it gets (`kind`):

    OWN        nothing above, no shape keys: the object's own mesh (the fast path)
    EVALUATED  the evaluated object after an evaluation in which it passed its input through,
               or, with modifiers other than Smooth FFD below (`copy`), the input copy it
               passed through with it
    CHAIN      the enabled modifier right above is a Smooth FFD: its result (or bake)
    """

    def __init__(self, obj, mod, render=False, own=False):
        mods = list(obj.modifiers)
        k = next((i for i, m in enumerate(mods) if m == mod), len(mods))
        self.above = [m for m in mods[:k] if enabled(m, render)]
        self.below_all = mods[k + 1:]
        self.below = [m for m in self.below_all if enabled(m, render)]
        key = obj.data.shape_keys if obj.type == 'MESH' else None
        self.shape_keys = key is not None and len(key.key_blocks) > 0
        last = self.above[-1] if self.above else None
        self.upper = last if last is not None and nodegroup.is_smooth_ffd_modifier(last) else None
        self.sffd_below = [m for m in self.below if nodegroup.is_smooth_ffd_modifier(m)]
        self.other_below = [m for m in self.below if not nodegroup.is_smooth_ffd_modifier(m)]
        self.render = render
        # The Input Copy's number: the modifier's place in the stack, 1-based.
        self.marker = k + 1
        if own or (not self.above and not self.shape_keys):
            self.kind = OWN
        elif self.upper is not None:
            self.kind = CHAIN
        else:
            self.kind = EVALUATED
        self.copy = self.kind == EVALUATED and bool(self.other_below)

    @property
    def reads_stack(self):
        return self.kind in (EVALUATED, CHAIN)


# --- what the stack above depends on ----------------------------------------------------

def referenced_ids(m):
    """The IDs a modifier's settings point at (objects, collections, textures, node groups
    and, for Geometry Nodes modifiers, the IDs in their inputs), with the data of objects."""
    out = []
    for prop in m.bl_rna.properties:
        if prop.type == 'POINTER' and prop.identifier != "rna_type":
            value = getattr(m, prop.identifier, None)
            if isinstance(value, bpy.types.ID):
                out.append(value)
    if m.type == 'NODES':
        for key in m.keys():
            value = m[key]
            if isinstance(value, bpy.types.ID):
                out.append(value)
    more = []
    for ident in out:
        if isinstance(ident, bpy.types.Object) and ident.data is not None:
            more.append(ident.data)
        elif isinstance(ident, bpy.types.Collection):
            more.extend(ident.all_objects)
    return out + more


def _refers_to_objects(stack):
    return any(isinstance(i, bpy.types.Object) for m in stack.above for i in referenced_ids(m))


def time_dependent(obj, stack):
    """Whether the stack's geometry at this position may change from frame to frame:
    animation or drivers on the object, its mesh or shape keys, a modifier above of a type not
    in STATIC_TYPES (or a texture-driven one with a texture), an ID a modifier above points
    at that is animated, parented or constrained (an armature: also bone constraints), or a
    Smooth FFD above whose result belongs to one frame."""
    if latticeio.animated(obj) or latticeio.animated(obj.data):
        return True
    key = obj.data.shape_keys
    if key is not None and latticeio.animated(key):
        return True
    if _refers_to_objects(stack) and latticeio.basis_matrix(obj) is None:
        return True
    for m in stack.above:
        if nodegroup.is_smooth_ffd_modifier(m):
            if frames.get_frames(m, "Result") != state.ALWAYS:
                return True
            continue
        if m.type not in STATIC_TYPES:
            return True
        if m.type in ('DISPLACE', 'WARP') and getattr(m, "texture", None) is not None:
            return True
        for ident in referenced_ids(m):
            if latticeio.animated(ident):
                return True
            if isinstance(ident, bpy.types.Object):
                if latticeio.basis_matrix(ident) is None:
                    return True
                if ident.type == 'ARMATURE' and ident.pose is not None and \
                        any(len(b.constraints) for b in ident.pose.bones):
                    return True
                if ident.type == 'MESH' and ident.data.shape_keys is not None and \
                        latticeio.animated(ident.data.shape_keys):
                    return True
    return False


def _rna_values(m):
    out = []
    for prop in m.bl_rna.properties:
        ident = prop.identifier
        if ident in ("rna_type", "is_override_data_editable", "is_active",
                     "persistent_uid", "show_expanded", "is_pin_to_last") or \
                prop.type == 'COLLECTION':
            continue
        try:
            value = getattr(m, ident)
        except AttributeError:
            continue
        if isinstance(value, bpy.types.ID):
            value = value.name_full
        elif prop.type == 'POINTER':
            continue
        elif hasattr(value, "__len__") and not isinstance(value, str):
            value = tuple(value)
        out.append((ident, value))
    if m.type == 'NODES':
        for key in sorted(m.keys()):
            value = m[key]
            out.append((key, value.name_full if isinstance(value, bpy.types.ID) else
                        repr(value.to_list() if hasattr(value, "to_list") else value)))
    return repr(out)


def settings_fingerprint(obj, stack):
    """Digest of what the original data say about the stack above (readable before an
    evaluation too): each modifier's type, name and settings, the shape keys' values and
    settings, the object's shape-key display flags."""
    parts = [stack.kind, stack.render]
    for m in stack.above:
        parts.append((m.type, m.name, _rna_values(m)))
    key = obj.data.shape_keys
    if key is not None:
        parts.append((key.use_relative, key.eval_time, obj.active_shape_key_index,
                      obj.show_only_shape_key, obj.use_shape_key_edit_mode,
                      tuple((kb.name, kb.value, kb.mute, kb.relative_key.name,
                             kb.slider_min, kb.slider_max, kb.vertex_group, kb.interpolation)
                            for kb in key.key_blocks)))
    return inputs.digest(*parts)


# --- reading ------------------------------------------------------------------------------

class Deferred(Exception):
    """The stack's geometry is read on the next evaluation (defer)."""


def begin_pass():
    """Called where one round of updates starts (handlers.update_all, api.update):
    state.stack_changed lists the modifiers that wrote or passed their input through in it."""
    state.stack_changed.clear()


def wrote(obj, mod):
    state.stack_changed.add((obj.as_pointer(), mod.name))


def mesh_fingerprint(mesh):
    """Digest of what a mesh holds besides its vertex positions, which the group's input check
    does not see: counts, faces, UV maps, material indices, sharp edges, flat faces, custom
    normals present (not the deform weights: no bulk read exists for them)."""
    parts = [len(mesh.vertices), len(mesh.edges), len(mesh.loops), len(mesh.polygons),
             compat.get_corner_verts(mesh), compat.get_material_index(mesh),
             getattr(mesh, "has_custom_normals", None)]
    for layer in mesh.uv_layers:
        parts += [layer.name, compat.get_uvs(mesh, layer)]
    flags = np.empty(len(mesh.edges), dtype=bool)
    mesh.edges.foreach_get("use_edge_sharp", flags)
    smooth = np.empty(len(mesh.polygons), dtype=bool)
    mesh.polygons.foreach_get("use_smooth", smooth)
    parts += [flags, smooth]
    return inputs.digest(*parts)


def shows_result(mesh, results):
    """Whether an evaluated mesh is one of the given result meshes (then the group showed a
    result, not its input): same counts and positions."""
    for res in results:
        if res is None or len(res.vertices) != len(mesh.vertices) or \
                len(res.polygons) != len(mesh.polygons) or len(res.vertices) == 0:
            continue
        if (compat.get_positions(res) == compat.get_positions(mesh)).all():
            return True
    return False


def defer(obj, mods):
    """Inside a depsgraph handler the depsgraph must not be evaluated again (Blender 3.4-5.1
    crash there after a relations update): the modifiers' frame ranges are cleared instead, so
    that the next evaluation passes their input through, where the next handler call reads
    it. In a window a timer runs that update at once (state.pending_timers: the handlers
    register it after their round); in background mode the next update does (or
    smooth_ffd.update)."""
    for m in mods:
        frames.set_frames(m, "Result", state.NEVER)
    obj.update_tag()
    state.stack_counters["deferred"] += 1
    state.pending_timers.add("stack")
    raise Deferred()


def force_passthrough(obj, mods, depsgraph):
    """Clears the frame ranges of these modifiers (they pass their input through) and
    evaluates the depsgraph again, with the handlers muted. Only outside depsgraph handlers
    (load, scripts, timers). The caller writes the ranges again (every modifier listed is
    updated after this one in the same call)."""
    for m in mods:
        frames.set_frames(m, "Result", state.NEVER)
        state.stack_changed.add((obj.as_pointer(), m.name))
    obj.update_tag()
    state.stack_counters["forced"] += 1
    with state.muted():
        depsgraph.update()


def source(obj, mod, settings, st, stack, p, groups=True):
    """The stack's geometry at mod's position as a meshio.SourceMesh (EVALUATED: from the
    evaluated object; CHAIN: from the Smooth FFD right above), read again only when it may
    have changed; the modifier's Stack Object follows it. p: the update's state.Pass.
    groups: read every vertex group (to carry them; a Python loop over the vertices), else
    only the Vertex Group setting's."""
    if nodegroup.layout(mod.node_group) != nodegroup.GROUP_LAYOUT:
        nodegroup.migrate(mod)   # a group of an older add-on: no Stack Object or Input Copy
    fp = settings_fingerprint(obj, stack)
    groups = groups or bool(settings.vertex_group)
    setting = (settings.vertex_group, settings.invert, groups)
    same = st.source is not None and st.source_kind == stack.kind and st.stack_fp == fp \
        and st.source_setting == setting
    ro = objects.result_object(obj, mod, create=False)
    if stack.kind == CHAIN:
        mesh, names, token, shown_by = _upper_output(obj, stack.upper, p.depsgraph)
        objects.set_stack_object(obj, mod, shown_by)
        set_input_copy(obj, mod, stack)
        if same and token is not None and st.upper_key == token:
            return st.source
        mesh_fp = None
    else:
        names, token = [g.name for g in obj.vertex_groups], None
    group_index = names.index(settings.vertex_group) if settings.vertex_group in names else None

    def read(mesh):
        return meshio.SourceMesh(mesh, group_index, settings.invert, names if groups else ())
    if stack.kind == CHAIN:
        src = read(mesh)
    else:
        src, mesh_fp = _evaluated_input(obj, mod, ro, st, stack, p, same, read)
        if src is None:
            return st.source
    state.stack_counters["reads"] += 1
    src.keep_normals_of(st.source)
    if stack.kind == EVALUATED and nodegroup.layout(mod.node_group) in nodegroup.STACK_LAYOUTS:
        so = objects.stack_object(obj, mod, ro)
        objects.record(so, src.positions)
        objects.set_stack_object(obj, mod, so)
    st.source, st.source_stamp, st.source_kind = src, None, stack.kind
    st.stack_fp, st.upper_key, st.source_setting = fp, token, setting
    st.mesh_fp = mesh_fp
    return src


def _upper_output(obj, upper, depsgraph):
    """(mesh, vertex group names, key, object shown) of what the Smooth FFD modifier right
    above shows on this frame: its bake, or its result (key: that result's input fingerprint;
    None: read it every time)."""
    frame = frames.scene_frame(depsgraph=depsgraph)
    ro = objects.result_object(obj, upper, create=False)
    names = [g.name for g in ro.vertex_groups] if ro is not None else []
    if frames.in_bake(upper, frame):
        host = objects.bake_object(upper)
        if host is not None:
            return host.evaluated_get(depsgraph).data, names, None, host
    st = state.of_result(ro)
    if st is not None and st.deferred:
        raise Deferred()       # its range and this one's are cleared: both read next time
    shown = frames.get_frames(upper, "Result")
    if st is None or st.last_key is None or not state.covers(shown, frame):
        raise inputs.SmoothFFDError(f"the Smooth FFD modifier above ({upper.name!r}) has no "
                                 f"result for this frame, so neither has this one")
    return ro.data, names, st.last_key, ro


def _evaluated_input(obj, mod, ro, st, stack, p, same, read):
    """(read(mesh), its fingerprint) for the stack's geometry here: the evaluated object where
    this modifier and every Smooth FFD below it passed their input through, or with other
    modifiers below, the input copy this one passed through (input_copy); (None, None) when
    the last reading still holds. Where the evaluation showed a result (the group found the
    input at the Stack Object's vertices) and something its check does not see may have
    changed (`triggered`: the mesh's other data, settings above), the input is read through
    one more evaluation (force_passthrough, outside handlers) or on the next one (defer).
    Turning the Input Copy on or off is such a change too."""
    depsgraph = p.depsgraph
    frame = frames.scene_frame(depsgraph=depsgraph)
    # Without the input copy the evaluated object must show this input, so every Smooth FFD
    # below passes it through too; the copy passes Smooth FFD modifiers below (nodegroup)
    # whether they show a result, a bake or their input.
    mods = [mod] if stack.copy else [mod] + stack.sffd_below
    if not stack.copy and any(frames.in_bake(m, frame) for m in stack.sffd_below):
        raise inputs.SmoothFFDError("a Smooth FFD modifier below is baked on this frame: the "
                                 "stack's geometry here is not shown (clear its bake)")
    results = [r.data for r in (objects.result_object(obj, m, create=False)
                                for m in mods) if r is not None]
    # A Smooth FFD above wrote, or passed its input through, since the evaluation: the stack
    # here is not what the next evaluation shows.
    stale = any((obj.as_pointer(), m.name) in state.stack_changed for m in stack.above)
    switched = set_input_copy(obj, mod, stack)
    if not stale and not switched:
        got = _passed_through(obj, stack, depsgraph, results, read)
        if got is not None:
            return got, mesh_fingerprint(obj.data)
        if same and not _needs_reading(obj, st, stack, p.changed, p.frame_change):
            return None, None
    if not p.can_evaluate:
        defer(obj, mods)
    force_passthrough(obj, mods, depsgraph)
    for m in stack.above:
        state.stack_changed.discard((obj.as_pointer(), m.name))
    got = _passed_through(obj, stack, depsgraph, results, read)
    if got is None:
        nodes = [m.name for m in stack.other_below if m.type == 'NODES']
        if stack.copy and nodes:
            raise inputs.SmoothFFDError(
                "the stack's geometry at this modifier could not be read: its input copy (an "
                "instance) did not reach the evaluated object, so a Geometry Nodes modifier "
                f"below ({', '.join(map(repr, nodes))}) drops or realizes instances; move it "
                "above Smooth FFD or apply it")
        raise inputs.SmoothFFDError("the stack's geometry at this modifier could not be read "
                                    "(a result is still shown)")
    return got, mesh_fingerprint(obj.data)


def _passed_through(obj, stack, depsgraph, results, read):
    """read(the stack's geometry here) when the last evaluation passed it through, else
    None."""
    if stack.copy:
        return input_copy(obj, stack.marker, depsgraph, read)
    mesh = obj.evaluated_get(depsgraph).data
    return None if shows_result(mesh, results) else read(mesh)


def set_input_copy(obj, mod, stack):
    """Sets the modifier's Input Copy: its place in the stack while other modifiers follow it
    (viewport or render), else 0. True when that changed it (the group's output changes on
    the next evaluation)."""
    if nodegroup.layout(mod.node_group) not in nodegroup.COPY_LAYOUTS:
        return False
    want = stack.marker if stack.kind == EVALUATED and any(
        not nodegroup.is_smooth_ffd_modifier(m) and (m.show_viewport or m.show_render)
        for m in stack.below_all) else 0
    if compat.get_modifier_input(mod, "Input Copy") == want:
        return False
    compat.set_modifier_input(mod, "Input Copy", want)
    obj.update_tag()
    return True


def input_copy(obj, marker, depsgraph, read):
    """read(mesh) of the input copy that the Smooth FFD modifier at 1-based place `marker`
    passed through in the last evaluation (nodegroup: an instance of its input mesh at scale
    0, translated to (0, 0, marker) in the object's space), or None when it did not (it
    showed a result). 5.0+: from the evaluated object's geometry set; before: among the
    depsgraph's instances, whose mesh lives while the iterator is on it (read there)."""
    ob_eval = obj.evaluated_get(depsgraph)

    def is_copy(x, y, z):
        return abs(x) < 0.25 and abs(y) < 0.25 and abs(z - marker) < 0.25
    if compat.HAS_EVALUATED_GEOMETRY:
        geometry = ob_eval.evaluated_geometry()
        points = geometry.instances_pointcloud()
        if points is None:
            return None
        n = len(points.points)
        xf = np.empty(16 * n, np.float32)     # column-major 4x4 a point
        points.attributes["instance_transform"].data.foreach_get("value", xf)
        ref = np.empty(n, np.int32)
        points.attributes[".reference_index"].data.foreach_get("value", ref)
        refs = geometry.instance_references()
        for i, m in enumerate(xf.reshape(n, 4, 4)):
            if is_copy(*m[3, :3]) and not m[:3, :3].any():
                target = refs[ref[i]]
                mesh = getattr(target, "mesh", None)
                if mesh is not None:
                    return read(mesh)
        return None
    inverse = ob_eval.matrix_world.inverted_safe()
    for inst in depsgraph.object_instances:
        if not inst.is_instance or inst.parent is None or inst.parent.original != obj or \
                inst.object is None or inst.object.type != 'MESH':
            continue
        if is_copy(*(inverse @ inst.matrix_world.translation)):
            return read(inst.object.data)
    return None


def _needs_reading(obj, st, stack, changed, frame_change):
    """With a result shown (the input has the vertices it was computed from): whether
    something else the input holds may have changed since it was read: on a new frame, a stack
    that changes with time; on an edit, the mesh's other data (mesh_fingerprint), or IDs that
    modifiers above take UV maps, weights or normals from."""
    if frame_change:
        # A new frame with a stack that changes with time finds no result (it belongs to its
        # own frame only); a result shown here is for this frame, or for a static stack.
        return False
    if changed is None:
        return True
    geometry, transform = changed
    if obj.data in geometry and mesh_fingerprint(obj.data) != st.mesh_fp:
        return True
    return any(m.type in NON_POSITIONAL_TYPES and set(referenced_ids(m)) & (geometry | transform)
               for m in stack.above)
