"""The "Smooth FFD" Geometry Nodes group that stands in for a modifier type.

Python cannot register a modifier type, so each Smooth FFD is a Geometry Nodes modifier using
this group: its inputs are the settings shown in the modifier panel, and its output is the
geometry of a hidden result object (Object Info, Original space) that the handlers keep up to
date. The group itself decides, without Python, which geometry a frame gets (so a file opened
where the add-on does not run never shows one frame's result on another frame):

- inside the bake's frames [Bake From, Bake To): the bake (bake.py), whatever else holds;
- else inside the frames the live result belongs to [Result From, Result To) (the add-on
  writes the frame it computed, or the whole timeline when nothing the result depends on
  is animated), and, where the modifier reads the stack's geometry above it (a Stack
  Object is set, stack_input), only while its input has the vertices of that Stack Object
  (the input the result was computed from: same count, same positions): the live result;
- else the source geometry, unchanged (no result for this frame, or an error); on Blender
  4.5+ a Warning node then says so in the modifier panel.

Layouts (the group's GROUP_TAG value): 1, Backend a text input (Blender 3.4-4.0); 2, Backend a
menu (4.1+: a menu socket feeding a Menu Switch node, which defines the items); 3 and 4, the
same with the frame ranges and the bake (Show Result folded into the result's frame range);
5 and 6, the same with the Stack Object and its input check; 7 and 8, the same with the Input
Copy; 9 and 10, the same with the Result Points; 11 and 12, the same with the tessellation
modes (Level, Tolerance, Screen: TESS_INPUTS). Files made with an older layout are moved
to this Blender's when opened (migrate), keeping every setting.

Input Copy (an int k, 0: off): where other modifiers follow it, the evaluated object shows
their output, not this modifier's input. While k > 0, the group's passed-through geometry
carries its input mesh once more as an instance at scale 0 (invisible), translated to
(0, 0, k) in the object's space so that the add-on finds it among the evaluated instances
(stack_input.input_copy). Modifiers other than Geometry Nodes operate on the mesh only and
pass instances on unchanged, and so does this group where it shows a result or a bake (in
layouts 7 and 8 the input's instances go on beside it, as Blender's Lattice modifier leaves
them), so the copy reaches the evaluated object.

Result Points (layouts 9 and 10): a hidden mesh of vertices only. Where it has as many
vertices as the result mesh, the group moves the result's vertices to its positions (Sample
Index by index, Set Position); else (no object, or emptied) the result is shown as it is. On
Blender before 3.6 (no implicit sharing: every change to the result mesh copies all of it
again, its topology, UV maps and attributes, in the depsgraph) the add-on sends
positions-only updates (live editing without exact normals) through it and leaves the result
mesh's topology untouched (write.write_result); every other write empties it.
"""
import bpy

from . import compat, core, state

GROUP_NAME = "Smooth FFD"
GROUP_TAG = "smooth_ffd_group"   # custom property marking our group (value: layout version)
TEXT_LAYOUT, MENU_LAYOUT = 1, 2              # before the frame ranges (files of older add-ons)
TEXT_FRAMES_LAYOUT, MENU_FRAMES_LAYOUT = 3, 4   # before the Stack Object (older add-ons)
TEXT_STACK_LAYOUT, MENU_STACK_LAYOUT = 5, 6      # before the Input Copy (older add-ons)
TEXT_COPY_LAYOUT, MENU_COPY_LAYOUT = 7, 8      # before the Result Points (older add-ons)
TEXT_POINTS_LAYOUT, MENU_POINTS_LAYOUT = 9, 10   # before the tessellation modes (older add-ons)
TEXT_TESS_LAYOUT, MENU_TESS_LAYOUT = 11, 12
GROUP_LAYOUT = MENU_TESS_LAYOUT if compat.HAS_MENU_SOCKET else TEXT_TESS_LAYOUT
MENU_LAYOUTS = (MENU_LAYOUT, MENU_FRAMES_LAYOUT, MENU_STACK_LAYOUT, MENU_COPY_LAYOUT,
                MENU_POINTS_LAYOUT, MENU_TESS_LAYOUT)
TESS_LAYOUTS = (TEXT_TESS_LAYOUT, MENU_TESS_LAYOUT)
POINTS_LAYOUTS = (TEXT_POINTS_LAYOUT, MENU_POINTS_LAYOUT) + TESS_LAYOUTS
COPY_LAYOUTS = (TEXT_COPY_LAYOUT, MENU_COPY_LAYOUT) + POINTS_LAYOUTS
STACK_LAYOUTS = (TEXT_STACK_LAYOUT, MENU_STACK_LAYOUT) + COPY_LAYOUTS
FRAMES_LAYOUTS = (TEXT_FRAMES_LAYOUT, MENU_FRAMES_LAYOUT) + STACK_LAYOUTS
LAYOUTS = (TEXT_LAYOUT, MENU_LAYOUT) + FRAMES_LAYOUTS
# A socket maximum the core decides (its MAX_LEVEL), asked when a group is built.
CORE_MAX_LEVEL = "the core's MAX_LEVEL"

# (name, socket type, default, min, max, description); order = panel order.
SETTINGS = (
    ("Lattice", 'NodeSocketObject', None, None, None, "Lattice object that deforms the mesh"),
    ("Viewport Level", 'NodeSocketInt', 3, 1, CORE_MAX_LEVEL,
     "Sub-triangles per patch edge in the viewport"),
    ("Render Level", 'NodeSocketInt', 10, 1, CORE_MAX_LEVEL,
     "Sub-triangles per patch edge for render and Apply"),
    # Layouts 11 and 12: the tessellation modes (a menu on 4.1+, text before: MENU_ITEMS).
    ("Viewport Tessellation", 'NodeSocketString', "level", None, None, None),
    ("Viewport Tolerance", 'NodeSocketFloat', 0.001, 1e-7, 1e6,
     "Tolerance mode: every triangle within this distance (object units) of its smooth patch"),
    ("Viewport Max Level", 'NodeSocketInt', 16, 1, CORE_MAX_LEVEL,
     "Tolerance mode: at most this many segments a patch edge in the viewport"),
    ("Render Tessellation", 'NodeSocketString', "level", None, None, None),
    ("Render Tolerance", 'NodeSocketFloat', 0.001, 1e-7, 1e6,
     "Tolerance mode (and Screen without a camera): every triangle within this distance "
     "(object units) of its smooth patch"),
    ("Render Pixel Size", 'NodeSocketFloat', 1.0, 0.01, 1e4,
     "Screen mode: the tolerance in pixels of the render camera, at the object's nearest point"),
    ("Render Max Level", 'NodeSocketInt', 64, 1, CORE_MAX_LEVEL,
     "Tolerance and Screen modes: at most this many segments a patch edge for render and Apply"),
    ("Backend", 'NodeSocketString', "auto", None, None, None),   # a menu on 4.1+ (_backend_text)
    ("Strength", 'NodeSocketFloat', 1.0, -1e6, 1e6, "Deformation strength (as the Lattice modifier)"),
    ("Vertex Group", 'NodeSocketString', "", None, None, "Vertex group weighting the deformation"),
    ("Invert Vertex Group", 'NodeSocketBool', False, None, None, "Use 1 - weight"),
    ("Exact Normals", 'NodeSocketBool', False, None, None,
     "Blender 3.4-4.4: write exact custom normals in the viewport too (slow on big meshes)"),
    ("Status", 'NodeSocketString', "", None, None, "Backend used, last update time, or the error"),
)
# Internal inputs written by the add-on, hidden from the panel where Blender allows it (4.2+).
FRAMES_INTERNAL_INPUTS = (
    ("Result Object", 'NodeSocketObject', None, None, None, "Internal: the hidden result mesh"),
    ("Result From", 'NodeSocketFloat', state.NEVER[0], None, None,
     "Internal: first frame the result belongs to"),
    ("Result To", 'NodeSocketFloat', state.NEVER[1], None, None,
     "Internal: end (exclusive) of the frames the result belongs to"),
    ("Bake Object", 'NodeSocketObject', None, None, None, "Internal: the baked frames"),
    ("Bake From", 'NodeSocketFloat', state.NEVER[0], None, None,
     "Internal: first baked frame - 1/2"),
    ("Bake To", 'NodeSocketFloat', state.NEVER[1], None, None,
     "Internal: last baked frame + 1/2"),
)
STACK_INTERNAL_INPUTS = FRAMES_INTERNAL_INPUTS + (
    ("Stack Object", 'NodeSocketObject', None, None, None,
     "Internal: the vertices of the input the result was computed from (stack_input)"),
)
COPY_INTERNAL_INPUTS = STACK_INTERNAL_INPUTS + (
    ("Input Copy", 'NodeSocketInt', 0, None, None,
     "Internal: nonzero while other modifiers follow: the input also passes as a hidden "
     "instance (stack_input)"),
)
INTERNAL_INPUTS = COPY_INTERNAL_INPUTS + (
    ("Result Points", 'NodeSocketObject', None, None, None,
     "Internal: the result's vertex positions, when they were sent without the result mesh"),
)
INPUTS = SETTINGS + INTERNAL_INPUTS
# The tessellation modes' inputs (layouts 11 and 12) and their items: a menu on 4.1+ (as the
# Backend), a text before (any case).
MENU_ITEMS = (("Viewport Tessellation", ("Level", "Tolerance")),
              ("Render Tessellation", ("Level", "Tolerance", "Screen")))
MENU_NAMES = tuple(name for name, _ in MENU_ITEMS)


def menu_items(name):
    return dict(MENU_ITEMS)[name]
TESS_INPUTS = ("Viewport Tessellation", "Viewport Tolerance", "Viewport Max Level",
               "Render Tessellation", "Render Tolerance", "Render Pixel Size", "Render Max Level")
INTERNAL = tuple(name for name, *_ in INTERNAL_INPUTS)
# Layouts 1 and 2 (older files): a validity flag instead of the frame ranges, no bake.
OLD_INTERNAL_INPUTS = (
    ("Result Object", 'NodeSocketObject', None, None, None, "Internal: the hidden result mesh"),
    ("Show Result", 'NodeSocketBool', False, None, None, "Internal: the result is valid"),
)
STALE_MESSAGE = ("Smooth FFD: no result for this frame or this input (the add-on did not "
                 "compute it, see Status): showing the input")


def is_smooth_ffd_group(group):
    return group is not None and group.get(GROUP_TAG) is not None


def is_smooth_ffd_modifier(mod):
    return mod.type == 'NODES' and is_smooth_ffd_group(mod.node_group)


def layout(group):
    return group.get(GROUP_TAG) if group is not None else None


def find_group():
    for group in bpy.data.node_groups:
        if is_smooth_ffd_group(group) and layout(group) == GROUP_LAYOUT:
            return group
    return None


def ensure_group():
    """The shared node group, created on first use (one group serves every modifier)."""
    group = find_group()
    if group is None:
        group = _build_group()
    return group


def _build_group(group_layout=GROUP_LAYOUT):
    """group_layout: an older layout (TEXT_LAYOUT, ...) builds that layout's group in any
    version (tests of migrate)."""
    group = bpy.data.node_groups.new(GROUP_NAME, 'GeometryNodeTree')
    group[GROUP_TAG] = group_layout
    menu = group_layout in MENU_LAYOUTS
    frames = group_layout in FRAMES_LAYOUTS
    stack = group_layout in STACK_LAYOUTS
    copy = group_layout in COPY_LAYOUTS
    points = group_layout in POINTS_LAYOUTS
    tess = group_layout in TESS_LAYOUTS
    compat.new_group_socket(group, 'INPUT', 'NodeSocketGeometry', "Geometry")
    internal = INTERNAL_INPUTS if points else COPY_INTERNAL_INPUTS if copy else \
        STACK_INTERNAL_INPUTS if stack else FRAMES_INTERNAL_INPUTS if frames else \
        OLD_INTERNAL_INPUTS
    for name, stype, default, lo, hi, desc in SETTINGS + internal:
        if name in TESS_INPUTS and not tess:
            continue
        if name == "Backend":
            if menu:
                stype, default = 'NodeSocketMenu', None
            desc = _backend_text(menu)
        elif name in MENU_NAMES:
            if menu:
                stype, default = 'NodeSocketMenu', None
            desc = _menu_text(name, menu)
        sock = compat.new_group_socket(group, 'INPUT', stype, name)
        sock.description = desc
        if default is not None:
            sock.default_value = default
        if lo is not None:
            sock.min_value = lo
            sock.max_value = core.smoothffd().MAX_LEVEL if hi == CORE_MAX_LEVEL else hi
        if name in {n for n, *_ in internal}:
            compat.hide_in_modifier(sock)
    compat.new_group_socket(group, 'OUTPUT', 'NodeSocketGeometry', "Geometry")

    nodes, links = group.nodes, group.links
    gin = nodes.new('NodeGroupInput')
    gout = nodes.new('NodeGroupOutput')
    info = nodes.new('GeometryNodeObjectInfo')
    # ORIGINAL: the result mesh is already in the source object's local space.
    info.transform_space = 'ORIGINAL'
    links.new(_out(gin, "Result Object"), info.inputs["Object"])
    gin.location, info.location, gout.location = (-900, 0), (-150, -150), (500, 0)
    if not frames:
        links.new(_switched(group, _out(gin, "Show Result"), _out(gin, "Geometry"),
                            info.outputs["Geometry"], (100, 0)), gout.inputs[0])
    else:
        result = _with_points(group, gin, info) if points else info.outputs["Geometry"]
        _frame_switches(group, gin, gout, result, stack, copy)
    if menu:
        _backend_menu(group, gin)
        if tess:
            for i, (name, items) in enumerate(MENU_ITEMS):
                _menu(group, gin, name, items, (-150, 250 + 100 * i))
    return group


def _frame_switches(group, gin, gout, result, stack=False, copy=False):
    """Source, live result (the geometry socket `result`) or bake by the frame the depsgraph
    evaluates (module docstring)."""
    nodes, links = group.nodes, group.links
    time = nodes.new('GeometryNodeInputSceneTime')
    time.location = (-650, 300)
    frame = time.outputs["Frame"]   # with the subframe (motion blur), as Blender evaluates it
    in_result = _in_range(group, frame, _out(gin, "Result From"), _out(gin, "Result To"), -300)
    if stack:
        in_result = _boolean(group, 'AND', (in_result, _stack_matches(group, gin)), (-150, 300))
    in_bake = _in_range(group, frame, _out(gin, "Bake From"), _out(gin, "Bake To"), -100)
    show_live = in_result
    if compat.HAS_WARNING_NODE:
        # The warning shows in the modifier panel whenever the source is shown instead of a
        # result. Its output (the condition, passed through) must be used or the node is
        # never evaluated: in_result AND NOT(its output), which is in_result again, and stays
        # in_result where the node is missing (a 4.5 file opened in 4.2 loses it: NOT of an
        # unlinked input is True).
        stale = _boolean(group, 'NOT', (in_result,), (-100, 450))
        warn = nodes.new('GeometryNodeWarning')
        warn.warning_type = 'WARNING'
        warn.location = (50, 450)
        links.new(stale, warn.inputs["Show"])
        warn.inputs["Message"].default_value = STALE_MESSAGE
        not_stale = _boolean(group, 'NOT', (warn.outputs["Show"],), (200, 450))
        show_live = _boolean(group, 'AND', (in_result, not_stale), (350, 450))
    parts = None
    if copy:
        # The input's parts other than its mesh (instances: an input copy of a Smooth FFD
        # above, or the user's) go on beside the result or bake, as with Blender's Lattice
        # modifier, which deforms the mesh only.
        parts = nodes.new('GeometryNodeSeparateComponents')
        parts.location = (-900, -700)
        links.new(_out(gin, "Geometry"), parts.inputs[0])
    live = _switched(group, show_live,
                     _input_copy(group, gin, parts) if copy else _out(gin, "Geometry"),
                     _with_instances(group, result, parts, (-150, -250)), (100, 0))
    bake_info = nodes.new('GeometryNodeObjectInfo')
    bake_info.transform_space = 'ORIGINAL'   # baked meshes are in the source's space too
    bake_info.location = (-150, -400)
    links.new(_out(gin, "Bake Object"), bake_info.inputs["Object"])
    baked = _switched(group, in_bake, live,
                      _with_instances(group, bake_info.outputs["Geometry"], parts, (-150, -500)),
                      (300, 0))
    links.new(baked, gout.inputs[0])


def _with_points(group, gin, info):
    """Geometry socket: the result (Object Info `info`) moved to the Result Points' positions
    where those have as many vertices as the result; else the result as it is (the switch
    evaluates only the branch it takes: no copy of the result when no points are sent)."""
    nodes, links = group.nodes, group.links
    geo = info.outputs["Geometry"]
    pts = nodes.new('GeometryNodeObjectInfo')
    pts.transform_space = 'ORIGINAL'   # written in the source object's space, as the result
    pts.location = (-650, -1000)
    links.new(_out(gin, "Result Points"), pts.inputs["Object"])
    pts_geo = pts.outputs["Geometry"]
    same_count = _compare(group, 'EQUAL', _domain_size(group, pts_geo, (-450, -1100)),
                          _domain_size(group, geo, (-450, -950)), (-250, -1050), 'INT')
    move = nodes.new('GeometryNodeSetPosition')
    move.location = (-250, -1250)
    links.new(geo, move.inputs["Geometry"])
    links.new(_sampled_position(group, pts_geo, (-450, -1250)), move.inputs["Position"])
    return _switched(group, same_count, geo, move.outputs[0], (-100, -1050))


def _stack_matches(group, gin):
    """Boolean socket: no Stack Object is set (an empty geometry), or the input geometry has
    its vertices: the same number, each at the same position (exactly: both are the stack's
    float32 positions, evaluated by the same code). The positions are compared on a switched
    geometry, so nothing is sampled without a Stack Object."""
    nodes, links = group.nodes, group.links
    geo = _out(gin, "Geometry")
    ref = nodes.new('GeometryNodeObjectInfo')
    ref.transform_space = 'ORIGINAL'
    ref.location = (-1150, 700)
    links.new(_out(gin, "Stack Object"), ref.inputs["Object"])
    ref_geo = ref.outputs["Geometry"]
    ref_size = _domain_size(group, ref_geo, (-950, 800))
    in_size = _domain_size(group, geo, (-950, 650))
    has_ref = _compare(group, 'GREATER_THAN', ref_size, 0, (-750, 850), 'INT')
    same_count = _compare(group, 'EQUAL', ref_size, in_size, (-750, 700), 'INT')
    checked = _switch(group, (-750, 550))
    cond, _false_in, true_in = _switch_sockets(checked)   # false: an empty geometry
    links.new(has_ref, cond)
    links.new(geo, true_in)
    dist = nodes.new('ShaderNodeVectorMath')
    dist.operation = 'DISTANCE'
    dist.location = (-350, 700)
    links.new(nodes.new('GeometryNodeInputPosition').outputs[0], dist.inputs[0])
    links.new(_sampled_position(group, ref_geo, (-550, 700)), dist.inputs[1])
    stat = nodes.new('GeometryNodeAttributeStatistic')
    stat.data_type = 'FLOAT'
    stat.domain = 'POINT'
    stat.location = (-150, 700)
    links.new(_switch_out(checked), next(s for s in stat.inputs if s.type == 'GEOMETRY'))
    links.new(next(s for s in dist.outputs if s.type == 'VALUE'),
              next(s for s in stat.inputs if s.enabled and s.type == 'VALUE'))
    biggest = next(s for s in stat.outputs if s.enabled and s.name == "Max")
    same_place = _compare(group, 'LESS_EQUAL', biggest, 0.0, (50, 700))
    same = _boolean(group, 'AND', (same_count, same_place), (250, 700))
    no_ref = _boolean(group, 'NOT', (has_ref,), (250, 850))
    return _boolean(group, 'OR', (no_ref, same), (450, 800))


def _sampled_position(group, geometry, location):
    """Vector field socket: the position of `geometry`'s point with the evaluated element's
    index (Sample Index)."""
    nodes, links = group.nodes, group.links
    sample = nodes.new('GeometryNodeSampleIndex')
    sample.data_type = 'FLOAT_VECTOR'
    sample.domain = 'POINT'
    sample.location = location
    links.new(geometry, next(s for s in sample.inputs if s.type == 'GEOMETRY'))
    links.new(nodes.new('GeometryNodeInputPosition').outputs[0],
              next(s for s in sample.inputs if s.enabled and s.type == 'VECTOR'))
    links.new(nodes.new('GeometryNodeInputIndex').outputs[0],
              next(s for s in sample.inputs if s.enabled and s.type == 'INT'))
    return next(s for s in sample.outputs if s.enabled and s.type == 'VECTOR')


def _with_instances(group, geometry, parts, location):
    """Geometry socket: `geometry` joined with the instances of the input (parts: the
    input's Separate Components node; None: `geometry` alone)."""
    if parts is None:
        return geometry
    join = group.nodes.new('GeometryNodeJoinGeometry')
    join.location = location
    group.links.new(geometry, join.inputs[0])
    group.links.new(parts.outputs["Instances"], join.inputs[0])
    return join.outputs[0]


def _input_copy(group, gin, parts):
    """Geometry socket: the input, and while Input Copy k > 0 also its mesh (parts: the
    input's Separate Components node) as an instance at scale 0 translated to (0, 0, k)
    (module docstring)."""
    nodes, links = group.nodes, group.links
    geo = _out(gin, "Geometry")
    inst = nodes.new('GeometryNodeGeometryToInstance')
    inst.location = (-700, -700)
    links.new(parts.outputs["Mesh"], inst.inputs[0])
    where = nodes.new('ShaderNodeCombineXYZ')
    where.location = (-700, -850)
    links.new(_out(gin, "Input Copy"), where.inputs["Z"])
    move = nodes.new('GeometryNodeTransform')
    move.location = (-500, -700)
    links.new(inst.outputs[0], move.inputs["Geometry"])
    links.new(where.outputs[0], move.inputs["Translation"])
    move.inputs["Scale"].default_value = (0.0, 0.0, 0.0)
    join = nodes.new('GeometryNodeJoinGeometry')
    join.location = (-300, -650)
    links.new(geo, join.inputs[0])
    links.new(move.outputs[0], join.inputs[0])
    on = _compare(group, 'GREATER_THAN', _out(gin, "Input Copy"), 0, (-500, -550), 'INT')
    return _switched(group, on, geo, join.outputs[0], (-100, -600))


def _domain_size(group, geometry, location):
    """Point count of a geometry's mesh."""
    node = group.nodes.new('GeometryNodeAttributeDomainSize')
    node.component = 'MESH'
    node.location = location
    group.links.new(geometry, node.inputs[0])
    return node.outputs["Point Count"]


def _in_range(group, value, lo, hi, y):
    """Boolean socket: lo <= value < hi."""
    ge = _compare(group, 'GREATER_EQUAL', value, lo, (-450, y))
    lt = _compare(group, 'LESS_THAN', value, hi, (-450, y - 60))
    return _boolean(group, 'AND', (ge, lt), (-300, y))


def _compare(group, operation, a, b, location, data_type='FLOAT'):
    node = group.nodes.new('FunctionNodeCompare')
    node.data_type = data_type
    node.operation = operation
    node.location = location
    sock_a, sock_b = [s for s in node.inputs if s.enabled][:2]
    for sock, src in ((sock_a, a), (sock_b, b)):
        if isinstance(src, (int, float)):
            sock.default_value = int(src) if data_type == 'INT' else float(src)
        else:
            group.links.new(src, sock)
    return node.outputs[0]


def _boolean(group, operation, operands, location):
    node = group.nodes.new('FunctionNodeBooleanMath')
    node.operation = operation
    node.location = location
    for sock, src in zip([s for s in node.inputs if s.enabled], operands):
        group.links.new(src, sock)
    return node.outputs[0]


def _switch(group, location):
    switch = group.nodes.new('GeometryNodeSwitch')
    switch.input_type = 'GEOMETRY'
    switch.location = location
    return switch


def _switched(group, condition, if_false, if_true, location):
    """Geometry socket: if_true where the boolean socket condition is true, else if_false
    (a Switch node: it evaluates only the side it takes)."""
    switch = _switch(group, location)
    cond, false_in, true_in = _switch_sockets(switch)
    group.links.new(condition, cond)
    group.links.new(if_false, false_in)
    group.links.new(if_true, true_in)
    return _switch_out(switch)


def _switch_out(switch):
    return switch.outputs[_first_enabled(switch.outputs, 'GEOMETRY')]


def backend_items():
    """The Backend menu's items (4.1+): the core's DEVICES, 'auto' as a word and the devices
    as the acronyms they are (core.parse_backend reads any case)."""
    names = core.smoothffd().DEVICES
    return tuple(n.title() if i == 0 else n.upper() for i, n in enumerate(names))


def _backend_text(menu):
    """The Backend input's description: its items (menu) or the names it takes (text)."""
    items = backend_items() if menu else core.smoothffd().DEVICES
    first = f"{items[0]} (CUDA when usable)" if menu else items[0]
    return f"{', '.join((first,) + tuple(items[1:-1]))} or {items[-1]}"


def _menu_text(name, menu):
    """A tessellation mode input's description: its items (menu) or the words it takes."""
    items = menu_items(name)
    words = items if menu else tuple(i.lower() for i in items)
    return (f"{', '.join(words[:-1])} or {words[-1]}: a fixed level, every triangle within a "
            f"tolerance" + (", or within a pixel size of the render camera" if len(items) > 2
                            else ""))


def parse_mode(name, value):
    """A tessellation mode input's value (menu item or text, any case) -> 'level',
    'tolerance' or 'screen'; an empty value is the first item; anything else raises
    ValueError."""
    items = [i.lower() for i in menu_items(name)]
    v = str(value or items[0]).strip().lower()
    if v not in items:
        raise ValueError(f"{name.lower()} must be one of {', '.join(items)}, not {value!r}")
    return v


def _backend_menu(group, gin):
    """4.1+: the Backend menu's items come from a Menu Switch node fed by the input (Blender
    infers a menu socket's items from the Menu Switch it is linked to). The switch's output
    is not used: the add-on reads the modifier's setting, the node only defines the items."""
    _menu(group, gin, "Backend", backend_items(), (-150, 150))


def _menu(group, gin, name, names, location):
    """4.1+: a menu input's items, from a Menu Switch node it feeds (_backend_menu)."""
    node = group.nodes.new('GeometryNodeMenuSwitch')
    node.label = f"{name} items"
    node.location = location
    node.data_type = 'INT'
    items = node.enum_items if hasattr(node, "enum_items") else node.enum_definition.enum_items
    while len(items) > len(names):
        items.remove(items[len(items) - 1])
    for i, item in enumerate(names):
        if i < len(items):
            items[i].name = item
        else:
            items.new(item)
    group.links.new(_out(gin, name), node.inputs[0])
    # Only once linked does the socket know the items (else: "enum not found").
    compat.input_socket(group, name).default_value = names[0]


def migrate(mod):
    """Moves a modifier using an older layout's group (a file from an older add-on or from
    3.4-4.0) to this Blender's group, keeping every setting; returns True when it did. Only
    upgrades: text to menu, no frame ranges to frame ranges, no Stack Object (or no Input
    Copy, or no Result Points) to one."""
    old = mod.node_group
    old_layout = layout(old)
    if not is_smooth_ffd_group(old) or old_layout not in LAYOUTS \
            or old_layout == GROUP_LAYOUT \
            or (old_layout in MENU_LAYOUTS and GROUP_LAYOUT not in MENU_LAYOUTS) \
            or (old_layout in FRAMES_LAYOUTS and GROUP_LAYOUT not in FRAMES_LAYOUTS) \
            or (old_layout in STACK_LAYOUTS and GROUP_LAYOUT not in STACK_LAYOUTS) \
            or (old_layout in COPY_LAYOUTS and GROUP_LAYOUT not in COPY_LAYOUTS) \
            or (old_layout in POINTS_LAYOUTS and GROUP_LAYOUT not in POINTS_LAYOUTS) \
            or (old_layout in TESS_LAYOUTS and GROUP_LAYOUT not in TESS_LAYOUTS):
        return False
    values = {}
    for name, *_ in INPUTS:
        try:
            values[name] = compat.get_modifier_input(mod, name)
        except KeyError:            # an input the old layout did not have: its default
            pass
    mod.node_group = ensure_group()
    # Inputs the old layout lacked get their defaults: on 3.4-4.0 the modifier's values are
    # keyed by position (Input_N), so a new input would otherwise take an old one's value.
    for name, _stype, default, *_ in INPUTS:
        if name in values or default is None:
            continue
        if name in MENU_NAMES:
            default = menu_items(name)[0]
        try:
            compat.set_modifier_input(mod, name, default)
        except KeyError:            # not an input of this layout
            pass
    for name, value in values.items():
        if value is None:           # an empty object input: already empty
            continue
        if name == "Backend":
            names = core.smoothffd().DEVICES
            value = str(value).strip().lower() or names[0]
            if value not in names:   # it was an error; a menu cannot hold it
                print(f"Smooth FFD [{mod.name}]: backend {value!r} is not a menu item: {names[0]}")
                value = names[0]
        elif name in MENU_NAMES:
            items = menu_items(name)
            try:
                value = items[[i.lower() for i in items].index(parse_mode(name, value))]
            except ValueError:
                print(f"Smooth FFD [{mod.name}]: {name.lower()} {value!r} is not a menu item: "
                      f"{items[0]}")
                value = items[0]
        compat.set_modifier_input(mod, name, value)
    # An old group's result had no frame range: shown nowhere until the handlers write one
    # (load_post recomputes every modifier).
    if old.users == 0:
        bpy.data.node_groups.remove(old)
    return True


def _out(node, name):
    for s in node.outputs:
        if s.name == name:
            return s
    raise KeyError(name)


def _first_enabled(sockets, stype):
    for i, s in enumerate(sockets):
        if s.type == stype and s.enabled:
            return i
    raise KeyError(stype)


def _switch_sockets(switch):
    """(condition, false, true) inputs of a geometry Switch; 3.4 has one socket set per type."""
    enabled = [s for s in switch.inputs if s.enabled]
    cond = next(s for s in enabled if s.type == 'BOOLEAN')
    geo = [s for s in enabled if s.type == 'GEOMETRY']
    return cond, geo[0], geo[1]
