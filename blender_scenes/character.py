"""A character-like rigged mesh for the stack tests and the playback benchmark (runs inside
Blender; no add-on needed).

    mesh = character_mesh(subdivisions=2)        # box-modelled body, Catmull-Clark smoothed
    obj, arm = rigged_character(subdivisions=2)  # + an armature (spine, arm.L, arm.R) that waves
                                                 #   over frames 1-6, and an Armature modifier
    other = character_object(2, "B", rig=arm)    # another body on the same rig

The body is one connected quad mesh (torso, neck and head, two arms, two legs) smoothed by
Blender's own Subdivision Surface and applied; the soles are shaded flat (their normals split
from the legs'), a belt of edges around the waist is marked sharp, and a cylindrical UV map
("UVMap") is cut along the back. Weights are explicit smooth ramps: each arm's group rises
from 0 to 1 across the shoulder, "spine" takes the rest.
"""
import math
import os

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

FRAMES = (1, 6)
BONES = ("spine", "arm.L", "arm.R")


def _link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _box_body():
    """The base cage: a torso split in two along x (for the legs), legs, arms, neck, head."""
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=(0.7, 0.36, 0.8), verts=bm.verts)
    bmesh.ops.translate(bm, vec=(0.0, 0.0, 1.3), verts=bm.verts)
    # One cut along x: two bottom faces (legs) and two top faces.
    xedges = [e for e in bm.edges if abs(e.verts[0].co.x - e.verts[1].co.x) > 1e-6]
    bmesh.ops.subdivide_edges(bm, edges=xedges, cuts=1, use_grid_fill=True)

    def faces_where(pred):
        bm.faces.ensure_lookup_table()
        return [f for f in bm.faces if pred(f.calc_center_median(), f.normal)]

    def extrude(faces, steps):
        """Extrudes each face on its own, step by step: steps = [(offset, scale)]."""
        for face in faces:
            for offset, scale in steps:
                r = bmesh.ops.extrude_face_region(bm, geom=[face])
                bmesh.ops.delete(bm, geom=[face], context='FACES')
                new_verts = {g for g in r["geom"] if isinstance(g, bmesh.types.BMVert)}
                face = next(g for g in r["geom"] if isinstance(g, bmesh.types.BMFace)
                            and all(v in new_verts for v in g.verts))
                c = face.calc_center_median()
                n = face.normal.copy()
                for v in face.verts:
                    v.co = c + (v.co - c) * scale + n * offset
    legs = faces_where(lambda c, n: n.z < -0.9)
    arms = faces_where(lambda c, n: abs(n.x) > 0.9)
    extrude(legs, [(0.35, 0.85), (0.45, 0.9), (0.15, 1.0)])
    extrude(arms, [(0.2, 0.7), (0.35, 0.9), (0.3, 0.85)])
    top = faces_where(lambda c, n: n.z > 0.9)
    r = bmesh.ops.extrude_face_region(bm, geom=top)
    bmesh.ops.delete(bm, geom=top, context='FACES')
    neck = [g for g in r["geom"] if isinstance(g, bmesh.types.BMVert)]
    for v in neck:
        v.co.z += 0.12
        v.co.x *= 0.45
        v.co.y *= 0.7
    faces = [g for g in r["geom"] if isinstance(g, bmesh.types.BMFace)]
    head_top = [f for f in faces if f.normal.z > 0.9]
    r = bmesh.ops.extrude_face_region(bm, geom=head_top)
    bmesh.ops.delete(bm, geom=head_top, context='FACES')
    for v in [g for g in r["geom"] if isinstance(g, bmesh.types.BMVert)]:
        v.co.z += 0.38
        v.co.x *= 1.6
        v.co.y *= 1.2
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    # bmesh orders new elements by pointer hashes: a canonical order (vertices by position,
    # faces by their vertices) makes every call give the same mesh, vertex for vertex.
    bm.verts.index_update()
    co = np.array([v.co[:] for v in bm.verts])
    order = np.lexsort(np.round(co, 5).T[::-1])
    rank = np.empty(len(order), np.int64)
    rank[order] = np.arange(len(order))
    faces = []
    for f in bm.faces:
        idx = [int(rank[v.index]) for v in f.verts]
        k = idx.index(min(idx))
        faces.append(tuple(idx[k:] + idx[:k]))
    bm.free()
    me = bpy.data.meshes.new("character_cage")
    me.from_pydata([tuple(map(float, p)) for p in co[order]], [], sorted(faces))
    me.update()
    return me


def character_mesh(subdivisions=2, name="character"):
    """The smoothed body as a new mesh (quads), with flat soles, a sharp waist belt and a UV
    map. subdivisions=2: 736 faces; 3: 2,944; 4: 11,776."""
    cage = _box_body()
    tmp = _link(bpy.data.objects.new("character_cage", cage))
    sub = tmp.modifiers.new("Subsurf", 'SUBSURF')
    sub.levels = sub.render_levels = subdivisions
    dg = bpy.context.evaluated_depsgraph_get()
    me = bpy.data.meshes.new_from_object(tmp.evaluated_get(dg))
    me.name = name
    bpy.data.objects.remove(tmp)
    bpy.data.meshes.remove(cage)
    nv, nf = len(me.vertices), len(me.polygons)
    co = np.empty(nv * 3, np.float32)
    me.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    # Smooth everywhere but the soles.
    centers = np.empty(nf * 3, np.float32)
    me.polygons.foreach_get("center", centers)
    centers = centers.reshape(-1, 3)
    normals = np.empty(nf * 3, np.float32)
    me.polygons.foreach_get("normal", normals)
    smooth = ~((normals.reshape(-1, 3)[:, 2] < -0.8) & (centers[:, 2] < co[:, 2].min() + 0.05))
    me.polygons.foreach_set("use_smooth", smooth)
    # A sharp belt around the torso: the edges between faces above and below the waist.
    ne = len(me.edges)
    loop_edge = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("edge_index", loop_edge)
    starts = np.empty(nf, np.int32)
    me.polygons.foreach_get("loop_start", starts)
    face_of_loop = np.repeat(np.arange(nf), np.diff(np.append(starts, len(me.loops))))
    above = centers[:, 2] > 1.1
    torso = np.abs(centers[:, 0]) < 0.3
    count = np.zeros((ne, 2), np.int32)   # per edge: torso faces above, torso faces below
    np.add.at(count, (loop_edge[torso[face_of_loop]],
                      (~above[face_of_loop][torso[face_of_loop]]).astype(np.int32)), 1)
    sharp = (count[:, 0] == 1) & (count[:, 1] == 1)
    me.edges.foreach_set("use_edge_sharp", sharp)
    if hasattr(me, "use_auto_smooth"):   # before 4.1 sharp edges count with auto smooth only
        me.use_auto_smooth = True
        me.auto_smooth_angle = math.pi
    # Cylindrical UVs around the body's axis, cut at the back (each face on one side).
    loops = np.empty(len(me.loops), np.int32)
    me.loops.foreach_get("vertex_index", loops)
    p = co[loops]
    u = (np.arctan2(p[:, 0], -p[:, 1]) / (2 * np.pi) + 0.5)
    cx = centers[face_of_loop]
    back = (cx[:, 1] > 0) & (np.abs(cx[:, 0]) < 0.5)
    u = np.where(back & (p[:, 0] < 0) & (cx[:, 0] >= 0), u + 1.0, u)
    u = np.where(back & (p[:, 0] >= 0) & (cx[:, 0] < 0), u - 1.0, u)
    z = co[:, 2]
    v = (p[:, 2] - z.min()) / (z.max() - z.min())
    uv = me.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", np.stack([u, v], 1).astype(np.float32).ravel())
    me.update()
    return me


def _smoothstep(x, lo, hi):
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def add_weights(obj):
    """Vertex groups spine, arm.L, arm.R with explicit smooth ramps (they sum to 1)."""
    me = obj.data
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    x = co.reshape(-1, 3)[:, 0].astype(np.float64)
    arm_l = _smoothstep(x, 0.22, 0.55)
    arm_r = _smoothstep(-x, 0.22, 0.55)
    spine = 1.0 - arm_l - arm_r
    for name, w in (("spine", spine), ("arm.L", arm_l), ("arm.R", arm_r)):
        vg = obj.vertex_groups.new(name=name)
        for i in np.nonzero(w > 0)[0]:
            vg.add([int(i)], float(w[i]), 'REPLACE')


def armature(name="rig", amplitude=1.0):
    """spine (hips to chest) with arm.L and arm.R at the shoulders; keyframed on FRAMES, its
    angles scaled by amplitude (1: a wave; 0.02: a slight idle motion)."""
    data = bpy.data.armatures.new(name)
    arm = _link(bpy.data.objects.new(name, data))
    prev = bpy.context.view_layer.objects.active
    bpy.context.view_layer.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    spine = data.edit_bones.new("spine")
    spine.head, spine.tail = (0, 0, 0.9), (0, 0, 1.6)
    for side, s in (("L", 1), ("R", -1)):
        b = data.edit_bones.new(f"arm.{side}")
        b.head, b.tail = (0.38 * s, 0, 1.45), (1.2 * s, 0, 1.45)
        b.parent = spine
    bpy.ops.object.mode_set(mode='OBJECT')
    bpy.context.view_layer.objects.active = prev
    f0, f1 = FRAMES
    poses = {  # frame -> (spine x, arm.L y, arm.R y) Euler angles in radians
        f0: (0.0, 0.0, 0.0), f0 + 2: (0.15, 0.6, -0.3), f1: (-0.1, -0.5, 0.7)}
    for b in arm.pose.bones:
        b.rotation_mode = 'XYZ'
    for frame, (sx, al, ar) in poses.items():
        sx, al, ar = amplitude * sx, amplitude * al, amplitude * ar
        arm.pose.bones["spine"].rotation_euler = (sx, 0, 0.1 * sx)
        arm.pose.bones["arm.L"].rotation_euler = (0, al, 0)
        arm.pose.bones["arm.R"].rotation_euler = (0, ar, 0)
        for b in arm.pose.bones:
            b.keyframe_insert("rotation_euler", frame=frame)
    return arm


def character_object(subdivisions=2, name="character", rig=None, location=(0.0, 0.0, 0.0)):
    """The body as a linked object with weights; with a rig, an Armature modifier first."""
    obj = _link(bpy.data.objects.new(name, character_mesh(subdivisions, name)))
    obj.location = location
    add_weights(obj)
    if rig is not None:
        mod = obj.modifiers.new("Armature", 'ARMATURE')
        mod.object = rig
    return obj


def rigged_character(subdivisions=2, name="character", location=(0.0, 0.0, 0.0)):
    """(mesh object, armature object): the body weighted to the rig, Armature modifier first."""
    arm = armature(name + ".rig")
    arm.location = location
    return character_object(subdivisions, name, arm, location), arm


def lattice_around(objects, shape=(4, 4, 4), margin=0.08, jitter=0.12, seed=3,
                   interp='KEY_BSPLINE', name="lat", frames=FRAMES):
    """A lattice object boxing the objects' evaluated geometry (world space) over `frames`
    (first, last) with `margin` on each side, its points jittered by up to `jitter` of their
    spacing (an edited lattice)."""
    sc = bpy.context.scene
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    keep = sc.frame_current
    for f in range(frames[0], frames[1] + 1):
        sc.frame_set(f)
        dg = bpy.context.evaluated_depsgraph_get()
        for o in objects:
            ev = o.evaluated_get(dg)
            co = np.empty(len(ev.data.vertices) * 3, np.float32)
            ev.data.vertices.foreach_get("co", co)
            m = np.array(ev.matrix_world)
            w = co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3]
            lo, hi = np.minimum(lo, w.min(0)), np.maximum(hi, w.max(0))
    sc.frame_set(keep)
    size = (hi - lo) * (1 + 2 * margin)
    lt = bpy.data.lattices.new(name)
    # Linked before it is resized: a lattice with an object spreads its points over the unit
    # box, [-0.5, 0.5]^3, as one added in the viewport (resized without an object, they would
    # be one unit apart, and the lattice (n-1) times the objects' box: no knot plane inside).
    lat = _link(bpy.data.objects.new(name, lt))
    lt.points_u, lt.points_v, lt.points_w = shape
    lt.interpolation_type_u = lt.interpolation_type_v = lt.interpolation_type_w = interp
    lat.location = (lo + hi) / 2
    lat.scale = size
    rng = np.random.default_rng(seed)
    spacing = 1.0 / np.maximum(np.array(shape) - 1, 1)   # jitter: a fraction of the spacing
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-jitter, jitter, 3) * spacing
    return lat


def import_rigged(path):
    """A rigged file (.glb, .gltf, .fbx) through Blender's own importer at its defaults, as a
    user brings one: (its first mesh with an Armature modifier, that armature, the action it
    now plays). The armature plays its Walk action when it has one (else its active action),
    with its NLA tracks removed so that nothing else moves it."""
    if not hasattr(np, "bool"):   # Debian's Blender 3.4.1 glTF importer and numpy >= 1.24
        np.bool = bool
    ext = os.path.splitext(path)[1].lower()
    if ext in (".glb", ".gltf"):
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".fbx":
        bpy.ops.import_scene.fbx(filepath=path)
    else:
        raise ValueError(f"{path}: not a .glb, .gltf or .fbx file")
    skinned = [o for o in bpy.data.objects if o.type == 'MESH'
               and any(m.type == 'ARMATURE' and m.object for m in o.modifiers)]
    if not skinned:
        raise ValueError(f"{path}: no mesh with an Armature modifier")
    obj = skinned[0]
    rig = next(m.object for m in obj.modifiers if m.type == 'ARMATURE')
    ad = rig.animation_data
    act = next((a for a in bpy.data.actions if a.name.lower().startswith("walk")),
               ad.action if ad else None)
    if act is None:
        raise ValueError(f"{path}: the armature has no action to play")
    for track in list(ad.nla_tracks):
        ad.nla_tracks.remove(track)
    ad.action = act
    return obj, rig, act


def rigged_copy(obj, name):
    """A copy of a rigged object (its own mesh, the same modifiers, parent and armature), shown
    and in the same collections."""
    new = obj.copy()
    new.data = obj.data.copy()
    new.name = name
    new.hide_viewport = False
    for coll in obj.users_collection:
        coll.objects.link(new)
    return new
