"""Regenerate the real-mesh corpus in this folder with Blender (3.4 or later) and its own OBJ
exporter, as a user would export them:

    blender -b --factory-startup --python tests/data/real/make_corpus.py

Every asset is made by Blender's operators (primitives, Suzanne, Spin, Subdivision Surface)
or built here with bmesh from a few numbers; README.md says what each one is and under which
licence. Deterministic: the jitter uses a fixed seed.
"""
import math
import os
import random
import sys

import bmesh
import bpy
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
LEGACY = bpy.app.version < (4, 1, 0)  # use_auto_smooth exists up to 4.0


def clear():
    bpy.ops.object.select_all(action="SELECT")
    bpy.ops.object.delete()
    for m in list(bpy.data.meshes):
        bpy.data.meshes.remove(m)


def auto_smooth(obj, degrees):
    """Shade smooth with split normals at edges sharper than `degrees` (Blender's 'Auto
    Smooth'); flat faces keep their face normal."""
    if LEGACY:
        obj.data.use_auto_smooth = True
        obj.data.auto_smooth_angle = math.radians(degrees)
    else:  # 4.1+: sharp edges from the angle, as the "Smooth by Angle" operator does
        obj.data.set_sharp_from_angle(angle=math.radians(degrees))


def shade(obj, smooth):
    for p in obj.data.polygons:
        p.use_smooth = smooth


def export(obj, name, uv=True):
    bpy.ops.object.select_all(action="DESELECT")
    obj.select_set(True)
    bpy.context.view_layer.objects.active = obj
    path = os.path.join(HERE, name)
    kw = dict(filepath=path, export_selected_objects=True, export_normals=True, export_uv=uv,
              export_materials=False, apply_modifiers=True, forward_axis="Y", up_axis="Z")
    bpy.ops.wm.obj_export(**kw)
    print("wrote", path, len(obj.data.polygons), "faces")


def apply_modifiers(obj):
    bpy.context.view_layer.objects.active = obj
    for m in list(obj.modifiers):
        bpy.ops.object.modifier_apply(modifier=m.name)


def primitives():
    clear()
    bpy.ops.mesh.primitive_cube_add(size=2)
    cube = bpy.context.object
    shade(cube, False)
    export(cube, "cube.obj")

    clear()
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1)
    s = bpy.context.object
    shade(s, True)
    export(s, "uv_sphere.obj")

    clear()
    bpy.ops.mesh.primitive_cylinder_add(vertices=32, radius=1, depth=2, end_fill_type="NGON")
    c = bpy.context.object
    shade(c, True)
    auto_smooth(c, 30)
    export(c, "cylinder.obj")

    clear()
    bpy.ops.mesh.primitive_torus_add(major_segments=48, minor_segments=12, major_radius=1,
                                     minor_radius=0.25)
    t = bpy.context.object
    shade(t, True)
    export(t, "torus.obj")


def suzanne():
    clear()
    bpy.ops.mesh.primitive_monkey_add(size=2)
    m = bpy.context.object
    shade(m, True)
    auto_smooth(m, 30)
    export(m, "suzanne.obj")

    # Smooth everywhere, one subdivision applied: about 3.9k triangles, every normal averaged.
    clear()
    bpy.ops.mesh.primitive_monkey_add(size=2)
    m = bpy.context.object
    mod = m.modifiers.new("sub", "SUBSURF")
    mod.levels = 1
    apply_modifiers(m)
    shade(m, True)
    export(m, "suzanne_subsurf.obj")


def lathe():
    """A goblet: profile spun 24 times about z (Spin), a flat foot, a thin cup wall with a
    flat lip; auto smooth 30 degrees makes the foot's and the lip's rims sharp."""
    clear()
    prof = [(0.0, 0.0), (0.55, 0.0), (0.55, 0.06), (0.18, 0.14), (0.09, 0.3), (0.08, 0.7),
            (0.14, 0.85), (0.4, 1.0), (0.55, 1.2), (0.6, 1.45), (0.6, 1.6), (0.56, 1.6),
            (0.56, 1.45), (0.51, 1.22), (0.37, 1.05), (0.0, 0.98)]
    bm = bmesh.new()
    verts = [bm.verts.new((r, 0.0, z)) for r, z in prof]
    for a, b in zip(verts, verts[1:]):
        bm.edges.new((a, b))
    bmesh.ops.spin(bm, geom=bm.verts[:] + bm.edges[:], cent=(0, 0, 0), axis=(0, 0, 1),
                   angle=2 * math.pi, steps=24, use_duplicate=False)
    bmesh.ops.remove_doubles(bm, verts=bm.verts[:], dist=1e-5)
    me = bpy.data.meshes.new("goblet")
    bm.to_mesh(me)
    bm.free()
    obj = bpy.data.objects.new("goblet", me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    # Consistent outward winding.
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.normals_make_consistent(inside=False)
    bpy.ops.object.mode_set(mode="OBJECT")
    shade(obj, True)
    auto_smooth(obj, 30)
    export(obj, "goblet.obj", uv=False)


def character():
    """A low-poly figure: a flat-shaded torso, legs and upper arms with jittered (non-planar)
    quads, smooth-shaded forearms joined to them (normals split where flat faces meet smooth
    ones, smooth across the forearms' 90-degree turns), and a smooth UV-sphere head of its own.
    """
    clear()
    rnd = random.Random(19)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=(0.8, 0.45, 1.0), verts=bm.verts)
    bmesh.ops.translate(bm, vec=(0, 0, 1.4), verts=bm.verts)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True)

    def face_near(direction, where):
        best, bestd = None, -1e9
        for f in bm.faces:
            c = f.calc_center_median()
            n = f.normal
            if n.dot(direction) < 0.9:
                continue
            d = -(c - Vector(where)).length
            if d > bestd:
                best, bestd = f, d
        return best

    bm.normal_update()
    # Legs: extrude the two bottom quads down twice, the shins narrower.
    for x in (-0.2, 0.2):
        f = face_near(Vector((0, 0, -1)), (x, 0, 0.9))
        r = bmesh.ops.extrude_face_region(bm, geom=[f])
        bmesh.ops.delete(bm, geom=[f], context="FACES")
        nv = [e for e in r["geom"] if isinstance(e, bmesh.types.BMVert)]
        bmesh.ops.translate(bm, vec=(0, 0, -0.45), verts=nv)
        nf = [e for e in r["geom"] if isinstance(e, bmesh.types.BMFace)][0]
        r = bmesh.ops.extrude_face_region(bm, geom=[nf])
        bmesh.ops.delete(bm, geom=[nf], context="FACES")
        nv = [e for e in r["geom"] if isinstance(e, bmesh.types.BMVert)]
        c = sum((v.co for v in nv), Vector()) / len(nv)
        for v in nv:
            v.co = c + (v.co - c) * 0.8 + Vector((0, 0.05, -0.45))
    bm.normal_update()
    # Arms: extrude the upper side quads outwards, twice.
    for sx in (-1, 1):
        f = face_near(Vector((sx, 0, 0)), (sx * 0.4, 0, 1.65))
        r = bmesh.ops.extrude_face_region(bm, geom=[f])
        bmesh.ops.delete(bm, geom=[f], context="FACES")
        nv = [e for e in r["geom"] if isinstance(e, bmesh.types.BMVert)]
        bmesh.ops.translate(bm, vec=(sx * 0.35, 0, -0.05), verts=nv)
        nf = [e for e in r["geom"] if isinstance(e, bmesh.types.BMFace)][0]
        r = bmesh.ops.extrude_face_region(bm, geom=[nf])
        bmesh.ops.delete(bm, geom=[nf], context="FACES")
        nv = [e for e in r["geom"] if isinstance(e, bmesh.types.BMVert)]
        c = sum((v.co for v in nv), Vector()) / len(nv)
        for v in nv:
            v.co = c + (v.co - c) * 0.75 + Vector((sx * 0.35, 0, -0.15))
    bm.normal_update()
    # Neck: the top quads extruded into a narrow stub; head: a UV sphere above it (its own
    # closed component), smooth shaded below.
    top = [f for f in bm.faces if f.normal.z > 0.9 and f.calc_center_median().z > 1.85]
    r = bmesh.ops.extrude_face_region(bm, geom=top)
    bmesh.ops.delete(bm, geom=top, context="FACES")
    nv = [e for e in r["geom"] if isinstance(e, bmesh.types.BMVert)]
    c = sum((v.co for v in nv), Vector()) / len(nv)
    for v in nv:
        v.co = c + (v.co - c) * 0.45 + Vector((0, 0, 0.12))
    neck_z = max(v.co.z for v in nv)
    head = bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=10, radius=0.34)
    hv = set(head["verts"])
    bmesh.ops.translate(bm, vec=(0, 0, neck_z + 0.36), verts=list(hv))
    bm.normal_update()
    # Jitter every vertex below the head a little: the flat quads become non-planar.
    for v in bm.verts:
        if v not in hv:
            v.co += Vector((rnd.uniform(-1, 1), rnd.uniform(-1, 1), rnd.uniform(-1, 1))) * 0.025
    bm.normal_update()
    me = bpy.data.meshes.new("figure")
    bm.to_mesh(me)
    bm.free()
    obj = bpy.data.objects.new("figure", me)
    bpy.context.collection.objects.link(obj)
    bpy.context.view_layer.objects.active = obj
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.remove_doubles(threshold=1e-6)
    bpy.ops.mesh.normals_make_consistent(inside=False)
    bpy.ops.object.mode_set(mode="OBJECT")
    for p in me.polygons:
        # Smooth: the head (above the shoulders) and the hands (the outermost arm segment).
        cz = p.center.z
        p.use_smooth = cz > neck_z or abs(p.center.x) > 0.8
    auto_smooth(obj, 180)  # split only where flat faces meet smooth ones
    export(obj, "figure.obj", uv=False)


def rock():
    """An OBJ with its own normals, as another tool writes them: an icosphere (3 subdivisions,
    1280 triangles) displaced by a sum of waves into a lumpy rock, with angle-weighted vertex
    normals (not Blender's rule) written with 6 digits. Plain Python, no Blender operator."""
    t = (1 + 5 ** 0.5) / 2
    V = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    F = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    V = [Vector(v).normalized() for v in V]
    for _ in range(3):
        cache, out = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                V.append((V[a] + V[b]).normalized())
                cache[key] = len(V) - 1
            return cache[key]

        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        F = out
    waves = [((0.9, 0.3, -0.2), 3.1, 0.12), ((-0.2, 0.8, 0.5), 5.3, 0.07), ((0.4, -0.5, 0.8), 8.9, 0.05),
             ((0.7, 0.7, 0.1), 13.7, 0.025)]
    P = []
    for v in V:
        r = 1.0 + sum(a * math.sin(f * v.dot(Vector(d).normalized()) + i) for i, (d, f, a) in enumerate(waves))
        P.append(v * r * Vector((1.0, 0.8, 0.65)))
    N = [Vector((0, 0, 0)) for _ in P]
    for f in F:
        for k in range(3):
            a, b, c = P[f[k]], P[f[(k + 1) % 3]], P[f[(k + 2) % 3]]
            n = (b - a).cross(c - a)
            if n.length > 0:
                N[f[k]] += n.normalized() * (b - a).angle(c - a)
    path = os.path.join(HERE, "rock.obj")
    with open(path, "w") as fh:
        fh.write("# lumpy rock, angle-weighted vertex normals (smoothffd tests/data/real/make_corpus.py)\n")
        for p in P:
            fh.write("v %.6f %.6f %.6f\n" % tuple(p))
        for n in N:
            fh.write("vn %.6f %.6f %.6f\n" % tuple(n.normalized()))
        for f in F:
            fh.write("f %d//%d %d//%d %d//%d\n" % (f[0] + 1, f[0] + 1, f[1] + 1, f[1] + 1, f[2] + 1, f[2] + 1))
    print("wrote", path, len(F), "faces")


def main():
    rock()
    primitives()
    suzanne()
    lathe()
    character()


if __name__ == "__main__":
    main()
