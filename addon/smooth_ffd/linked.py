"""Smooth FFD objects linked from a library file (File > Link) and library overrides of them.

Linked data belong to their library: the add-on never writes them (the object, its modifier's
inputs and status, the library's hidden result object and mesh, its lattice). Writing them
in memory, as the add-on once did, showed the library's saved result on every frame (the
edited linked mesh is not re-evaluated) with a fresh status, zero positions after a
topology change (3.4) or a crash (5.0). What a linked modifier shows is decided by its
linked node group alone (nodegroup): the library's bake on its baked frames, the library's
saved result on the frames it belongs to (every frame when nothing is animated), the source
mesh elsewhere; never another frame's result. Nothing local can stand in: the linked group
reads the linked result object through the linked modifier's input, and only a write of
linked data (a pointer or the mesh) changes what it reads. So the console says once per
modifier what is shown and what to do: a library override (live results) or a bake in the
library.

A library override (Object > Library Override > Make, ID.override_hierarchy_create) is local
data: its modifier's inputs are overridable properties, recorded in the shot file. Its
Result Object input still points at the library's result (linked, or on 3.4 an override
whose mesh is linked), which the add-on must not write, so the override gets a local result
object of its own (objects.result_object) that the override's input points at; the
status, frame ranges and bake are written to the override like any setting. On 3.4 a float
input written from Python lost its "overridable" flag (the ID property is replaced by a
double), so a library saved by the add-on had Result From/To and Strength not overridable:
compat.set_modifier_input keeps the flag, and overrides get it back here.
"""
import bpy

from . import compat, frames, nodegroup, state

def is_linked(id_data):
    """Data from a library file (not an override: those are local)."""
    return id_data is not None and id_data.library is not None


def is_override(id_data):
    return id_data is not None and getattr(id_data, "override_library", None) is not None


def local_result(ro):
    """Whether ro can be the add-on's result object: local data, not an override, with a
    local mesh (the library's result, linked or overridden, is never written)."""
    return (ro.library is None and not is_override(ro)
            and (ro.data is None or (ro.data.library is None and not is_override(ro.data))))


def library_path(id_data):
    lib = id_data.library
    return lib.filepath if lib is not None else ""


# --- linked modifiers: read, never write -------------------------------------------------

def describe(obj, mod):
    """What a linked modifier shows, and what to do for a live result."""
    try:
        bake_lo, bake_hi = frames.get_frames(mod, "Bake")
        lo, hi = frames.get_frames(mod, "Result")
    except KeyError:   # no node group, or not ours any more
        bake_lo, bake_hi = lo, hi = state.NEVER
    parts = []
    if bake_lo < bake_hi:
        parts.append(f"the library's bake on frames {bake_lo + 0.5:g}-{bake_hi - 0.5:g}")
    if (lo, hi) == state.ALWAYS:
        parts.append(f"the library's saved result on every {'other ' if parts else ''}frame "
                     f"(nothing it depends on is animated)")
    else:
        if lo < hi and not bake_lo <= lo < hi <= bake_hi:
            parts.append(f"the library's saved result on frame {(lo + hi) / 2:g}")
        parts.append("the source mesh on every other frame" if parts else
                     "the source mesh on every frame (the library saved no result)")
    shows = ", ".join(parts)
    return (f"Smooth FFD [{obj.name} / {mod.name}]: {obj.name!r} is linked from "
            f"{library_path(obj)} and linked data cannot be written, so nothing is computed "
            f"for it: it shows {shows}. For a live result make a library override of it "
            f"(Object > Library Override > Make), or bake the frames in the library file "
            f"(Object > Smooth FFD > Bake...)")


def report(obj, mod):
    """Prints describe() once per linked modifier (this session)."""
    key = (obj.name_full, mod.name)
    if key in state.linked_reported:
        return False
    state.linked_reported[key] = text = describe(obj, mod)
    print(text)
    return True


def linked_modifiers(scene):
    """(object, modifier) of every linked Smooth FFD modifier the scene shows: linked
    objects among its objects (a linked collection in the scene) and inside the collections
    its objects instance (File > Link's default: an empty instancing the collection)."""
    out, seen = [], set()
    stack = list(scene.objects)
    while stack:
        ob = stack.pop()
        key = ob.as_pointer()
        if key in seen:
            continue
        seen.add(key)
        if ob.library is not None and ob.type == 'MESH':
            out.extend((ob, m) for m in ob.modifiers if nodegroup.is_smooth_ffd_modifier(m))
        if ob.instance_type == 'COLLECTION' and ob.instance_collection is not None:
            stack.extend(ob.instance_collection.all_objects)
    return out


def report_scene(scene, force=False):
    """Reports the scene's linked Smooth FFD modifiers not reported yet; scans only when the
    file's objects, collections or libraries changed in number (or force: file load)."""
    data = bpy.data
    sig = (scene.name_full, len(data.objects), len(data.collections), len(data.libraries),
           len(scene.objects))
    if not force and sig == state.linked_scanned[0]:
        return 0
    state.linked_scanned[0] = sig
    if not len(data.libraries):
        return 0
    return sum(report(obj, mod) for obj, mod in linked_modifiers(scene))


def check_writable(obj, mod=None, action="change"):
    """Raises RuntimeError for what the add-on must not do: anything on a linked object, and
    applying or removing a modifier an override has from its library (Blender refuses both
    too)."""
    if is_linked(obj):
        raise RuntimeError(
            f"Smooth FFD cannot {action} {obj.name!r}: it is linked from {library_path(obj)} "
            f"and linked data cannot be written; make a library override of it (Object > "
            f"Library Override > Make)")
    if mod is not None and action in ("apply", "remove") and is_override(obj) \
            and getattr(mod, "is_override_data", False):
        raise RuntimeError(
            f"Smooth FFD cannot {action} {mod.name!r} of {obj.name!r}: the modifier comes "
            f"from the library of this override (Blender cannot {action} it either); "
            f"{action} it in the library file")


# --- overrides ---------------------------------------------------------------------------

def prepare_override(obj, mod):
    """Makes every input of an override's Smooth FFD modifier overridable, so what the add-on
    writes (result object, frame ranges, status, bake) and what the user sets are recorded
    in the shot file; once per modifier and session. A library saved by an older add-on on
    3.4 had float inputs without the flag (compat.set_modifier_input)."""
    if not is_override(obj) or compat.HAS_MODIFIER_PROPERTIES:
        return
    key = (obj.name_full, mod.name)
    if key in state.overridable_done:
        return
    state.overridable_done.add(key)
    for name, *_ in nodegroup.INPUTS:
        try:
            compat.ensure_overridable(mod, name)
        except (KeyError, TypeError, AttributeError, RuntimeError):   # an older layout's input
            pass
