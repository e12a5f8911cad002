"""A modifier's frame ranges as its node group holds them (nodegroup): the "Result" range (the
frames its result belongs to) and the "Bake" range (the frames its bake shows), and the frame
a depsgraph evaluates, which the group's Scene Time node compares with them."""
import bpy

from . import compat, nodegroup, state


def has_frames(mod):
    """Whether the modifier's group has the frame ranges (a group of an older layout, a file
    not yet migrated (nodegroup.migrate), has a validity flag for the result and no bake)."""
    return nodegroup.layout(mod.node_group) in nodegroup.FRAMES_LAYOUTS


def get_frames(mod, which):
    """(from, to) of the "Result" or "Bake" frame range."""
    if not has_frames(mod):
        if which == "Result" and compat.get_modifier_input(mod, "Show Result"):
            return state.ALWAYS
        return state.NEVER
    return (float(compat.get_modifier_input(mod, f"{which} From")),
            float(compat.get_modifier_input(mod, f"{which} To")))


def set_frames(mod, which, frames):
    """Writes a frame range when it differs; returns whether it did."""
    frames = tuple(float(f) for f in frames)
    if get_frames(mod, which) == frames:
        return False
    if not has_frames(mod):
        if which != "Result":
            raise KeyError(f"the group of {mod.name!r} is of an older layout, without a bake")
        compat.set_modifier_input(mod, "Show Result", frames != state.NEVER)
        return True
    compat.set_modifier_input(mod, f"{which} From", frames[0])
    compat.set_modifier_input(mod, f"{which} To", frames[1])
    return True


def in_bake(mod, frame):
    """Whether the modifier's bake covers this frame (the group shows the bake there)."""
    return state.covers(get_frames(mod, "Bake"), frame)


def scene_frame(scene=None, depsgraph=None):
    """The frame (with subframe and time remapping) a depsgraph evaluates: what the group's
    Scene Time node compares with the frame ranges."""
    if scene is None:
        scene = depsgraph.scene if depsgraph is not None else bpy.context.scene
    return float(scene.frame_current_final)
