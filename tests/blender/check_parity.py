"""Parity with Blender's own Lattice modifier at the original vertices at every level; all
interpolation types, 1-point axes, rotated/scaled objects and lattices, strength, vertex
groups, vertices outside the lattice. At level 1 also at the vertices the knot planes cut into
the faces where the lattice map is a cubic polynomial over each cut piece (LINEAR interpolation
on the flat faces of a cube): those cut-in vertices, whose rest positions must lie on the input
faces, against the Lattice modifier deforming the same rest points. Elsewhere the cut-in
vertices lie on the smooth patches, which approximate the lattice map between the original
vertices: their distance to it is printed, not asserted. Tolerance: 1e-5 of the lattice size."""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402

TOL = 1e-5
INTERPS = ("KEY_LINEAR", "KEY_CARDINAL", "KEY_CATMULL_ROM", "KEY_BSPLINE")

# (mesh, lattice shape, interpolation, object rot/scale, lattice rot/scale, strength, group)
CASES = [
    ("cube", (2, 2, 2), "KEY_LINEAR", None, None, 1.0, None),
    ("suzanne", (3, 3, 3), "KEY_BSPLINE", None, None, 1.0, None),
    ("uvsphere", (4, 3, 5), "KEY_CARDINAL", ((0.3, 0.2, 0.1), (1.2, 0.8, 1.0)), None, 1.0, None),
    ("cylinder", (3, 4, 2), "KEY_CATMULL_ROM", None, ((0.1, 0.5, -0.3), (1.4, 1.1, 0.9)), 1.0, None),
    ("suzanne", (1, 3, 3), "KEY_BSPLINE", ((0.0, 0.0, 0.7), (1, 1, 1)), ((0.2, 0, 0), (1.2, 1.3, 1.4)), 1.0, None),
    ("uvsphere", (3, 1, 2), "KEY_LINEAR", None, ((0, 0.4, 0), (1.0, 1.0, 1.0)), 0.6, None),
    ("cube", (5, 5, 5), "KEY_CARDINAL", ((0.5, 0.5, 0), (0.7, 1.3, 1.1)), ((0, 0, 0.9), (1.3, 1.2, 1.0)), 1.0, "group"),
    ("cylinder", (2, 3, 4), "KEY_BSPLINE", None, None, 0.8, "inverted"),
    ("suzanne", (4, 4, 4), "KEY_CATMULL_ROM", None, None, 1.0, "group"),
    # Lattice much smaller than the mesh: most vertices lie outside it.
    ("uvsphere", (3, 3, 3), "KEY_BSPLINE", None, ((0.3, 0.1, 0.2), (0.6, 0.6, 0.6)), 1.0, None),
    ("suzanne", (2, 1, 1), "KEY_CARDINAL", None, ((0, 0, 0), (0.9, 0.9, 0.9)), 1.0, None),
    ("cube", (3, 3, 3), "KEY_LINEAR", ((0.2, 0.1, 0.0), (2.0, 2.0, 2.0)), ((0.0, 0.1, 0.2), (3.0, 3.0, 3.0)), 1.0, None),
    ("cube", (4, 3, 5), "KEY_LINEAR", ((0.1, 0.3, 0.2), (1.1, 0.9, 1.3)), ((0.2, -0.1, 0.4), (1.2, 1.4, 1.1)), 0.7, None),
]
LEVELS = (1, 2, 3)


def build(case, seed):
    mesh_kind, shape, interp, obj_xf, lat_xf, strength, group = case
    T.clear()
    obj = T.make_mesh(mesh_kind)
    if obj_xf:
        obj.rotation_euler, obj.scale = obj_xf
    lrot, lscale = lat_xf or ((0, 0, 0), (1.5, 1.5, 1.5))
    lat = T.make_lattice(shape, interp, loc=(0.05, -0.03, 0.02), rot=lrot, scale=lscale, seed=seed)
    vg_name, invert = "", False
    if group:
        vg = obj.vertex_groups.new(name="weights")
        rng = np.random.default_rng(seed + 100)
        for v in obj.data.vertices:
            w = float(rng.uniform(0, 1))
            if w > 0.15:   # some vertices stay outside the group (weight 0)
                vg.add([v.index], w, 'REPLACE')
        vg_name, invert = "weights", group == "inverted"
    T.update()
    ref = T.lattice_modifier_twin(obj, lat, strength, vg_name, invert)
    return obj, lat, ref, strength, vg_name, invert


def run_case(i, case):
    obj, lat, ref, strength, vg_name, invert = build(case, seed=i)
    smooth_ffd = T.smooth_ffd
    meshio = T.meshio
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=1, render_level=1, strength=strength,
                                    vertex_group=vg_name, invert_vertex_group=invert)
    T.update()
    size = T.lattice_size(obj, lat)
    expect = T.positions(T.evaluated_mesh(ref))
    src = T.positions(obj.data)
    moved = np.abs(expect - src).max()
    label = f"case{i} {case[0]} {case[1]} {case[2]} s={case[5]} vg={case[6]}"
    for level in LEVELS:
        compat = T.compat
        compat.set_modifier_input(mod, "Viewport Level", level)
        obj.update_tag()
        T.update()
        status = smooth_ffd.status(mod)
        got_mesh = T.evaluated_mesh(obj)
        got = T.positions(got_mesh)
        if len(got) < len(expect):
            T.check(f"{label} L{level}", False, f"too few vertices {len(got)} ({status})")
            continue
        err = np.abs(got[:len(expect)] - expect).max() / size
        detail = f"max err {err:.2e} x lattice size (moved {moved / size:.3f}), {status}"
        ok = err <= TOL and status.startswith("OK")
        T.check(f"{label} L{level}", ok, detail)
        if level == 1 and not vg_name:
            # The vertices the knot planes cut into the faces, against the Lattice modifier
            # deforming their rest points. A LINEAR map is trilinear in each knot cell, a cubic
            # over each flat piece of a cut face, which the level-1 patches reproduce.
            rest = T.point_attribute(got_mesh, meshio.REST_ATTRIBUTE)
            twin = T.points_twin(rest, obj, lat, strength)
            T.update()
            exp_all = T.positions(T.evaluated_mesh(twin))
            err = np.abs(got - exp_all).max() / size
            cut = len(got) - len(expect)
            if case[0] == "cube" and case[2] == "KEY_LINEAR" and max(case[1]) > 2:
                # (Two points on every axis: no inner knot plane, nothing cut.)
                # On the cube's faces: |x|, |y| or |z| is the half size in object space.
                half = np.abs(src).max()
                off = np.abs(np.abs(rest[len(expect):]).max(axis=1) - half).max(initial=0.0) / size
                moved_rest = np.abs(rest[:len(expect)] - src).max() / size
                T.check(f"{label} L1 rest points: the input's, then cut-in ones on its faces",
                        cut > 0 and off <= TOL and moved_rest <= TOL,
                        f"{cut} cut-in vertices, max {off:.2e} x lattice size off the faces, "
                        f"original ones {moved_rest:.2e} off their input positions")
                T.check(f"{label} L1 whole output", err <= TOL,
                        f"max err {err:.2e} x lattice size over {len(got)} vertices")
            else:
                print(f"INFO {label} L1: {cut} cut-in vertices, max distance to the lattice map "
                      f"{err:.2e} x lattice size (the smooth patches approximate it there)")


def main():
    T.setup()
    for i, case in enumerate(CASES):
        T.run(f"case{i}", run_case, i, case)
    T.finish()


main()
