"""The first step of an update: one modifier's inputs read from Blender (its settings, the
lattice, the placement, the source mesh: the object's own or the stack's geometry above it,
stack_input) with their fingerprint, and the frames a result of them is right for."""
import bpy

from . import compat, core, inputs, latticeio, meshio, objects, stack_input, state, \
    tessellation


class Settings:
    """The modifier's settings (its group's inputs) as the update reads them."""

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


class Inputs:
    """Everything one update uses, and its fingerprint (key)."""

    def __init__(self, settings, level, backend, exact, lattice, l2o, source, key, tess):
        self.tess = tess            # tessellation.Tess: a level, or adaptive to a tolerance
        self.settings = settings
        self.level = level
        self.backend = backend
        self.exact = exact
        self.lattice = lattice      # (rest, points, interpolation, point weights)
        self.l2o = l2o
        self.source = source        # meshio.SourceMesh
        self.key = key


def _level_backend_exact(settings, render):
    level = core.parse_level(settings.render_level if render else settings.viewport_level,
                             "render level" if render else "viewport level")
    backend = core.parse_backend(settings.backend)
    # Exact custom normals up to 4.4 only when asked for (slow); 4.5+ always exact.
    exact = render or settings.exact or compat.CHEAP_EXACT_NORMALS
    return level, backend, exact


def _key(lattice_key, l2o, settings, source, level, backend, exact, tess):
    return inputs.digest(lattice_key, l2o, settings.strength, source.key, source.extras_key,
                         level, backend, exact, tess.key())


def evaluated_inputs(obj, mod, st, p, stack, groups):
    """The inputs from the evaluated depsgraph (p: the update's state.Pass)."""
    settings = Settings(mod)
    level, backend, exact = _level_backend_exact(settings, p.render)
    rest, pts, interp, _shape, lattice_key, weights = latticeio.read_lattice(settings.lattice,
                                                                             p.depsgraph)
    l2o = core.lattice_to_object(latticeio.world_matrix(obj, p.depsgraph),
                                 latticeio.world_matrix(settings.lattice, p.depsgraph))
    if stack.reads_stack:
        source = stack_input.source(obj, mod, settings, st, stack, p, groups)
    else:
        objects.set_stack_object(obj, mod, None)   # no input check for the own mesh
        stack_input.set_input_copy(obj, mod, stack)
        source = _own_source(obj, settings, st, p.mesh_changed(obj))
    box = tessellation.bounding_box(source.positions, pts, l2o) if p.render else None
    scene = p.scene if p.scene is not None else getattr(p.depsgraph, "scene", None)
    tess = tessellation.tess(mod, p.render, obj, scene, p.depsgraph, box)
    key = _key(lattice_key, l2o, settings, source, level, backend, exact, tess)
    return Inputs(settings, level, backend, exact, (rest, pts, interp, weights), l2o, source,
                  key, tess)


def early_inputs(obj, mod, st, stack, groups):
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
            up = objects.state_of(obj, stack.upper)
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
    rest, pts, interp, _shape, lattice_key, weights = latticeio.read_lattice(lat, None)
    l2o = core.lattice_to_object(obj_matrix, lat_matrix)
    tess = tessellation.tess(mod, False)
    key = _key(lattice_key, l2o, settings, st.source, level, backend, exact, tess)
    return Inputs(settings, level, backend, exact, (rest, pts, interp, weights), l2o,
                  st.source, key, tess)


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


def _own_source(obj, settings, st, mesh_changed):
    """The object's own mesh as a meshio.SourceMesh, read again only when it may have
    changed."""
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


def result_frames(obj, lattice_obj, frame, stack=None):
    """The frames a result computed at `frame` is right for: all of them when nothing it
    depends on can change with time (no animation, drivers, parents, constraints, hooks or
    shape keys on the lattice, the object or their data: the conditions of early_inputs;
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
    return state.ALWAYS if static else (frame - 0.5, frame + 0.5)
