"""The lattice's vertex group (Lattice.vertex_group: per-point weights) against Blender's own
Lattice modifier: the first V output vertices within 1e-5 of the lattice size, at levels 1 and
2, for every interpolation type, rotated/scaled objects and lattices, strength and the
modifier's own vertex group (Blender's factor enters squared), vertices outside the lattice,
one-point axes. Live: weights changed (object mode, and assigned in edit mode), the group
switched, cleared, unknown or empty; weight changes keep the plan."""
import os
import sys
import time

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, compat, latticeio  # noqa: E402

TOL = 1e-5

# (mesh, lattice shape, interpolation, object rot/scale, lattice rot/scale, strength,
#  the modifier's vertex group, the lattice's weights)
CASES = [
    ("uvsphere", (4, 3, 5), "KEY_BSPLINE", None, None, 1.0, None, "random"),
    ("suzanne", (3, 3, 3), "KEY_CARDINAL", ((0.3, 0.2, 0.1), (1.2, 0.8, 1.0)),
     ((0.1, 0.5, -0.3), (1.4, 1.1, 0.9)), 0.7, "group", "random"),
    ("cylinder", (4, 4, 2), "KEY_CATMULL_ROM", None, None, 1.0, "inverted", "one"),
    ("cube", (2, 3, 4), "KEY_LINEAR", ((0.5, 0.5, 0), (0.7, 1.3, 1.1)), None, 0.8, None, "ramp"),
    ("suzanne", (1, 3, 3), "KEY_BSPLINE", None, ((0.2, 0, 0), (1.2, 1.3, 1.4)), 1.0, None, "random"),
    # Lattice smaller than the mesh: most vertices outside it (the boundary weights blend).
    ("uvsphere", (3, 3, 3), "KEY_BSPLINE", None, ((0.3, 0.1, 0.2), (0.6, 0.6, 0.6)), 1.0, None, "random"),
]
LEVELS = (1, 2)


def add_weights(lat, pattern, rng, name="lw"):
    """A vertex group on the lattice object, named by lat.data.vertex_group; some points left
    out of it (weight 0)."""
    vg = lat.vertex_groups.new(name=name)
    n = len(lat.data.points)
    nu = lat.data.points_u
    for i in range(n):
        if pattern == "random":
            w = float(rng.uniform(0, 1))
            if w < 0.15:
                continue
        elif pattern == "ramp":
            w = (i % nu) / max(1, nu - 1)
        else:   # one point only
            if i != n // 2:
                continue
            w = 1.0
        vg.add([i], w, 'REPLACE')
    lat.data.vertex_group = name
    return vg


_last = {}


def parity(label, obj, lat, ref, mod, changed=False):
    """changed: Blender's own result must differ from the last parity's (the edit took)."""
    got = T.positions(T.evaluated_mesh(obj))
    exp = T.positions(T.evaluated_mesh(ref))
    if changed:
        prev = _last.get(ref.name)
        moved = np.abs(exp - prev).max() / T.lattice_size(obj, lat) if prev is not None else 0.0
        T.check(f"{label}: Blender's result changed", moved > 1e-3, f"by {moved:.3f} x lattice size")
    _last[ref.name] = exp
    size = T.lattice_size(obj, lat)
    status = smooth_ffd.status(mod)
    if len(got) < len(exp):
        T.check(label, False, f"{len(got)} < {len(exp)} vertices, {status}")
        return None
    err = np.abs(got[:len(exp)] - exp).max() / size
    T.check(label, err <= TOL and status.startswith("OK"), f"err {err:.2e} x lattice size, {status}")
    return err


def run_case(i, case):
    mesh_kind, shape, interp, obj_xf, lat_xf, strength, group, pattern = case
    T.clear()
    obj = T.make_mesh(mesh_kind)
    if obj_xf:
        obj.rotation_euler, obj.scale = obj_xf
    lrot, lscale = lat_xf or ((0, 0, 0), (1.5, 1.5, 1.5))
    lat = T.make_lattice(shape, interp, loc=(0.05, -0.03, 0.02), rot=lrot, scale=lscale, seed=i)
    rng = np.random.default_rng(i + 50)
    add_weights(lat, pattern, rng)
    vg_name, invert = "", False
    if group:
        vg = obj.vertex_groups.new(name="weights")
        for v in obj.data.vertices:
            w = float(rng.uniform(0, 1))
            if w > 0.15:
                vg.add([v.index], w, 'REPLACE')
        vg_name, invert = "weights", group == "inverted"
    T.update()
    ref = T.lattice_modifier_twin(obj, lat, strength, vg_name, invert)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=1, render_level=1, strength=strength,
                                    vertex_group=vg_name, invert_vertex_group=invert)
    T.update()
    label = f"case{i} {mesh_kind} {shape} {interp} s={strength} vg={group} lw={pattern}"
    for level in LEVELS:
        compat.set_modifier_input(mod, "Viewport Level", level)
        obj.update_tag()
        T.update()
        parity(f"{label} L{level}", obj, lat, ref, mod)
    # The weights matter here: Blender's result without them is far from it.
    lat.data.vertex_group = ""
    T.update()
    unweighted = T.positions(T.evaluated_mesh(ref))
    lat.data.vertex_group = "lw"
    T.update()
    weighted = T.positions(T.evaluated_mesh(ref))
    moved = np.abs(unweighted - weighted).max() / T.lattice_size(obj, lat)
    T.check(f"{label}: the weights move vertices", moved > 1e-3, f"{moved:.3f} x lattice size")


def test_live():
    """Weight edits and group changes through the handlers."""
    T.clear()
    obj = T.make_mesh("suzanne")
    lat = T.make_lattice((4, 4, 4), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=3)
    rng = np.random.default_rng(7)
    vg = add_weights(lat, "random", rng)
    other = lat.vertex_groups.new(name="other")
    for i in range(len(lat.data.points)):
        other.add([i], float(rng.uniform(0.2, 1.0)), 'REPLACE')
    lat.data.vertex_group = "lw"
    ref = T.lattice_modifier_twin(obj, lat)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2, render_level=2)
    T.update()
    parity("live: initial", obj, lat, ref, mod)
    plans = T.state.plans_built[0]

    def tag():
        lat.data.update_tag()   # vertex_group.add tags nothing on 3.4
        lat.update_tag()
        T.update()

    vg.add([0, 5, 21, 42], 0.05, 'REPLACE')
    vg.remove([10, 11])
    tag()
    parity("live: weights changed", obj, lat, ref, mod, changed=True)
    lat.data.vertex_group = "other"
    tag()
    parity("live: lattice vertex group switched", obj, lat, ref, mod, changed=True)
    T.check("live: weight changes and a switched group keep the plan",
            T.state.plans_built[0] == plans, f"{T.state.plans_built[0] - plans} plans built")
    lat.data.vertex_group = ""
    tag()
    parity("live: lattice vertex group cleared", obj, lat, ref, mod, changed=True)
    lat.data.vertex_group = "no such group"
    tag()
    parity("live: unknown lattice vertex group (no weighting)", obj, lat, ref, mod)
    lat.data.vertex_group = "lw"
    tag()
    parity("live: group set again", obj, lat, ref, mod, changed=True)

    # Weights assigned in edit mode (how users set them): the edit lattice's weights.
    bpy.context.view_layer.objects.active = lat
    bpy.ops.object.mode_set(mode='EDIT')
    for i, p in enumerate(lat.data.points):
        p.select = i % 3 == 0
    lat.vertex_groups.active_index = vg.index
    bpy.context.scene.tool_settings.vertex_group_weight = 0.9
    r = bpy.ops.object.vertex_group_assign()
    tag()
    edit_w = np.array([vg.weight(i) if i % 3 == 0 else 0.0 for i in range(0, len(lat.data.points), 3)])
    T.check("live: edit mode assign ran", r == {'FINISHED'} and np.allclose(edit_w[edit_w > 0], 0.9),
            f"{r}")
    parity("live: weights assigned in edit mode", obj, lat, ref, mod, changed=True)
    bpy.ops.object.mode_set(mode='OBJECT')
    T.update()
    parity("live: edit mode left", obj, lat, ref, mod)

    # A lattice whose group was made but never given a point: Blender has no weight layer
    # and deforms fully.
    T.clear()
    obj = T.make_mesh("uvsphere")
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=4)
    lat.vertex_groups.new(name="empty")
    lat.data.vertex_group = "empty"
    ref = T.lattice_modifier_twin(obj, lat)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2, render_level=2)
    T.update()
    err = parity("live: empty lattice vertex group", obj, lat, ref, mod)
    moved = np.abs(T.positions(T.evaluated_mesh(ref)) - T.positions(obj.data)).max()
    print(f"INFO empty group: Blender moves vertices by up to {moved:.3f} (err {err})")


def test_read_time():
    """Reading the weights of a large lattice (printed: it runs on every update)."""
    T.clear()
    lat = T.make_lattice((20, 20, 20), "KEY_BSPLINE", seed=5)
    add_weights(lat, "random", np.random.default_rng(1))
    n = len(lat.data.points)
    t0 = time.perf_counter()
    w = latticeio.lattice_weights(lat, n)
    ms = 1e3 * (time.perf_counter() - t0)
    T.check("read 8000 point weights", w is not None and w.shape == (n,) and (w > 0).sum() > 0.8 * n,
            f"{ms:.1f} ms")
    print(f"INFO reading 8000 lattice point weights: {ms:.1f} ms")


def main():
    T.setup()
    for i, case in enumerate(CASES):
        T.run(f"case{i}", run_case, i, case)
    T.run("live", test_live)
    T.run("read time", test_read_time)
    T.finish()


main()
