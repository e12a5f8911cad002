"""Blender-version differences, in one place (docs/addon.md, "Blender versions").

Every other module asks this one instead of testing ``bpy.app.version`` itself, so a new
Blender release means editing only this file.
"""
import bpy
import numpy as np

from . import state

VERSION = bpy.app.version[:2]

# 4.1 removed use_auto_smooth / calc_normals_split; corner normals are always available.
HAS_CORNER_NORMALS = VERSION >= (4, 1)
# 4.5 stores free custom normals as a float3 corner attribute named "custom_normal".
HAS_FREE_NORMAL_ATTRIBUTE = VERSION >= (4, 5)
# Exact custom normals are cheap to write only from 4.5 (the attribute above, one memcpy);
# before, normals_split_custom_set costs 1-4 us a corner (measured on 4.2.23: 54 s for the
# 14M corners of a 46.8k-triangle sphere at level 10), so up to 4.4 the viewport shades the
# dense mesh with Blender's own normals unless Exact Normals is on; render and Apply are exact.
CHEAP_EXACT_NORMALS = HAS_FREE_NORMAL_ATTRIBUTE
# 4.0 replaced NodeTree.inputs/outputs with NodeTree.interface.
HAS_TREE_INTERFACE = VERSION >= (4, 0)
# 5.2 moved modifier inputs from ID properties to mod.properties.inputs.
HAS_MODIFIER_PROPERTIES = VERSION >= (5, 2)
# 4.1 added menu sockets: a group input of type NodeSocketMenu takes its items from the Menu
# Switch node it feeds; the modifier stores the chosen item's number (an int ID property whose
# UI data lists the items).
HAS_MENU_SOCKET = VERSION >= (4, 1)
# The Warning node (a message in the modifier panel, no Python needed): in 4.5 and 5.x here,
# not in 4.2; tested by the type itself rather than a version (getattr: the unit tests' fake
# bpy has no types).
HAS_WARNING_NODE = hasattr(getattr(bpy, "types", None), "GeometryNodeWarning")
# Attributes for sharp edges / flat faces replaced the MeshEdge/MeshPolygon flags.
HAS_SHARP_EDGE_ATTRIBUTE = VERSION >= (3, 5)
HAS_SHARP_FACE_ATTRIBUTE = VERSION >= (3, 6)
# Object.evaluated_geometry() (4.5+): the evaluated GeometrySet with its instances, without
# walking the depsgraph's instances. Used from 5.0: in 4.5.15 each call leaks one memory
# block (Blender prints "Not freed memory blocks" at exit; measured here).
HAS_EVALUATED_GEOMETRY = VERSION >= (5, 0)
# Before 3.6 (no implicit sharing of mesh arrays) the depsgraph copies a whole mesh, topology
# and attributes, whenever it changes: positions-only updates go through a mesh of vertices
# only (nodegroup's Result Points). Measured on 3.4.1, 767k triangles: 77 against 148 ms an
# update (and 4.1 against 6.4 ms at 63k).
POSITIONS_THROUGH_POINTS = VERSION < (3, 6)


# --- node group interface -------------------------------------------------------------------

def new_group_socket(group, in_out, socket_type, name):
    """Adds an interface socket; returns it (its identifier is assigned by Blender)."""
    if HAS_TREE_INTERFACE:
        return group.interface.new_socket(name, in_out=in_out, socket_type=socket_type)
    sockets = group.inputs if in_out == 'INPUT' else group.outputs
    return sockets.new(socket_type, name)


def group_sockets(group, in_out='INPUT'):
    """The group's interface sockets of one direction, in order."""
    if HAS_TREE_INTERFACE:
        return [item for item in group.interface.items_tree
                if item.item_type == 'SOCKET' and item.in_out == in_out]
    return list(group.inputs if in_out == 'INPUT' else group.outputs)


def hide_in_modifier(socket):
    """Hides an internal input from the modifier panel where Blender can (4.2+)."""
    if hasattr(socket, "hide_in_modifier"):
        socket.hide_in_modifier = True


def input_socket(group, name):
    """The group's interface input named `name` (KeyError when there is none)."""
    if group is None:
        raise KeyError(f"no node group: no input named {name!r}")
    for socket in group_sockets(group, 'INPUT'):
        if socket.name == name:
            return socket
    raise KeyError(f"node group {group.name!r} has no input named {name!r}")


# state.input_tables: (group pointer, session uid, number of interface items) -> {name:
# (identifier, is_menu)}. Every update reads some 30 inputs by name, and a walk over the
# group's interface through RNA costs about 10 us each (about 0.3 ms an update). Growing or
# shrinking the interface changes the key; an identifier never changes while its socket
# exists, and a lookup that misses (a renamed socket) walks the interface again.


def _interface_size(group):
    return len(group.interface.items_tree) if HAS_TREE_INTERFACE else len(group.inputs)


def _input_entry(group, name):
    """(identifier, is_menu) of the group's input named `name`; KeyError when none is."""
    if group is None:
        raise KeyError(f"no node group: no input named {name!r}")
    key = (group.as_pointer(), getattr(group, "session_uid", 0), _interface_size(group))
    table = state.input_tables.get(key)
    if table is None or name not in table:
        table = {s.name: (s.identifier, is_menu_socket(s)) for s in group_sockets(group, 'INPUT')}
        if len(state.input_tables) > 64:
            state.input_tables.clear()
        state.input_tables[key] = table
        if name not in table:
            raise KeyError(f"node group {group.name!r} has no input named {name!r}")
    return table[name]


def input_identifier(group, name):
    """Resolves a group input's identifier from its name: Input_N up to 3.6, Socket_N from 4.0."""
    return input_socket(group, name).identifier


def is_menu_socket(socket):
    """Whether an interface socket is a menu (4.1+); 3.x sockets call their type
    bl_socket_idname."""
    kind = getattr(socket, "socket_type", None) or getattr(socket, "bl_socket_idname", None)
    return kind == 'NodeSocketMenu'


def menu_items(mod, ident):
    """[(name, number)] of a menu input, from the modifier's ID-property UI data (4.1-5.1)."""
    items = mod.id_properties_ui(ident).as_dict().get("items") or ()
    return [(item[0], item[-1]) for item in items]


def _menu_name(mod, ident, value):
    """The item name a menu input's stored number stands for; the raw value when none does
    (the caller then reports it)."""
    try:
        for name, number in menu_items(mod, ident):
            if number == value:
                return name
    except (AttributeError, TypeError, KeyError):
        pass
    return value


def _menu_value(mod, ident, name):
    """The number a menu input stores for the item called `name` (any case)."""
    items = menu_items(mod, ident)
    for item, number in items:
        if item.lower() == str(name).strip().lower():
            return number
    raise ValueError(f"{name!r} is not one of {', '.join(i for i, _ in items)}")


def _input_slot(mod, ident):
    """5.2+: the modifier's input `ident` (mod.properties.inputs.<identifier>, whose .value is
    the setting); mod.properties is None while the modifier has no node group."""
    props = mod.properties
    if props is None:
        raise KeyError(f"modifier {mod.name!r} has no node group inputs")
    return getattr(props.inputs, ident)


def get_modifier_input(mod, name):
    """A Geometry Nodes modifier's input value by the group input's name: mod["Input_N"] up to
    3.6, mod["Socket_N"] from 4.0 (ID properties), mod.properties.inputs.<identifier>.value
    from 5.2. A menu input (4.1+) gives its item's name."""
    ident, menu = _input_entry(mod.node_group, name)
    value = _input_slot(mod, ident).value if HAS_MODIFIER_PROPERTIES else mod[ident]
    if not isinstance(value, str) and menu:
        value = _menu_name(mod, ident, value)
    return value


def set_modifier_input(mod, name, value):
    """Sets an input by name; a menu input (4.1+) takes its item's name (any case), and
    raises ValueError for a name that is not an item."""
    ident, menu = _input_entry(mod.node_group, name)
    if HAS_MODIFIER_PROPERTIES:
        # 5.2 (from its documentation, untested): a menu input's value is its item's name.
        _input_slot(mod, ident).value = value
        return
    if isinstance(value, str) and menu:
        value = _menu_value(mod, ident, value)
    # On 3.4 (not 4.2+) a Python float replaces the socket's float ID property by a double
    # one, dropping its "overridable" flag: library overrides of the object would not
    # record it (linked.py). Keep the flag.
    path = f'["{ident}"]'
    try:
        overridable = mod.is_property_overridable_library(path)
    except (TypeError, AttributeError):   # not set yet (or a test's stand-in)
        overridable = False
    mod[ident] = value
    if overridable and not mod.is_property_overridable_library(path):
        mod.property_overridable_library_set(path, True)


def ensure_overridable(mod, name):
    """Marks a modifier input as overridable by library overrides (up to 5.1: an ID
    property of the modifier); KeyError when the group has no such input."""
    path = f'["{input_identifier(mod.node_group, name)}"]'
    if not mod.is_property_overridable_library(path):
        mod.property_overridable_library_set(path, True)


# --- positions ------------------------------------------------------------------------------

def _position_attribute(mesh):
    # From 3.5 positions are a generic float3 attribute; its foreach path is a plain copy,
    # while vertices' "co" goes through a per-item path in 4.x/5.x (20x slower measured).
    return mesh.attributes.get("position") if VERSION >= (3, 5) else None


def get_positions(mesh):
    out = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    attr = _position_attribute(mesh)
    if attr is not None:
        attr.data.foreach_get("vector", out)
    else:
        mesh.vertices.foreach_get("co", out)
    return out.reshape(-1, 3)


def set_positions(mesh, positions):
    flat = np.ascontiguousarray(positions, dtype=np.float32).ravel()
    attr = _position_attribute(mesh)
    if attr is not None:
        attr.data.foreach_set("vector", flat)
    else:
        mesh.vertices.foreach_set("co", flat)


# From 4.0 the topology arrays are attributes too; the old per-element properties convert
# item by item (measured on 5.0 for 300k faces: loops.vertex_index 266 ms vs 1 ms,
# edges.vertices 245 ms vs 2 ms, polygons.material_index 288 ms vs about 1 ms).
_ATTRIBUTE_TOPOLOGY = VERSION >= (4, 0)


def _int_attribute(mesh, name, domain, create=False):
    attr = mesh.attributes.get(name) if _ATTRIBUTE_TOPOLOGY else None
    if attr is None and create and _ATTRIBUTE_TOPOLOGY:
        attr = mesh.attributes.new(name, 'INT', domain)
    return attr


def get_corner_verts(mesh):
    out = np.empty(len(mesh.loops), dtype=np.int32)
    attr = _int_attribute(mesh, ".corner_vert", 'CORNER')
    (attr.data if attr is not None else mesh.loops).foreach_get(
        "value" if attr is not None else "vertex_index", out)
    return out


def set_corner_verts(mesh, corner_verts):
    flat = np.ascontiguousarray(corner_verts, dtype=np.int32).ravel()
    attr = _int_attribute(mesh, ".corner_vert", 'CORNER')
    if attr is not None:
        attr.data.foreach_set("value", flat)
    else:
        mesh.loops.foreach_set("vertex_index", flat)


def get_material_index(mesh):
    out = np.zeros(len(mesh.polygons), dtype=np.int32)
    if _ATTRIBUTE_TOPOLOGY:
        attr = mesh.attributes.get("material_index")
        if attr is not None:   # absent means all zero
            attr.data.foreach_get("value", out)
    else:
        mesh.polygons.foreach_get("material_index", out)
    return out


def set_material_index(mesh, index):
    flat = np.ascontiguousarray(index, dtype=np.int32)
    if _ATTRIBUTE_TOPOLOGY:
        if not flat.any():
            return
        _int_attribute(mesh, "material_index", 'FACE', create=True).data.foreach_set("value", flat)
    else:
        mesh.polygons.foreach_set("material_index", flat)


def get_edges(mesh):
    out = np.empty(len(mesh.edges) * 2, dtype=np.int32)
    attr = mesh.attributes.get(".edge_verts") if _ATTRIBUTE_TOPOLOGY else None
    if attr is not None:
        attr.data.foreach_get("value", out)
    else:
        mesh.edges.foreach_get("vertices", out)
    return out.reshape(-1, 2)


def get_uvs(mesh, layer):
    out = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    attr = mesh.attributes.get(layer.name) if _ATTRIBUTE_TOPOLOGY else None
    if attr is not None and attr.data_type == 'FLOAT2':
        attr.data.foreach_get("vector", out)
    else:
        layer.data.foreach_get("uv", out)
    return out.reshape(-1, 2)


def set_uvs(mesh, layer, uvs):
    flat = np.ascontiguousarray(uvs, dtype=np.float32).ravel()
    attr = mesh.attributes.get(layer.name) if _ATTRIBUTE_TOPOLOGY else None
    if attr is not None and attr.data_type == 'FLOAT2':
        attr.data.foreach_set("vector", flat)
    else:
        layer.data.foreach_set("uv", flat)


# --- reading split normals ------------------------------------------------------------------

def read_corner_normals(mesh):
    """(C, 3) float32 split normals as Blender shades them (custom, sharp edges, flat faces)."""
    out = np.empty(len(mesh.loops) * 3, dtype=np.float32)
    if HAS_CORNER_NORMALS:
        mesh.corner_normals.foreach_get("vector", out)
    else:
        # Without auto smooth, 3.4 ignores sharp edges and custom normals; calc_normals_split
        # then gives vertex normals on smooth faces and face normals on flat ones, which is
        # exactly what Blender shades.
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", out)
        if not mesh.is_evaluated:
            mesh.free_normals_split()   # leave the user's mesh as it was
    return out.reshape(-1, 3)


# --- writing the result's flags and normals --------------------------------------------------

def set_all_faces_smooth(mesh):
    """Output normals come from the normal patches, so no face may force flat shading."""
    if HAS_SHARP_FACE_ATTRIBUTE:
        attr = mesh.attributes.get("sharp_face")
        if attr is not None:
            mesh.attributes.remove(attr)
    else:
        mesh.polygons.foreach_set("use_smooth", np.ones(len(mesh.polygons), dtype=bool))


def set_sharp_edges(mesh, flags):
    """flags: (E,) bool per mesh edge."""
    if HAS_SHARP_EDGE_ATTRIBUTE:
        attr = mesh.attributes.get("sharp_edge")
        if not flags.any():
            if attr is not None:
                mesh.attributes.remove(attr)
            return
        if attr is None:
            attr = mesh.attributes.new("sharp_edge", 'BOOLEAN', 'EDGE')
        attr.data.foreach_set("value", flags)
    else:
        mesh.edges.foreach_set("use_edge_sharp", flags)


def enable_split_normals(mesh, enable=True):
    """3.4-4.0: custom normals and sharp edges only count with auto smooth on; an angle of
    180 degrees makes the marked sharp edges the only splits."""
    if not HAS_CORNER_NORMALS:
        mesh.use_auto_smooth = enable
        mesh.auto_smooth_angle = np.pi


def write_custom_normals(mesh, normals, domain='CORNER'):
    """normals: (C, 3) float32 unit vectors, one per loop, or with domain='POINT' (4.5+ only)
    one per vertex. Returns the path used."""
    if HAS_FREE_NORMAL_ATTRIBUTE:
        # A float3 attribute named custom_normal is a free custom normal in 4.5+ (on the
        # corner or the point domain): a memcpy through foreach_set instead of ~1 us per
        # corner in normals_split_custom_set.
        attr = mesh.attributes.get("custom_normal")
        if attr is not None and (attr.data_type != 'FLOAT_VECTOR' or attr.domain != domain):
            mesh.attributes.remove(attr)
            attr = None
        if attr is None:
            attr = mesh.attributes.new("custom_normal", 'FLOAT_VECTOR', domain)
        attr.data.foreach_set("vector", np.ascontiguousarray(normals, dtype=np.float32).ravel())
        return "attribute" if domain == 'CORNER' else "point attribute"
    if domain != 'CORNER':
        raise ValueError("point-domain custom normals need Blender 4.5+")
    enable_split_normals(mesh)
    # Blender refuses a flat array here; it wants one 3-vector per loop.
    mesh.normals_split_custom_set(np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 3))
    return "custom_set"


def remove_custom_normals(mesh):
    """4.5+: drops the custom_normal attribute, so that Blender shades from the geometry
    (before 4.5 a result with custom normals is rebuilt instead: write.write_result)."""
    if HAS_FREE_NORMAL_ATTRIBUTE:
        attr = mesh.attributes.get("custom_normal")
        if attr is not None:
            mesh.attributes.remove(attr)


def write_vertex_normals(mesh, normals):
    """normals: (V, 3) float32 unit vectors, one per vertex, for a result whose normals never
    split. 4.5+: the point-domain custom_normal attribute (a memcpy); before,
    normals_split_custom_set_from_vertices, which takes a sixth of the values the per-corner
    call does (a vertex has about six corners in a dense triangle mesh). Returns the path."""
    if HAS_FREE_NORMAL_ATTRIBUTE:
        return write_custom_normals(mesh, normals, 'POINT')
    enable_split_normals(mesh)
    mesh.normals_split_custom_set_from_vertices(
        np.ascontiguousarray(normals, dtype=np.float32).reshape(-1, 3))
    return "custom_set_from_vertices"


def set_loop_starts(mesh, loop_starts, loop_totals):
    mesh.polygons.foreach_set("loop_start", loop_starts)
    if VERSION < (4, 0):
        mesh.polygons.foreach_set("loop_total", loop_totals)
