"""The "Smooth FFD" Geometry Nodes group that stands in for a modifier type.

Python cannot register a modifier type, so each Smooth FFD is a Geometry Nodes modifier using
this group: its inputs are the settings shown in the modifier panel, and its output is the
geometry of a hidden result object (Object Info, Original space) that the handlers keep up to
date; while no valid result exists, a Switch passes the source geometry through unchanged.
"""
import bpy

from . import compat

GROUP_NAME = "Smooth FFD"
GROUP_TAG = "smooth_ffd_group"   # custom property marking our group (value: layout version)
GROUP_LAYOUT = 1

# (name, socket type, default, min, max, description); order = panel order.
INPUTS = (
    ("Lattice", 'NodeSocketObject', None, None, None, "Lattice object that deforms the mesh"),
    ("Viewport Level", 'NodeSocketInt', 3, 1, 64, "Sub-triangles per patch edge in the viewport"),
    ("Render Level", 'NodeSocketInt', 10, 1, 64, "Sub-triangles per patch edge for render and Apply"),
    ("Backend", 'NodeSocketString', "auto", None, None, "auto, cpu or cuda"),
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


def find_group():
    for group in bpy.data.node_groups:
        if is_smooth_ffd_group(group) and group.get(GROUP_TAG) == GROUP_LAYOUT:
            return group
    return None


def ensure_group():
    """The shared node group, created on first use (one group serves every modifier)."""
    group = find_group()
    if group is None:
        group = _build_group()
    return group


def _build_group():
    group = bpy.data.node_groups.new(GROUP_NAME, 'GeometryNodeTree')
    group[GROUP_TAG] = GROUP_LAYOUT
    compat.new_group_socket(group, 'INPUT', 'NodeSocketGeometry', "Geometry")
    for name, stype, default, lo, hi, desc in INPUTS:
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
    return group


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
