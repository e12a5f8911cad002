"""The "Smooth FFD" Geometry Nodes group that stands in for a modifier type.

Python cannot register a modifier type, so each Smooth FFD is a Geometry Nodes modifier using
this group: its inputs are the settings shown in the modifier panel, and its output is the
geometry of a hidden result object (Object Info, Original space) that the handlers keep up to
date; while no valid result exists, a Switch passes the source geometry through unchanged.

Layouts (the group's GROUP_TAG value): 1, Backend a text input (Blender 3.4-4.0); 2, Backend a
menu (4.1+: a menu socket feeding a Menu Switch node, which defines the items). Files made with
layout 1 are moved to layout 2 when opened in 4.1+ (migrate), keeping every setting.
"""
import bpy

from . import compat

GROUP_NAME = "Smooth FFD"
GROUP_TAG = "smooth_ffd_group"   # custom property marking our group (value: layout version)
TEXT_LAYOUT, MENU_LAYOUT = 1, 2
GROUP_LAYOUT = MENU_LAYOUT if compat.HAS_MENU_SOCKET else TEXT_LAYOUT
BACKEND_ITEMS = ("Auto", "CPU", "CUDA")   # the menu's items (inputs.parse_backend reads any case)

# (name, socket type, default, min, max, description); order = panel order.
INPUTS = (
    ("Lattice", 'NodeSocketObject', None, None, None, "Lattice object that deforms the mesh"),
    ("Viewport Level", 'NodeSocketInt', 3, 1, 64, "Sub-triangles per patch edge in the viewport"),
    ("Render Level", 'NodeSocketInt', 10, 1, 64, "Sub-triangles per patch edge for render and Apply"),
    ("Backend", 'NodeSocketString', "auto", None, None, "auto, cpu or cuda"),   # a menu on 4.1+
    ("Strength", 'NodeSocketFloat', 1.0, -1e6, 1e6, "Deformation strength (as the Lattice modifier)"),
    ("Vertex Group", 'NodeSocketString', "", None, None, "Vertex group weighting the deformation"),
    ("Invert Vertex Group", 'NodeSocketBool', False, None, None, "Use 1 - weight"),
    ("Exact Normals", 'NodeSocketBool', False, None, None,
     "Blender 3.4-4.4: write exact custom normals in the viewport too (slow on big meshes)"),
    ("Status", 'NodeSocketString', "", None, None, "Backend used, last update time, or the error"),
    # Internal inputs written by the add-on, hidden from the panel where Blender allows it.
    ("Result Object", 'NodeSocketObject', None, None, None, "Internal: the hidden result mesh"),
    ("Show Result", 'NodeSocketBool', False, None, None, "Internal: the result is valid"),
)
INTERNAL = ("Result Object", "Show Result")


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
    """group_layout: TEXT_LAYOUT builds 3.4-4.0's group in any version (tests of migrate)."""
    group = bpy.data.node_groups.new(GROUP_NAME, 'GeometryNodeTree')
    group[GROUP_TAG] = group_layout
    menu = group_layout == MENU_LAYOUT
    compat.new_group_socket(group, 'INPUT', 'NodeSocketGeometry', "Geometry")
    for name, stype, default, lo, hi, desc in INPUTS:
        if name == "Backend" and menu:
            stype, default, desc = 'NodeSocketMenu', None, "Auto (CUDA when usable), CPU or CUDA"
        sock = compat.new_group_socket(group, 'INPUT', stype, name)
        sock.description = desc
        if default is not None:
            sock.default_value = default
        if lo is not None:
            sock.min_value, sock.max_value = lo, hi
        if name in INTERNAL:
            compat.hide_in_modifier(sock)
    compat.new_group_socket(group, 'OUTPUT', 'NodeSocketGeometry', "Geometry")

    nodes, links = group.nodes, group.links
    gin = nodes.new('NodeGroupInput')
    gout = nodes.new('NodeGroupOutput')
    info = nodes.new('GeometryNodeObjectInfo')
    # ORIGINAL: the result mesh is already in the source object's local space.
    info.transform_space = 'ORIGINAL'
    switch = nodes.new('GeometryNodeSwitch')
    switch.input_type = 'GEOMETRY'
    gin.location, info.location, switch.location, gout.location = (-400, 0), (-150, -150), (100, 0), (300, 0)

    links.new(_out(gin, "Result Object"), info.inputs["Object"])
    cond, false_in, true_in = _switch_sockets(switch)
    links.new(_out(gin, "Show Result"), cond)
    links.new(_out(gin, "Geometry"), false_in)
    links.new(info.outputs["Geometry"], true_in)
    links.new(switch.outputs[_first_enabled(switch.outputs, 'GEOMETRY')], gout.inputs[0])
    if menu:
        _backend_menu(group, gin)
    return group


def _backend_menu(group, gin):
    """4.1+: the Backend menu's items come from a Menu Switch node fed by the input (Blender
    infers a menu socket's items from the Menu Switch it is linked to). The switch's output
    is not used: the add-on reads the modifier's setting, the node only defines the items."""
    node = group.nodes.new('GeometryNodeMenuSwitch')
    node.label = "Backend items"
    node.location = (-150, 150)
    node.data_type = 'INT'
    items = node.enum_items if hasattr(node, "enum_items") else node.enum_definition.enum_items
    while len(items) > len(BACKEND_ITEMS):
        items.remove(items[len(items) - 1])
    for i, name in enumerate(BACKEND_ITEMS):
        if i < len(items):
            items[i].name = name
        else:
            items.new(name)
    group.links.new(_out(gin, "Backend"), node.inputs[0])
    # Only once linked does the socket know the items (else: "enum not found").
    compat.input_socket(group, "Backend").default_value = BACKEND_ITEMS[0]


def migrate(mod):
    """Moves a modifier using an older layout's group (a file from 3.4-4.0) to this Blender's
    group, keeping every setting; returns True when it did. Only upgrades."""
    old = mod.node_group
    if not is_smooth_ffd_group(old) or not isinstance(layout(old), int) \
            or layout(old) >= GROUP_LAYOUT:
        return False
    values = {}
    for name, *_ in INPUTS:
        try:
            values[name] = compat.get_modifier_input(mod, name)
        except KeyError:            # an input the old layout did not have: its default
            pass
    mod.node_group = ensure_group()
    for name, value in values.items():
        if value is None:           # an empty object input: already empty
            continue
        if name == "Backend":
            value = str(value).strip().lower() or "auto"
            if value not in ("auto", "cpu", "cuda"):   # it was an error; a menu cannot hold it
                print(f"Smooth FFD [{mod.name}]: backend {value!r} is not a menu item: auto")
                value = "auto"
        compat.set_modifier_input(mod, name, value)
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
