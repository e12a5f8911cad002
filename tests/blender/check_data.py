"""Data carried onto the result: vertex groups (before and after Apply), every UV map, and the
warning for modifiers above Smooth FFD that it cannot read (others below it).

Expected values are computed here independently of the add-on's carry code: source
triangles directly, quads through whichever diagonal reproduces the core's own interpolation
of the render UV map (random per-corner values, so the two diagonals disagree)."""
import os
import sys

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402
from sffd_testlib import smooth_ffd, carry, compat, meshio, stack_input  # noqa: E402,E501

RNG = np.random.default_rng(7)


def uv_array(mesh, name):
    out = np.empty(len(mesh.loops) * 2, dtype=np.float32)
    mesh.uv_layers[name].data.foreach_get("uv", out)
    return out.reshape(-1, 2)


def set_uv(mesh, name, values):
    layer = mesh.uv_layers.get(name) or mesh.uv_layers.new(name=name)
    layer.data.foreach_set("uv", np.ascontiguousarray(values, np.float32).ravel())
    return layer


def groups_of(mesh, names):
    """{name: (member (N,) bool, weight (N,) float32)} read vertex by vertex."""
    out = {n: (np.zeros(len(mesh.vertices), bool), np.zeros(len(mesh.vertices), np.float32))
           for n in names}
    for v in mesh.vertices:
        for g in v.groups:
            m, w = out[names[g.group]]
            m[v.index] = True
            w[v.index] = g.weight
    return out


def face_attr(mesh):
    out = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.attributes[meshio.SOURCE_FACE_ATTRIBUTE].data.foreach_get("value", out)
    return out


def sphere_scene(level=2, render_level=3):
    T.clear()
    obj = T.make_mesh("uvsphere")   # 16 x 8: quads and triangle fans at the poles
    me = obj.data
    # Random per-corner values for the render map: the core's interpolation of it tells which
    # diagonal it cut each quad along (independent of the add-on's own triangulation).
    set_uv(me, "UVMap", RNG.uniform(0, 1, (len(me.loops), 2)))
    set_uv(me, "second", RNG.uniform(-1, 2, (len(me.loops), 2)))
    me.uv_layers.active = me.uv_layers["second"]
    me.uv_layers["UVMap"].active_render = True
    co = T.positions(me)
    full = obj.vertex_groups.new(name="full")
    part = obj.vertex_groups.new(name="partial")
    for v in me.vertices:
        full.add([v.index], float(0.5 + 0.5 * co[v.index, 2] / 0.8), 'REPLACE')
        if co[v.index, 0] > -0.1:   # about half the sphere
            w = 1.0 if co[v.index, 1] > 0.3 else float(RNG.uniform(0, 1))
            part.add([v.index], w, 'REPLACE')
    me.update()
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=render_level)
    T.update()
    return obj, lat, mod


class Source:
    """The source's corners, UVs and groups, read before the test changes anything."""

    def __init__(self, obj):
        me = obj.data
        self.nv = len(me.vertices)
        self.co = T.positions(me)
        self.cv = T.triangles_like_loops(me)
        self.fo = np.concatenate([[0], np.cumsum([p.loop_total for p in me.polygons])])
        self.uv = {l.name: uv_array(me, l.name) for l in me.uv_layers}
        self.names = [g.name for g in obj.vertex_groups]
        self.groups = groups_of(me, self.names)
        face = np.repeat(np.arange(len(me.polygons)), np.diff(self.fo))
        self.corner_of = {(int(f), int(v)): c for c, (f, v) in enumerate(zip(face, self.cv))}


def candidate_triangles(src, f):
    """Corner triples of face f: the face itself, or a quad's two triangles per diagonal."""
    c = list(range(src.fo[f], src.fo[f + 1]))
    if len(c) == 3:
        return [[c]]
    assert len(c) == 4, len(c)
    a, b, cc, d = c
    return [[(a, b, cc), (a, cc, d)], [(a, b, d), (b, cc, d)]]


def bary(x, pts):
    """Barycentric coordinates of x in triangle pts (3, 3), in float64, own code."""
    a, b, c = pts
    m = np.stack([b - a, c - a], axis=1)
    sol, *_ = np.linalg.lstsq(m, x - a, rcond=None)
    return np.array([1 - sol.sum(), sol[0], sol[1]])


def expected_at(src, f, x, render_uv, render_name):
    """(barycentrics, source corners) of rest point x in face f's triangle the core used,
    and how far the render-UV prediction is from the core's value (the disambiguation)."""
    best = None
    for option in candidate_triangles(src, f):
        # The triangle of this triangulation that holds x (largest smallest coordinate).
        b, tri = max(((bary(x, src.co[src.cv[list(t)]]), t) for t in option),
                     key=lambda bt: bt[0].min())
        pred = b @ src.uv[render_name][list(tri)]
        err = np.abs(pred - render_uv).max()
        if best is None or err < best[2]:
            best = (b, tri, err)
    return best


def check_interpolated(label, out_mesh, src, corners_out, uv_out_render, check_fn):
    """For output corners (triangle, corner) pairs: compute the expected triangle and call
    check_fn(b, tri, k) -> error; returns the worst error and the worst disambiguation."""
    tris = T.triangles(out_mesh)
    faces = face_attr(out_mesh)
    rest = T.point_attribute(out_mesh, meshio.REST_ATTRIBUTE).astype(np.float64)
    worst, worst_pick = 0.0, 0.0
    for t, k in corners_out:
        o = tris[t, k]
        b, tri, pick = expected_at(src, int(faces[t]), rest[o], uv_out_render[3 * t + k], "UVMap")
        worst_pick = max(worst_pick, pick)
        worst = max(worst, check_fn(b, tri, o, 3 * t + k))
    return worst, worst_pick


def test_vertex_groups():
    obj, lat, mod = sphere_scene()
    src = Source(obj)
    nv = src.nv
    # Before Apply: the result carries the groups, so a modifier below sees them.
    disp = obj.modifiers.new("Displace", 'DISPLACE')
    disp.vertex_group = "partial"
    disp.direction = 'Z'
    disp.mid_level = 0.0
    disp.strength = 0.1
    disp.show_viewport = False
    T.update()
    plain = T.positions(T.evaluated_mesh(obj))
    disp.show_viewport = True
    T.update()
    shifted = T.positions(T.evaluated_mesh(obj))
    ev = T.evaluated_mesh(obj)
    eobj = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    enames = [g.name for g in eobj.vertex_groups]
    T.check("result carries group names", enames == src.names, str(enames))
    eg = groups_of(ev, enames)["partial"]
    dz = (shifted - plain)[:, 2] / 0.1
    T.check("Displace below reads the carried group",
            np.abs(dz - np.where(eg[0], eg[1], 0)).max() < 1e-5 and eg[0][nv:].any(),
            f"max |dz - w| {np.abs(dz - np.where(eg[0], eg[1], 0)).max():.1e}, "
            f"{int(eg[0].sum())}/{len(eg[0])} vertices in 'partial'")
    obj.modifiers.remove(disp)
    T.update()

    timing_before = T.pipeline.last_timing(obj, mod)
    smooth_ffd.apply_smooth_ffd(obj, mod)
    T.update()
    me = obj.data
    names = [g.name for g in obj.vertex_groups]
    T.check("apply: vertex group names", names == src.names, str(names))
    got = groups_of(me, names)
    for name in src.names:
        m_in, w_in = src.groups[name]
        m_out, w_out = got[name]
        T.check(f"apply: '{name}' first V exact",
                np.array_equal(m_out[:nv], m_in) and np.array_equal(w_out[:nv][m_in], w_in[m_in]),
                f"{int(m_in.sum())} members, max diff "
                f"{np.abs(w_out[:nv] - w_in).max():.1e}")
    # Interpolated weights: every corner of every triangle of the first 400 output triangles
    # (and all pole triangles), against this file's own barycentric computation.
    uv_render = uv_array(me, "UVMap")
    tris = T.triangles(me)
    faces = face_attr(me)
    pole = np.nonzero(np.diff(src.fo)[faces] == 3)[0][:200]
    sample = [(int(t), k) for t in np.concatenate([np.arange(400), pole]) for k in range(3)
              if tris[t, k] >= nv]
    for name in src.names:
        m_in, w_in = src.groups[name]
        m_out, w_out = got[name]

        def err(b, tri, o, _c, m_in=m_in, w_in=w_in, m_out=m_out, w_out=w_out):
            v = src.cv[list(tri)]
            used = b > 1e-6
            exp_m = bool((m_in[v] & used).any())
            exp_w = float(np.clip(b, 0, None) @ np.where(m_in[v], w_in[v], 0.0))
            if exp_m != bool(m_out[o]):
                return np.inf
            return abs(exp_w - float(w_out[o])) if exp_m else 0.0
        worst, pick = check_interpolated(name, me, src, sample, uv_render, err)
        T.check(f"apply: '{name}' interpolated weights", worst < 1e-5 and pick < 1e-5,
                f"{len(sample)} corners, max err {worst:.1e} (triangle pick {pick:.1e})")
    t = timing_before or {}
    print(f"carry: {t.get('carry_ms', 0):.1f} ms, {t.get('carry_add_calls', 0)} VertexGroup.add calls")


def test_uv_maps():
    obj, lat, mod = sphere_scene()
    src = Source(obj)
    nv = src.nv
    smooth_ffd.apply_smooth_ffd(obj, mod)
    me = obj.data
    names = [l.name for l in me.uv_layers]
    T.check("UV map names and order", names == ["UVMap", "second"], str(names))
    T.check("active UV map kept", me.uv_layers.active.name == "second", me.uv_layers.active.name)
    render = [l.name for l in me.uv_layers if l.active_render]
    T.check("active render UV map kept", render == ["UVMap"], str(render))
    tris = T.triangles(me)
    faces = face_attr(me)
    out = {n: uv_array(me, n) for n in names}
    # Original corners: exactly the source's values (every output corner at a source vertex).
    for n in names:
        k = np.nonzero(tris.ravel() < nv)[0]
        ref = np.array([src.uv[n][src.corner_of[(int(faces[i // 3]), int(tris.ravel()[i]))]]
                        for i in k])
        T.check(f"'{n}' at original corners exact", np.array_equal(out[n][k], ref),
                f"{len(k)} corners, max diff {np.abs(out[n][k] - ref).max():.1e}")
    # Inside faces: the first 300 output triangles' corners, this file's interpolation.
    sample = [(t, k) for t in range(300) for k in range(3)]

    def err(b, tri, _o, c):
        return float(np.abs(np.clip(b, 0, None) @ src.uv["second"][list(tri)] - out["second"][c]).max())
    worst, pick = check_interpolated("second", me, src, sample, out["UVMap"], err)
    T.check("'second' interpolated inside faces", worst < 2e-6 and pick < 1e-5,
            f"{len(sample)} corners, max err {worst:.1e} (triangle pick {pick:.1e})")


def test_carry_matches_core():
    """A copy of the render UV map under another name goes through the add-on's carrying
    (Plan.interpolate_corners) and must come out as the core's own UVs, bitwise; the plan's
    vertex sources put every output vertex on its rest position."""
    T.clear()
    obj = T.make_mesh("uvsphere")
    me = obj.data
    set_uv(me, "UVMap", RNG.uniform(0, 1, (len(me.loops), 2)))
    set_uv(me, "copy", uv_array(me, "UVMap"))
    me.uv_layers["UVMap"].active_render = True
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=3)
    T.update()
    st = T.objects.state_of(obj, mod)
    res = st.result
    ev = T.evaluated_mesh(obj)
    copy, render = uv_array(ev, "copy"), uv_array(ev, "UVMap")
    T.check("carried copy == core's UVs (all corners, bitwise)",
            np.array_equal(copy, res.uvs.reshape(-1, 2)) and np.array_equal(copy, render),
            f"{len(copy)} corners, max diff {np.abs(copy - res.uvs.reshape(-1, 2)).max():.1e}")
    plan = st.deformer.plan
    tri, bary = plan.vertex_sources()
    corners, _ = plan.input_triangles()
    src = Source(obj)
    pts = src.co[src.cv[corners[tri]]].astype(np.float64)
    err = np.abs(np.einsum("nk,nki->ni", bary, pts) - res.rest_positions).max()
    T.check("vertex sources reproduce the rest positions", err < 2e-6, f"max err {err:.1e}")


def test_no_extras_no_cost():
    """No groups, one UV map: the vertex sources are never asked for (nothing added to the
    hot path) and no VertexGroup.add is called."""
    T.clear()
    obj = T.make_mesh("uvsphere")
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    calls = []
    group_values = carry.group_values
    carry.group_values = lambda *a: calls.append(1) or group_values(*a)
    try:
        mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2)
        T.update()
    finally:
        carry.group_values = group_values
    t = T.pipeline.last_timing(obj, mod)
    T.check("no groups, one UV map: nothing carried", not calls and t["carry_add_calls"] == 0,
            f"carry {t['carry_ms']:.2f} ms")
    ev = T.evaluated_mesh(obj)
    T.check("one UV map carried", [l.name for l in ev.uv_layers] == ["UVMap"])


def test_extras_follow_edits():
    """Carried data follow source edits that need no new plan (weights, UV maps, groups)."""
    obj, lat, mod = sphere_scene()
    st = T.objects.state_of(obj, mod)
    plan = st.plan_key
    nv = len(obj.data.vertices)
    v = int(np.nonzero(groups_of(obj.data, ["full", "partial"])["partial"][0])[0][0])
    obj.vertex_groups["partial"].add([v], 0.123, 'REPLACE')
    obj.data.update()
    T.update()
    ev = T.evaluated_mesh(obj)
    g = groups_of(ev, [x.name for x in obj.evaluated_get(
        bpy.context.evaluated_depsgraph_get()).vertex_groups])["partial"]
    T.check("edited weight carried", abs(float(g[1][v]) - 0.123) < 1e-7 and st.plan_key == plan,
            f"{float(g[1][v]):.6f}, same plan {st.plan_key == plan}")
    set_uv(obj.data, "third", RNG.uniform(0, 1, (len(obj.data.loops), 2)))
    obj.data.update()
    T.update()
    ev = T.evaluated_mesh(obj)
    T.check("new UV map carried", [l.name for l in ev.uv_layers] == ["UVMap", "second", "third"]
            and st.plan_key == plan, str([l.name for l in ev.uv_layers]))
    # Blender 3.4 re-reads split normals of an unchanged big mesh with ~2e-7 differences:
    # such a re-read must keep the plan (simulated here, as this sphere is small).
    read = compat.read_corner_normals
    compat.read_corner_normals = lambda m: read(m) + np.float32(2e-7) * np.sign(
        RNG.standard_normal((len(m.loops), 3))).astype(np.float32)
    try:
        obj.vertex_groups["full"].add([v], 0.5, 'REPLACE')
        obj.data.update()
        T.update()
    finally:
        compat.read_corner_normals = read
    T.check("normals jitter on re-read keeps the plan", st.plan_key == plan and
            not T.pipeline.last_timing(obj, mod)["rebuilt"], str(T.pipeline.last_timing(obj, mod)["rebuilt"]))
    obj.vertex_groups.clear()
    obj.data.update()
    T.update()
    eobj = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    T.check("removed groups leave the result", len(eobj.vertex_groups) == 0 and
            len(T.evaluated_mesh(obj).vertices) > nv, str([x.name for x in eobj.vertex_groups]))


def move_to(obj, name, index):
    with bpy.context.temp_override(object=obj, active_object=obj):
        bpy.ops.object.modifier_move_to_index(modifier=name, index=index)


def test_modifiers_above():
    """Modifiers above are read (stack_input: check_stack_input.py compares with Blender's
    Lattice modifier), also with other modifiers below (through the input copy)."""
    T.clear()
    obj = T.make_mesh("cube")
    lat = T.make_lattice((3, 3, 3), "KEY_BSPLINE", scale=(1.6, 1.6, 1.6), seed=5)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=2)
    T.update()
    T.check("no warning when first", "warning" not in smooth_ffd.status(mod), smooth_ffd.status(mod))
    sub = obj.modifiers.new("Subdiv", 'SUBSURF')
    T.update()
    T.check("no warning for a modifier below", "warning" not in smooth_ffd.status(mod))
    deferred = T.state.stack_counters["deferred"]
    move_to(obj, sub.name, 0)
    T.update()
    # Moved above: the group shows the old result (its input was the object's own mesh, which
    # it does not check), and the handler cannot evaluate again inside the depsgraph's
    # update, so the input is read on the next one (in a window a timer runs it at once;
    # here smooth_ffd.update does).
    T.check("moved above: read on the next update",
            T.state.stack_counters["deferred"] == deferred + 1, str(T.state.stack_counters))
    smooth_ffd.update(obj)
    st = T.objects.state_of(obj, mod)
    T.check("a modifier above: its geometry is the input, no warning",
            "warning" not in smooth_ffd.status(mod) and smooth_ffd.status(mod).startswith("OK")
            and st.source.num_vertices > len(obj.data.vertices),
            f"{st.source.num_vertices} input vertices: {smooth_ffd.status(mod)}")
    wave = obj.modifiers.new("Wave", 'WAVE')   # below: the input copy is turned on
    T.update()
    smooth_ffd.update(obj)
    T.check("a modifier below as well: the geometry above is still the input, no warning",
            smooth_ffd.status(mod).startswith("OK") and "warning" not in smooth_ffd.status(mod)
            and st.source.num_vertices > len(obj.data.vertices) and
            compat.get_modifier_input(mod, "Input Copy") == 2,
            f"{st.source.num_vertices} input vertices: {smooth_ffd.status(mod)}")
    lat.data.points[3].co_deform.z += 0.2   # a lattice edit: the last reading holds
    reads = T.state.stack_counters["reads"]
    T.update()
    T.check("lattice edit with a modifier below: no new reading, status OK",
            T.state.stack_counters["reads"] == reads and smooth_ffd.status(mod).startswith("OK"),
            f"{T.state.stack_counters}: {smooth_ffd.status(mod)}")
    # A Geometry Nodes modifier below that keeps only the mesh drops the input copy: a clear
    # error naming it, and the object shows its input (no result).
    drop = bpy.data.node_groups.new("mesh only", 'GeometryNodeTree')
    compat.new_group_socket(drop, 'INPUT', 'NodeSocketGeometry', "Geometry")
    compat.new_group_socket(drop, 'OUTPUT', 'NodeSocketGeometry', "Geometry")
    gi, go = drop.nodes.new('NodeGroupInput'), drop.nodes.new('NodeGroupOutput')
    parts = drop.nodes.new('GeometryNodeSeparateComponents')
    drop.links.new(gi.outputs[0], parts.inputs[0])
    drop.links.new(parts.outputs["Mesh"], go.inputs[0])
    gn = obj.modifiers.new("Mesh Only", 'NODES')
    gn.node_group = drop
    T.update()
    smooth_ffd.update(obj)
    status = smooth_ffd.status(mod)
    T.check("a Geometry Nodes modifier below dropping instances: error naming it",
            status.startswith("Error") and "'Mesh Only'" in status and "instances" in status,
            status)
    obj.modifiers.remove(gn)
    T.update()
    smooth_ffd.update(obj)
    T.check("that modifier removed: OK again", smooth_ffd.status(mod).startswith("OK") and
            st.source.num_vertices > len(obj.data.vertices), smooth_ffd.status(mod))
    wave.show_viewport = wave.show_render = False
    T.update()
    smooth_ffd.update(obj)
    T.check("disabled modifiers below do not count: Input Copy off",
            compat.get_modifier_input(mod, "Input Copy") == 0 and
            st.source.num_vertices > len(obj.data.vertices), smooth_ffd.status(mod))
    move_to(obj, mod.name, 0)
    T.update()
    T.check("first again: no warning", "warning" not in smooth_ffd.status(mod),
            smooth_ffd.status(mod))


def fit_error_values(mesh):
    a = mesh.attributes.get(meshio.FIT_ERROR_ATTRIBUTE)
    if a is None:
        return None
    out = np.empty(len(a.data), dtype=np.float32)
    a.data.foreach_get("value", out)
    return a.domain, a.data_type, out


def test_fit_error_attribute():
    """The fit error bound on the result: a face attribute whose value bounds, over each input
    face, the output's distance from Blender's own Lattice modifier at the output's rest
    points (the exact FFD of the flat input: the cube's faces are flat, so the output is the
    fitted patches themselves); its maximum in the status; written with exact results (render;
    the viewport where it shows exact normals), and no stale value after other updates."""
    T.clear()
    obj = T.make_mesh("cube")
    lat = T.make_lattice(jitter=0.25, seed=11)
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=4, render_level=4)
    T.update()
    smooth_ffd.update(obj, render=True)
    ro = T.objects.result_object(obj, mod, create=False)
    got = fit_error_values(ro.data)
    status = smooth_ffd.status(mod)
    T.check("render update: the fit error is a float face attribute of the result",
            got is not None and got[0] == 'FACE' and got[1] == 'FLOAT' and len(got[2]) == len(ro.data.polygons),
            str(got and got[:2]))
    if got is None:
        return
    err = got[2]
    T.check("the status shows the largest bound", f"fit error \u2264 {float(err.max()):.3g}" in status, status)
    size = T.lattice_size(obj, lat)
    pos = T.positions(ro.data)
    tris = T.triangles(ro.data)
    face = face_attr(ro.data)
    rest = T.point_attribute(ro.data, meshio.REST_ATTRIBUTE)
    twin = T.points_twin(rest, obj, lat)   # evaluating it may update the result (viewport)
    T.update()
    exact = T.positions(T.evaluated_mesh(twin))
    bpy.data.objects.remove(twin)
    dist = np.linalg.norm(pos - exact, axis=1)[tris].max(axis=1)
    true_face = np.zeros(face.max() + 1)
    bound_face = np.zeros(face.max() + 1)
    np.maximum.at(true_face, face, dist)
    np.maximum.at(bound_face, face, err)
    T.check("each triangle's bound is its input face's", bool(np.all(err == bound_face[face])))
    T.check("each face's distance from the exact FFD is within its bound",
            bool(np.all(true_face <= bound_face * (1 + 1e-3) + 1e-6 * size)),
            f"worst excess {float(np.max(true_face - bound_face)):.3g}, bound max {float(err.max()):.3g}")
    ratio = bound_face / np.maximum(true_face, 1e-12)
    T.check("the bound is a close one (every face within 1-3x of its distance)",
            bool(np.all((ratio >= 1.0) & (ratio < 3.0))), str(np.round(ratio, 2)))
    # A viewport update: on 3.4-4.4 it computes positions only (no estimate) unless Exact
    # Normals is on; then no value of the render update may stay behind.
    lat.data.points[0].co_deform = np.array(lat.data.points[0].co_deform) + 0.1
    T.update()
    smooth_ffd.update(obj, force=True)
    exact_update = ro.data.get(T.state.NORMALS_KEY) == "exact"
    got = fit_error_values(ro.data)
    T.check("a viewport update: the attribute where it was estimated (exact results), else none",
            (got is not None) == exact_update, f"exact {exact_update}, attribute {got is not None}")
    T.check("the modified object carries what the result has",
            (meshio.FIT_ERROR_ATTRIBUTE in T.evaluated_mesh(obj).attributes) == exact_update,
            str(list(T.evaluated_mesh(obj).attributes.keys())))


def main():
    T.setup()
    for fn in (test_vertex_groups, test_uv_maps, test_carry_matches_core, test_extras_follow_edits,
               test_no_extras_no_cost, test_modifiers_above, test_fit_error_attribute):
        T.run(fn.__name__, fn)
    T.finish()


main()
