"""Unit tests of addon/smooth_ffd/compat.py's node-socket paths without Blender: compat.py is
loaded with a fake `bpy` whose app.version picks the branch, and driven with small fakes that
behave like each API generation (docs/addon.md, "Blender versions"):

* 3.4-3.6: group sockets in NodeTree.inputs/outputs (identifiers "Input_N"), modifier inputs
  are ID properties: mod["Input_N"];
* 4.0-5.1: NodeTree.interface.items_tree (sockets and panels, identifiers "Socket_N"), still
  ID properties: mod["Socket_N"];
* 5.2+: same interface, inputs at mod.properties.inputs.<identifier>.value (no ID property).

Identifiers are deliberately not numbered in panel order, so a hard-coded index would fail.
"""
import importlib.util
import os
import sys
import types

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def load_compat(version):
    fake = types.ModuleType("bpy")
    fake.app = types.SimpleNamespace(version=version)
    saved = sys.modules.get("bpy")
    sys.modules["bpy"] = fake
    # compat imports the add-on's state module (`from . import state`): both are loaded as
    # modules of a package of their own, one per version.
    package = f"smooth_ffd_compat_{'_'.join(map(str, version))}"
    sys.modules[package] = types.ModuleType(package)
    sys.modules[package].__path__ = []
    try:
        for name in ("state", "compat"):
            spec = importlib.util.spec_from_file_location(
                f"{package}.{name}", os.path.join(ROOT, "addon", "smooth_ffd", f"{name}.py"))
            mod = importlib.util.module_from_spec(spec)
            sys.modules[spec.name] = mod
            spec.loader.exec_module(mod)
            setattr(sys.modules[package], name, mod)
        return mod
    finally:
        if saved is None:
            sys.modules.pop("bpy", None)
        else:
            sys.modules["bpy"] = saved


# --- fakes --------------------------------------------------------------------------------------

class Socket34:
    """3.x NodeSocketInterface: name, identifier."""

    def __init__(self, name, identifier):
        self.name, self.identifier = name, identifier


class Sockets34(list):
    """NodeTree.inputs / outputs (3.x): new(type, name) assigns the next Input_N / Output_N."""

    def __init__(self, prefix, counter):
        super().__init__()
        self.prefix, self.counter = prefix, counter

    def new(self, socket_type, name):
        self.counter[0] += 1
        s = Socket34(name, f"{self.prefix}_{self.counter[0]}")
        s.socket_type = socket_type
        self.append(s)
        return s


class Group34:
    def __init__(self, name="Smooth FFD"):
        self.name = name
        counter = [0]
        self.inputs = Sockets34("Input", counter)
        self.outputs = Sockets34("Output", counter)
    # No `interface`: 4.0 added it.

    def as_pointer(self):   # bpy_struct.as_pointer: the address, which keys compat's caches
        return id(self)


class Item40:
    """4.0+ NodeTreeInterfaceSocket / NodeTreeInterfacePanel."""

    def __init__(self, item_type, name, identifier="", in_out=None, socket_type=None):
        self.item_type, self.name, self.identifier = item_type, name, identifier
        self.in_out, self.socket_type = in_out, socket_type
        if item_type == 'SOCKET':
            self.hide_in_modifier = False   # 4.2+


class Interface40:
    def __init__(self):
        self.items_tree = []
        self._n = 0

    def new_socket(self, name, in_out='INPUT', socket_type='NodeSocketFloat'):
        self._n += 1
        item = Item40('SOCKET', name, f"Socket_{self._n}", in_out, socket_type)
        self.items_tree.append(item)
        return item

    def new_panel(self, name):
        item = Item40('PANEL', name)
        self.items_tree.append(item)
        return item


class Group40:
    def __init__(self, name="Smooth FFD"):
        self.name = name
        self.interface = Interface40()
    # No `inputs` / `outputs`: removed in 4.0.

    def as_pointer(self):
        return id(self)


class IDPropModifier:
    """3.4-5.1 NodesModifier: inputs are ID properties keyed by the socket identifier."""

    def __init__(self, group, name="Smooth FFD"):
        self.name, self.node_group = name, group
        self.idprops = {}

    def __getitem__(self, key):
        return self.idprops[key]

    def __setitem__(self, key, value):
        self.idprops[key] = value
    # No `properties`: 5.2 added it.


class InputSlot52:
    def __init__(self):
        self.value = None


class Inputs52:
    """mod.properties.inputs: one attribute per group input identifier."""

    def __init__(self, identifiers):
        for ident in identifiers:
            setattr(self, ident, InputSlot52())


class Modifier52:
    """5.2 NodesModifier: inputs at mod.properties.inputs.<identifier>.value; the ID-property
    path is gone (any use of it fails the test)."""

    def __init__(self, group, name="Smooth FFD"):
        self.name, self.node_group = name, group
        idents = [i.identifier for i in group.interface.items_tree
                  if i.item_type == 'SOCKET' and i.in_out == 'INPUT']
        self.properties = types.SimpleNamespace(inputs=Inputs52(idents))

    def __getitem__(self, key):
        raise AssertionError(f"5.2 has no ID property for input {key!r}")

    def __setitem__(self, key, value):
        raise AssertionError(f"5.2 has no ID property for input {key!r}")


# --- groups as the add-on builds them (through compat itself) -------------------------------

NAMES = ("Lattice", "Viewport Level", "Render Level", "Status")


def build_group(compat, group):
    compat.new_group_socket(group, 'INPUT', 'NodeSocketGeometry', "Geometry")
    # An output named like an input: must never be resolved as the input.
    compat.new_group_socket(group, 'OUTPUT', 'NodeSocketGeometry', "Status")
    for name in NAMES:
        compat.new_group_socket(group, 'INPUT', 'NodeSocketInt', name)
    return group


def idents(compat, group):
    return {n: compat.input_identifier(group, n) for n in NAMES}


# --- tests --------------------------------------------------------------------------------------

def test_flags_per_version():
    c34, c40, c51, c52 = (load_compat(v) for v in ((3, 4, 1), (4, 0, 2), (5, 1, 0), (5, 2, 0)))
    assert (c34.HAS_TREE_INTERFACE, c34.HAS_MODIFIER_PROPERTIES) == (False, False)
    assert (c40.HAS_TREE_INTERFACE, c40.HAS_MODIFIER_PROPERTIES) == (True, False)
    assert (c51.HAS_TREE_INTERFACE, c51.HAS_MODIFIER_PROPERTIES) == (True, False)
    assert (c52.HAS_TREE_INTERFACE, c52.HAS_MODIFIER_PROPERTIES) == (True, True)


def test_blender_34_input_n_id_properties():
    compat = load_compat((3, 4, 1))
    group = build_group(compat, Group34())
    ids = idents(compat, group)
    # Geometry took Input_1, the output Output_2: identifiers follow creation, not panel order.
    assert ids == {"Lattice": "Input_3", "Viewport Level": "Input_4", "Render Level": "Input_5",
                   "Status": "Input_6"}
    assert [s.name for s in compat.group_sockets(group, 'OUTPUT')] == ["Status"]
    mod = IDPropModifier(group)
    compat.set_modifier_input(mod, "Render Level", 7)
    compat.set_modifier_input(mod, "Viewport Level", 2)
    assert mod.idprops == {"Input_5": 7, "Input_4": 2}
    assert compat.get_modifier_input(mod, "Render Level") == 7
    mod.idprops["Input_6"] = "OK cpu"      # what Blender would hold
    assert compat.get_modifier_input(mod, "Status") == "OK cpu"
    with pytest.raises(KeyError):
        compat.get_modifier_input(mod, "Strength")
    sock = group.inputs[0]
    compat.hide_in_modifier(sock)          # 3.4 sockets cannot hide: a no-op, no attribute
    assert not hasattr(sock, "hide_in_modifier")


def test_blender_40_socket_n_id_properties():
    compat = load_compat((4, 0, 2))
    group = Group40()
    group.interface.new_panel("Settings")      # panels share items_tree; never a socket
    build_group(compat, group)
    ids = idents(compat, group)
    assert ids == {"Lattice": "Socket_3", "Viewport Level": "Socket_4",
                   "Render Level": "Socket_5", "Status": "Socket_6"}
    assert [s.identifier for s in compat.group_sockets(group, 'OUTPUT')] == ["Socket_2"]
    mod = IDPropModifier(group)
    compat.set_modifier_input(mod, "Status", "OK cuda")
    compat.set_modifier_input(mod, "Viewport Level", 3)
    assert mod.idprops == {"Socket_6": "OK cuda", "Socket_4": 3}
    assert compat.get_modifier_input(mod, "Status") == "OK cuda"
    item = group.interface.items_tree[-1]
    compat.hide_in_modifier(item)
    assert item.hide_in_modifier is True


def test_blender_51_still_id_properties():
    compat = load_compat((5, 1, 0))
    group = build_group(compat, Group40())
    mod = IDPropModifier(group)
    compat.set_modifier_input(mod, "Lattice", "lat")
    assert mod.idprops == {"Socket_3": "lat"}


def test_blender_52_modifier_properties():
    compat = load_compat((5, 2, 0))
    group = build_group(compat, Group40())
    mod = Modifier52(group)                    # its ID-property path raises
    compat.set_modifier_input(mod, "Render Level", 12)
    compat.set_modifier_input(mod, "Status", "OK cpu")
    inputs = mod.properties.inputs
    assert inputs.Socket_5.value == 12 and inputs.Socket_6.value == "OK cpu"
    assert inputs.Socket_3.value is None and inputs.Socket_4.value is None
    assert compat.get_modifier_input(mod, "Render Level") == 12
    inputs.Socket_4.value = 5                  # set by the user in the panel
    assert compat.get_modifier_input(mod, "Viewport Level") == 5
    mod.properties = None                      # NodesModifierProperties | None (no group)
    with pytest.raises(KeyError):
        compat.get_modifier_input(mod, "Render Level")
    mod.node_group = None
    with pytest.raises(KeyError):
        compat.set_modifier_input(mod, "Render Level", 1)


class MenuModifier(IDPropModifier):
    """4.1-5.1 with a menu input: the ID property holds the item's number, its UI data the items
    as (identifier, name, description, icon, number), numbers not in item order."""

    def __init__(self, group, ident, items):
        super().__init__(group)
        self.menu_ident, self.items = ident, items

    def id_properties_ui(self, key):
        assert key == self.menu_ident
        items = [(n, n, "", 0, v) for n, v in self.items]
        return types.SimpleNamespace(as_dict=lambda: {"default": 0, "items": items})


def test_menu_input_by_item_name():
    compat = load_compat((4, 2, 0))
    assert compat.HAS_MENU_SOCKET and not load_compat((4, 0, 2)).HAS_MENU_SOCKET
    group = build_group(compat, Group40())
    compat.new_group_socket(group, 'INPUT', 'NodeSocketMenu', "Backend")
    ident = compat.input_identifier(group, "Backend")
    mod = MenuModifier(group, ident, [("Auto", 4), ("CPU", 2), ("CUDA", 7)])
    compat.set_modifier_input(mod, "Backend", "cpu")      # any case
    assert mod.idprops[ident] == 2
    assert compat.get_modifier_input(mod, "Backend") == "CPU"
    with pytest.raises(ValueError):
        compat.set_modifier_input(mod, "Backend", "gpu")
    mod.idprops[ident] = 99                                 # no item: the raw value
    assert compat.get_modifier_input(mod, "Backend") == 99
    compat.set_modifier_input(mod, "Viewport Level", 3)     # other inputs: as before
    assert mod.idprops[compat.input_identifier(group, "Viewport Level")] == 3
    # A text Backend (a file from 3.4-4.0) still reads as its text.
    old = build_group(compat, Group40())
    compat.new_group_socket(old, 'INPUT', 'NodeSocketString', "Backend")
    mod2 = IDPropModifier(old)
    compat.set_modifier_input(mod2, "Backend", "cuda")
    assert compat.get_modifier_input(mod2, "Backend") == "cuda"
