"""Bakes a Smooth FFD modifier, frame by frame, into the .blend itself, so that a machine
without the add-on (a render farm node, `--factory-startup`, Python disabled) renders every
baked frame right, with nothing but Blender's own nodes.

Each baked frame's result (the render level, exact normals, UV maps, vertex groups,
attributes, materials: the live result mesh as the add-on wrote it) is copied into a mesh of
its own, held by an unlinked "frame" object; frames whose inputs are equal share one. A
hidden host object's Geometry Nodes modifier picks the frame's mesh with Object Info nodes
behind a tree of Switch nodes on the Scene Time frame (log2 of the frame count deep), and the
Smooth FFD group shows the host's geometry on the baked frames (nodegroup: Bake Object, Bake
From, Bake To). The meshes are passed through untouched, so custom normals survive on every
Blender (3.4's Realize Instances, for one, would drop them), and a frame's topology may
differ from the next one's (moving the lattice object re-clips the mesh into other patches,
so the triangle count changes from frame to frame).

Why not Alembic or USD with a Mesh Sequence Cache modifier: Debian's Blender 3.4.1 is built
without either, so a file baked that way would not render there; the in-file bake needs no
external file either (one .blend to send to a farm) and is bitwise the live result, where
Alembic drops vertex groups and attributes and rounds custom normals. Its cost is the file's
size: every distinct frame is a full mesh (docs/addon.md).
"""
import bpy

from . import compat, frames, nodegroup, objects, pipeline, state


def bake(obj, mod, frame_start, frame_end, scene=None):
    """Bakes frames frame_start..frame_end (inclusive) at the render level; returns the
    host object. Raises RuntimeError (nothing baked, any previous bake cleared) when a frame
    has no valid result. The caller then updates every modifier for the frame shown
    (handlers.update_all)."""
    frame_start, frame_end = int(frame_start), int(frame_end)
    if frame_end < frame_start:
        raise ValueError(f"frame_end {frame_end} is before frame_start {frame_start}")
    scene = scene if scene is not None else bpy.context.scene
    if not frames.has_frames(mod):
        nodegroup.migrate(mod)
    clear(obj, mod)
    ro = objects.result_object(obj, mod)
    st = state.of_result(ro, create=True)
    level = int(compat.get_modifier_input(mod, "Render Level"))
    old_frame = (scene.frame_current, scene.frame_subframe)
    segments = []     # [first, last, frame object]
    by_key = {}
    made = []
    try:
        with state.muted():
            for f in range(frame_start, frame_end + 1):
                scene.frame_set(f)
                depsgraph = bpy.context.evaluated_depsgraph_get()
                pipeline.update_modifier(obj, mod, state.Pass(depsgraph, scene=scene, render=True))
                status = compat.get_modifier_input(mod, "Status")
                if not status.startswith("OK") or st.last_key is None:
                    raise RuntimeError(f"Smooth FFD bake: frame {f}: {status}")
                fo = by_key.get(st.last_key)
                if fo is None:
                    fo = by_key[st.last_key] = _frame_object(obj, mod, ro, f)
                    made.append(fo)
                if segments and segments[-1][2] is fo and segments[-1][1] == f - 1:
                    segments[-1][1] = f
                else:
                    segments.append([f, f, fo])
            host = _host(obj, mod, segments, level, (frame_start, frame_end))
            # Set before the next evaluation, which rebuilds the relations that creating the
            # objects tagged: an ID input set afterwards gets no relation (Object Info would
            # read the host unevaluated) until something else rebuilds them.
            compat.set_modifier_input(mod, "Bake Object", host)
            frames.set_frames(mod, "Bake", (frame_start - 0.5, frame_end + 0.5))
    except BaseException:
        for fo in made:
            _remove_object(fo)
        raise
    finally:
        with state.muted():
            scene.frame_set(old_frame[0], subframe=old_frame[1])
    obj.update_tag()
    return host


def clear(obj, mod):
    """Removes the bake (its host, group, frame objects and meshes); the modifier is live
    again on those frames. Returns whether there was one."""
    if not frames.has_frames(mod):
        return False
    host = compat.get_modifier_input(mod, "Bake Object")
    had = host is not None or frames.get_frames(mod, "Bake") != state.NEVER
    compat.set_modifier_input(mod, "Bake Object", None)
    frames.set_frames(mod, "Bake", state.NEVER)
    if host is not None and host.get(state.BAKE_KEY) == "host" and host.users == 0:
        remove_host(host)
    if had:
        st = objects.state_of(obj, mod)
        if st is not None:
            st.last_key = None   # the handlers write this frame's live result again
        obj.update_tag()
    return had


def remove_host(host):
    if host.library is not None:   # a library's bake (a linked or overridden modifier's)
        return
    groups = [m.node_group for m in host.modifiers if m.type == 'NODES' and m.node_group]
    _remove_object(host)
    for group in groups:
        if group.get(state.BAKE_KEY) != "frames" or group.users:
            continue
        frame_objects = {n.inputs["Object"].default_value for n in group.nodes
                  if n.bl_idname == 'GeometryNodeObjectInfo'}
        bpy.data.node_groups.remove(group)
        for fo in frame_objects:
            if fo is not None and fo.get(state.BAKE_KEY) == "frame" and fo.users == 0:
                _remove_object(fo)


def _remove_object(ob):
    mesh = ob.data
    bpy.data.objects.remove(ob)
    if mesh is not None and mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def _frame_object(obj, mod, ro, frame):
    """An unlinked object holding a copy of the result mesh, with its vertex group names
    (the weights live in the mesh, the names on the object)."""
    name = f"{obj.name}.{mod.name}.bake.{frame:04d}"
    mesh = ro.data.copy()
    mesh.name = name
    for key in list(mesh.keys()):
        del mesh[key]
    # A copy shares the derived-data caches (corner normals) with the result mesh, and on
    # 4.2 the result's next write fills the shared cache with the next frame's normals
    # (seen as frames 1-2 of check_stack.py's bake with frame 3's normals, in that session
    # only): update() gives the copy caches of its own.
    mesh.update()
    fo = bpy.data.objects.new(name, mesh)
    fo[state.BAKE_KEY] = "frame"
    for vg in ro.vertex_groups:
        fo.vertex_groups.new(name=vg.name)
    return fo


def _host(obj, mod, segments, level, frame_range):
    name = f"{obj.name}.{mod.name}.bake"
    host = bpy.data.objects.new(name, bpy.data.meshes.new(name))
    host[state.BAKE_KEY] = "host"
    host[state.LEVEL_KEY] = level
    host[state.RANGE_KEY] = list(frame_range)
    group = bpy.data.node_groups.new(f"Smooth FFD bake: {obj.name} / {mod.name}",
                                     'GeometryNodeTree')
    group[state.BAKE_KEY] = "frames"
    compat.new_group_socket(group, 'INPUT', 'NodeSocketGeometry', "Geometry")
    compat.new_group_socket(group, 'OUTPUT', 'NodeSocketGeometry', "Geometry")
    gin = group.nodes.new('NodeGroupInput')
    gout = group.nodes.new('NodeGroupOutput')
    time = group.nodes.new('GeometryNodeInputSceneTime')
    gin.location, time.location = (-600, 200), (-600, 0)
    out = _tree(group, time.outputs["Frame"], segments, 0)
    gout.location = (400, 0)
    group.links.new(out, gout.inputs[0])
    hm = host.modifiers.new("Smooth FFD bake", 'NODES')
    hm.node_group = group
    return host


def _tree(group, frame, segments, depth):
    """Geometry socket giving each segment's mesh on its frames: a leaf is an Object Info
    node; a branch switches at the first frame of its upper half (frame >= first - 1/2, so
    a subframe goes to the nearest baked frame)."""
    if len(segments) == 1:
        info = group.nodes.new('GeometryNodeObjectInfo')
        info.transform_space = 'ORIGINAL'
        info.inputs["Object"].default_value = segments[0][2]
        info.location = (-300 - 40 * depth, -150 * len(group.nodes) % 3000)
        return info.outputs["Geometry"]
    mid = len(segments) // 2
    low = _tree(group, frame, segments[:mid], depth + 1)
    high = _tree(group, frame, segments[mid:], depth + 1)
    cond = nodegroup._compare(group, 'GREATER_EQUAL', frame, segments[mid][0] - 0.5,
                              (-100 - 40 * depth, 0))
    switch = nodegroup._switch(group, (100 - 40 * depth, 0))
    sock_cond, false_in, true_in = nodegroup._switch_sockets(switch)
    group.links.new(cond, sock_cond)
    group.links.new(low, false_in)
    group.links.new(high, true_in)
    return nodegroup._switch_out(switch)
