"""Timing of one live update (a lattice point moved) in Blender: Smooth FFD beside Blender's
Lattice + Subdivision Surface at the same density, in the same run. Prints, asserts nothing.

    blender -b --factory-startup --python blender_scenes/bench_addon.py [-- REPEATS [ab] [noexact] [WORKLOAD...]]
    ~/.cache/smoothffd/venv-bpy-5.0/bin/python blender_scenes/bench_addon.py [REPEATS [ab] [noexact] [WORKLOAD...]]

Workloads (default: sphere):
  sphere   the 46.8k-triangle sphere, 5x5x5 lattice: Smooth FFD viewport levels 4 and 10
           beside Lattice + Subsurf levels 2 and 3 (and exact normals on 3.4-4.0);
  targets  the live-update table of docs/benchmarks.md: suzanne, sphere4 and dense below;
  suzanne  Suzanne with Subsurf 2 applied (15,744 triangles, smooth), 4x4x4 lattice:
           levels 2, 3, 4 beside Subsurf 1 and 2 (level 2 ~ Subsurf 1, level 4 ~ Subsurf 2);
  wrapped  suzanne in a 4x4x4 lattice wrapped around it (lattice(): the mesh crosses every
           knot span, as with a lattice an artist fits; not part of targets);
  sphere4  the 46.8k-triangle sphere at level 4 beside Subsurf 2: updates per second;
  dense    a 199,692-triangle sphere (quads) in an 8x8x8 lattice wrapped around it (lattice()),
           level 2 beside Subsurf 1: one lattice point moved (the middle one, and (1, 1, 1)
           next to a corner) against all points moved;
  adaptive suzanne (4x4x4 lattice) at viewport levels 2, 3, 4 beside the Tolerance mode at the
           same accuracy: t = e_L, the level-L output's true distance from its patches
           (tests/tessellation_error.py on the core's patches of the modifier's inputs).
Smooth FFD rows on 4.5+: exact normals on every update (background mode), and "live", the
viewport while a point is dragged (positions only, state.LIVE).

Each row splits its median update into where the time went, from marker handlers placed
first and last in depsgraph_update_pre/post: "pre" (Smooth FFD's work in
depsgraph_update_pre), "eval1" (Blender's evaluation before depsgraph_update_post), "post"
(Smooth FFD's work in depsgraph_update_post) and "eval2" (the second evaluation Blender runs
when a post handler tagged something, plus reading the mesh); inside the Smooth FFD work:
deform (core), mesh write, normals. "Blender alone (nothing new)": the object re-evaluated
with nothing changed and the add-on muted, the least any update can cost here.
"""
import os
import sys
import time

import bpy  # first: the bpy module puts bmesh on sys.path
import bmesh  # noqa: E402
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
# The add-on and the core from the source tree (a development build: scripts/build.sh).
sys.path[:0] = [os.path.join(ROOT, "addon"), os.path.join(ROOT, "python")]
import smooth_ffd  # noqa: E402
from smooth_ffd import compat, handlers, pipeline, state  # noqa: E402


def argv():
    a = sys.argv
    if "--" in a:
        return a[a.index("--") + 1:]
    return [] if "--python" in a else a[1:]


REPEATS = int(argv()[0]) if argv() else 5
# "ab": Smooth FFD rows also without the add-on's depsgraph_update_pre handler, interleaved.
AB = "ab" in argv()[1:]
# "noexact": skip the exact-normals rows on 3.4-4.0 (minutes at level 10; the tests use it).
NO_EXACT = "noexact" in argv()[1:]
_GROUPS = {"targets": ("suzanne", "sphere4", "dense")}
WORKLOADS = [w for a in argv()[1:] if a not in ("ab", "noexact")
             for w in _GROUPS.get(a, (a,))] or ["sphere"]
for _w in WORKLOADS:
    if _w not in ("sphere", "suzanne", "wrapped", "sphere4", "dense", "adaptive"):
        sys.exit(f"bench_addon.py: unknown workload {_w!r} (sphere, targets, suzanne, wrapped, sphere4, "
                 "dense, adaptive)")


def sphere_mesh(name, u=180, v=131, triangulate=True):
    """UV sphere, smooth. 180 x 131 triangulated: 2 * 180 * 130 = 46,800 triangles."""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=u, v_segments=v, radius=1.0)
    if triangulate:
        bmesh.ops.triangulate(bm, faces=bm.faces[:])
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    return me


def cube_sphere_mesh(name, cuts=128):
    """A cube's faces cut into (cuts + 1)^2 quads each, pushed onto the unit sphere, smooth:
    6 * 129^2 = 99,846 quads (199,692 triangles) at 128 cuts. (A UV sphere this dense has
    400-valent poles, on which Blender 3.4's first Subdivision Surface takes minutes.)"""
    me = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=2.0)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=cuts, use_grid_fill=True)
    for v in bm.verts:
        v.co.normalize()
    bm.to_mesh(me)
    bm.free()
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    me.update()
    return me


def suzanne_mesh():
    """Blender's Suzanne with a Subdivision Surface level 2 applied: 7,872 quads (15,744
    triangles), smooth."""
    me = bpy.data.meshes.new("suzanne_base")
    bm = bmesh.new()
    bmesh.ops.create_monkey(bm)
    bm.to_mesh(me)
    bm.free()
    tmp = link(bpy.data.objects.new("suzanne_tmp", me))
    tmp.modifiers.new("Subsurf", 'SUBSURF').levels = 2
    bpy.context.view_layer.update()
    out = bpy.data.meshes.new_from_object(tmp.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    out.name = "suzanne"
    bpy.data.objects.remove(tmp)
    bpy.data.meshes.remove(me)
    out.polygons.foreach_set("use_smooth", np.ones(len(out.polygons), dtype=bool))
    out.update()
    return out


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def sphere(name):
    """The 46,800-triangle sphere as an object."""
    return link(bpy.data.objects.new(name, sphere_mesh(name)))


def lattice(n=5, center=(0.0, 0.0, 0.0), size=(2.4, 2.4, 2.4), wrap=False):
    """n x n x n lattice (B-spline, Blender's default interpolation) around center, its
    deformed points jittered by up to 0.03 of a cell (the same seed for every run).

    Its points are made before it has an object, so Blender spaces them 1 apart (co from
    -(n-1)/2 to (n-1)/2; a lattice resized in the UI keeps -0.5..0.5 instead). Scaled by
    `size`, the lattice then spans (n-1) size, and a mesh of about `size` lies in its middle
    knot span only: no knot plane cuts it, and only the middle 4 points an axis move it
    (workloads suzanne, sphere4 and sphere, as their figures have always been measured).
    wrap=True scales it to span `size` instead, as an artist fits a lattice around a mesh:
    the mesh crosses every knot span, and each point moves the part of it near that point
    (workload dense)."""
    lt = bpy.data.lattices.new("lat")
    lt.points_u = lt.points_v = lt.points_w = n   # 5: the paper's 5x5x5 control points
    obj = link(bpy.data.objects.new("lat", lt))
    obj.location = center
    obj.scale = tuple(s / (n - 1) for s in size) if wrap else size
    rng = np.random.default_rng(1)
    for p in lt.points:
        p.co_deform = np.array(p.co) + rng.uniform(-0.03, 0.03, 3)
    return obj


def mesh_triangles(me):
    return len(me.loops) - 2 * len(me.polygons)


def add_sffd(obj, lat, level, exact, read=None):
    """Smooth FFD (CPU backend) at this viewport and render level, Exact Normals on or off,
    evaluated (read(obj): also the evaluated mesh); returns (modifier, ms of that first
    update, the plan included)."""
    t = time.perf_counter()
    mod = smooth_ffd.add_smooth_ffd(obj, lat, viewport_level=level, render_level=level,
                                    backend="cpu")
    compat.set_modifier_input(mod, "Exact Normals", exact)
    obj.update_tag()
    bpy.context.view_layer.update()
    if read is not None:
        read(obj)
    return mod, 1e3 * (time.perf_counter() - t)


def only_visible(obj):
    """Hidden objects are not evaluated, so each timing sees one object's work."""
    for o in bpy.context.scene.objects:
        if o.type == 'MESH':
            o.hide_viewport = o is not obj


_marks = []


def _mark(name):
    def handler(*_args):
        _marks.append((name, time.perf_counter()))
    handler.__name__ = f"bench_mark_{name}"
    return handler


_MARKERS = (("depsgraph_update_pre", 0, _mark("pre_begin")),
            ("depsgraph_update_pre", None, _mark("pre_end")),
            ("depsgraph_update_post", 0, _mark("post_begin")),
            ("depsgraph_update_post", None, _mark("post_end")))


def _install_markers():
    """Markers first and last in the handler lists (after the add-on registered its own)."""
    for name, index, fn in _MARKERS:
        lst = getattr(bpy.app.handlers, name)
        if fn in lst:
            lst.remove(fn)
        if index is None:
            lst.append(fn)
        else:
            lst.insert(index, fn)


def _phases(t0, t_end):
    """ms per phase of one update from the markers (first pre/post call of the update)."""
    first = {}
    for name, t in _marks:
        first.setdefault(name, t)
    pre_b, pre_e = first.get("pre_begin", t0), first.get("pre_end", t0)
    post_b, post_e = first.get("post_begin", t_end), first.get("post_end", t_end)
    return {"pre": pre_e - pre_b, "eval1": post_b - pre_e, "post": post_e - post_b,
            "eval2": t_end - post_e}


def _set_early(on):
    """Installs or removes the add-on's depsgraph_update_pre handler (A/B runs only)."""
    lst = bpy.app.handlers.depsgraph_update_pre
    fn = handlers.on_depsgraph_update_pre
    if on and fn not in lst:
        lst.append(fn)
    elif not on and fn in lst:
        lst.remove(fn)


def center_point(lat):
    """Index of the lattice's middle point (62 in a 5x5x5 lattice)."""
    lt = lat.data
    return lt.points_u // 2 + lt.points_u * (lt.points_v // 2 + lt.points_v * (lt.points_w // 2))


def near_corner_point(lat):
    """Index of point (1, 1, 1): next to the first corner (73 in an 8x8x8 lattice)."""
    lt = lat.data
    return 1 + lt.points_u * (1 + lt.points_v)


def _move(lat, move, sign):
    """Moves the middle point ("one"), point (1, 1, 1) ("corner") or every point ("all", each
    its own direction)."""
    pts = lat.data.points
    if move in ("one", "corner"):
        pts[center_point(lat) if move == "one" else near_corner_point(lat)].co_deform.z += 0.01 * sign
        return
    d = np.random.default_rng(2).uniform(-0.01, 0.01, (len(pts), 3))
    for p, dp in zip(pts, d):
        p.co_deform = np.array(p.co_deform) + sign * dp


def time_edit(lat, obj, repeats, mod=None, early_modes=(True,), moves=("one",)):
    """{(early, move): (median ms, split)}: ms from moving lattice points (move "one": the
    middle point, "corner": point (1, 1, 1), "all": every point; the points are moved before
    the clock starts) to the
    evaluated mesh being ready, and the median of each phase (see the module docstring) and
    of Smooth FFD's own timings. With early_modes=(True, False) the updates alternate
    between the add-on as shipped and the add-on without its depsgraph_update_pre handler;
    several moves alternate likewise (interleaved, so that all see the same machine load).

    Blender 4.x/5.x evaluate a final Subdivision Surface lazily, when the mesh is first
    accessed, so the timing includes that access (len(vertices)) for both stacks."""
    samples = {(e, m): ([], [], []) for e in early_modes for m in moves}
    for i in range(repeats):
        for early, move in samples:
            _set_early(early)
            _install_markers()
            times, phases, own = samples[early, move]
            _move(lat, move, 1 if i % 2 == 0 else -1)
            _marks.clear()
            t = time.perf_counter()
            bpy.context.view_layer.update()
            dg = bpy.context.evaluated_depsgraph_get()
            len(obj.evaluated_get(dg).data.vertices)
            t_end = time.perf_counter()
            times.append(1e3 * (t_end - t))
            phases.append({k: 1e3 * v for k, v in _phases(t, t_end).items()})
            lt = pipeline.last_timing(obj, mod) if mod is not None else None
            if lt:
                own.append(lt)
    _set_early(True)
    med = lambda xs: float(np.median(xs)) if xs else 0.0
    out = {}
    for key, (times, phases, own) in samples.items():
        split = {k: med([ph[k] for ph in phases]) for k in phases[0]}
        for k in ("deform_ms", "mesh_write_ms", "normals_ms"):
            split[k] = med([lt.get(k, 0.0) for lt in own])
        split["core_ms"] = med([lt.get("stats", {}).get("deform_ms", 0.0) for lt in own])
        split["patch_share"] = med([lt.get("stats", {}).get("recomputed_patches", 0) /
                                    max(lt.get("stats", {}).get("patches", 1), 1) for lt in own])
        split["normals_path"] = own[-1].get("normals") if own else None
        split["device"] = own[-1].get("stats", {}).get("device") if own else None
        out[key] = (med(times), split)
    return out


def time_reevaluation(obj, repeats):
    """Median ms of Blender re-evaluating obj with nothing new (the object tagged, the add-on's
    handlers muted): what showing any update costs at least, the copy its modifier makes of
    the result included."""
    times = []
    with state.muted():
        for _ in range(repeats):
            obj.update_tag()
            t = time.perf_counter()
            bpy.context.view_layer.update()
            len(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.vertices)
            times.append(1e3 * (time.perf_counter() - t))
    return float(np.median(times))


def _phase_text(split):
    return (f"pre {split['pre']:.0f} + eval1 {split['eval1']:.0f} + post {split['post']:.0f}"
            f" + eval2 {split['eval2']:.0f}")


def evaluated_tris(obj):
    """Triangles of the evaluated mesh (Subdivision Surface makes quads: 2 each)."""
    dg = bpy.context.evaluated_depsgraph_get()
    me = obj.evaluated_get(dg).data
    return len(me.loops) - 2 * len(me.polygons)


def clear_objects():
    for o in list(bpy.data.objects):
        bpy.data.objects.remove(o)


def _load():
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def workload_sphere():
    """The 46.8k-triangle sphere: levels 4 and 10 beside Subsurf 2 and 3 (the default)."""
    clear_objects()
    lat = lattice()
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs; sphere 46,800 triangles, "
          f"lattice 5x5x5 B-spline; one live update = move a lattice point + depsgraph update; "
          f"load average {_load()}")
    rows = []
    for level in (2, 3):
        ref = sphere(f"stack{level}")
        ref.modifiers.new("Lattice", 'LATTICE').object = lat
        ref.modifiers.new("Subsurf", 'SUBSURF').levels = level
        only_visible(ref)
        bpy.context.view_layer.update()
        ms, split = time_edit(lat, ref, REPEATS)[True, "one"]
        rows.append((f"Lattice + Subsurf level {level}", evaluated_tris(ref), ms, _phase_text(split)))
        bpy.data.objects.remove(ref)

    # 3.4-4.0: viewport mode (normals from the geometry) and exact normals; 4.1+: exact only.
    modes = [False] if compat.HAS_CORNER_NORMALS or NO_EXACT else [False, True]
    for exact in modes:
        for level in (4, 10):
            obj = sphere(f"sffd{level}")
            only_visible(obj)
            mod, first = add_sffd(obj, lat, level, exact)
            timed = time_edit(lat, obj, REPEATS, mod, (True, False) if AB else (True,))
            for (early, _move_kind), (ms, split) in timed.items():
                detail = (f"{_phase_text(split)}; deform {split['deform_ms']:.0f} (core "
                          f"{split['core_ms']:.0f}), mesh write {split['mesh_write_ms']:.0f}, "
                          f"normals {split['normals_ms']:.0f} [{split['normals_path']}]; first "
                          f"update (plan) {first:.0f} ms, device {split['device']}")
                name = f"Smooth FFD level {level}" + (" exact normals" if exact else "") + \
                    ("" if early else " no pre")
                rows.append((name, evaluated_tris(obj), ms, detail))
            smooth_ffd.remove_smooth_ffd(obj, mod)
            bpy.data.objects.remove(obj)
    print(f"load average at the end: {_load()}; "
          f"median of {REPEATS} updates; phases in ms (medians, so they need not add up)")
    print(f"{'':34s} {'triangles':>10s} {'update ms':>10s} {'ns/tri':>7s}")
    for name, tris, ms, detail in rows:
        print(f"{name:34s} {tris:10d} {ms:10.0f} {1e6 * ms / tris:7.0f}   {detail}")
    # The comparison: viewport level 4 vs Subsurf level 2, level 10 vs level 3.
    by_name = {name: (tris, ms) for name, tris, ms, _ in rows}
    for level, sub in ((4, 2), (10, 3)):
        (t1, m1), (t0, m0) = by_name[f"Smooth FFD level {level}"], by_name[f"Lattice + Subsurf level {sub}"]
        print(f"speedup level {level} vs Lattice + Subsurf level {sub}: {m0 / m1:.2f}x in time, "
              f"{(m0 / t0) / (m1 / t1):.2f}x per triangle")
    sys.stdout.flush()


# --- the live-update targets: one table over several workloads -------------------------------------

def stack_rows(workload, mesh, lat, levels, moves=("one",)):
    """Rows of Lattice + Subdivision Surface at each level on a copy of mesh."""
    rows = []
    for level in levels:
        ref = link(bpy.data.objects.new(f"stack{level}", mesh.copy()))
        ref.modifiers.new("Lattice", 'LATTICE').object = lat
        ref.modifiers.new("Subsurf", 'SUBSURF').levels = level
        only_visible(ref)
        bpy.context.view_layer.update()
        evaluated_tris(ref)   # 4.x/5.x subdivide lazily: the first access is not an update
        timed = time_edit(lat, ref, REPEATS, moves=moves)
        tris = evaluated_tris(ref)
        for move in moves:
            ms, split = timed[True, move]
            rows.append(dict(workload=workload, tris_in=mesh_triangles(mesh),
                             name=f"Lattice + Subsurf {level}", kind="stack", level=level,
                             move=move, tris=tris, ms=ms, detail=_phase_text(split)))
        me = ref.data
        bpy.data.objects.remove(ref)
        bpy.data.meshes.remove(me)
    return rows


def sffd_rows(workload, mesh, lat, levels, moves=("one",)):
    """Rows of Smooth FFD (CPU backend, the add-on's default normals) at each viewport level."""
    rows = []
    for level in levels:
        obj = link(bpy.data.objects.new(f"sffd{level}", mesh.copy()))
        only_visible(obj)
        mod, first = add_sffd(obj, lat, level, False, evaluated_tris)
        if not str(smooth_ffd.status(mod)).startswith("OK"):   # a broken core, say: no row
            sys.exit(f"bench_addon.py: Smooth FFD level {level} on {workload}: "
                     f"{smooth_ffd.status(mod)}")
        # 4.5+: background mode computes exact normals on every update; a window's viewport
        # computes positions only while a point is dragged (state.LIVE): both rows.
        for live in ((None, True) if compat.CHEAP_EXACT_NORMALS else (None,)):
            state.LIVE = live
            timed = time_edit(lat, obj, REPEATS, mod, moves=moves)
            state.LIVE = None
            tris = evaluated_tris(obj)
            floor = time_reevaluation(obj, REPEATS)
            for move in moves:
                ms, sp = timed[True, move]
                detail = (f"core deform {sp['core_ms']:.1f} ({sp['patch_share']:.0%} of the patches)"
                          f" / mesh write {sp['mesh_write_ms']:.1f}"
                          f" / normals {sp['normals_ms']:.1f} [{sp['normals_path']}]; "
                          f"{_phase_text(sp)}; Blender alone (nothing new) {floor:.1f}; "
                          f"first update (plan) {first:.0f}")
                rows.append(dict(workload=workload, tris_in=mesh_triangles(mesh),
                                 name=f"Smooth FFD level {level}" + (" live" if live else ""),
                                 kind="sffd", level=level, move=move, tris=tris, ms=ms,
                                 detail=detail))
        smooth_ffd.remove_smooth_ffd(obj, mod)
        me = obj.data
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(me)
    return rows


def _bbox(mesh):
    co = np.empty(3 * len(mesh.vertices))
    mesh.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    return (co.min(0) + co.max(0)) / 2, co.max(0) - co.min(0)


def uniform_errors(obj, lat, levels):
    """{L: e_L}: the largest distance between the uniform level-L triangles and the cubic
    patches of the modifier's inputs (obj's mesh, the evaluated lattice), by dense sampling."""
    sys.path.insert(0, os.path.join(ROOT, "tests"))
    import smoothffd
    import tessellation_error
    from smooth_ffd import core, latticeio, meshio
    from smoothffd import _core
    from smoothffd.deform import _control_values_f32

    dg = bpy.context.evaluated_depsgraph_get()
    rest, pts, interp, _shape, _key, _weights = latticeio.read_lattice(lat, dg)
    l2o = core.lattice_to_object(latticeio.world_matrix(obj, dg), latticeio.world_matrix(lat, dg))
    lattice = smoothffd.BlenderLattice(rest, pts, interpolation=interp, lattice_to_object=l2o)
    d = core.make_deformer(meshio.SourceMesh(obj.data, None, False, []), lattice, 1, "cpu", 1.0, 64)
    cp = _core.adaptive_frame(d.plan, _control_values_f32(d.lattice), 1e30, 1, 0, False, None,
                              True)["patch_control"]
    return {L: tessellation_error.uniform_error(cp, L) for L in levels}


def adaptive_rows(workload, mesh, lat, levels):
    """Smooth FFD at each viewport level beside its Tolerance mode at t = e_L (same accuracy)."""
    rows = sffd_rows(workload, mesh, lat, levels)
    probe = link(bpy.data.objects.new("probe", mesh.copy()))
    only_visible(probe)
    errors = uniform_errors(probe, lat, levels)
    me = probe.data
    bpy.data.objects.remove(probe)
    bpy.data.meshes.remove(me)
    for level in levels:
        obj = link(bpy.data.objects.new(f"adaptive{level}", mesh.copy()))
        only_visible(obj)
        mod, first = add_sffd(obj, lat, level, False)
        for key, value in (("Viewport Tessellation", "Tolerance"), ("Viewport Tolerance", errors[level]),
                           ("Viewport Max Level", 64)):
            compat.set_modifier_input(mod, key, value)
        obj.update_tag()
        bpy.context.view_layer.update()
        if not str(smooth_ffd.status(mod)).startswith("OK"):
            sys.exit(f"bench_addon.py: Smooth FFD tolerance on {workload}: {smooth_ffd.status(mod)}")
        ms, sp = time_edit(lat, obj, REPEATS, mod)[True, "one"]
        rows.append(dict(workload=workload, tris_in=mesh_triangles(mesh),
                         name=f"Smooth FFD tolerance e_{level}", kind="sffd", level=level, move="one",
                         tris=evaluated_tris(obj), ms=ms,
                         detail=(f"t = {errors[level]:.3g}; core deform {sp['core_ms']:.1f} / mesh write "
                                 f"{sp['mesh_write_ms']:.1f} / normals {sp['normals_ms']:.1f}; "
                                 f"{_phase_text(sp)}; status {smooth_ffd.status(mod)}")))
        smooth_ffd.remove_smooth_ffd(obj, mod)
        me = obj.data
        bpy.data.objects.remove(obj)
        bpy.data.meshes.remove(me)
    return rows


def workload_rows(workload):
    clear_objects()
    if workload == "adaptive":
        mesh = suzanne_mesh()
        center, ext = _bbox(mesh)
        lat = lattice(4, tuple(center), tuple(1.05 * ext))
        rows = adaptive_rows(workload, mesh, lat, (2, 3, 4))
    elif workload in ("suzanne", "wrapped"):
        mesh = suzanne_mesh()
        center, ext = _bbox(mesh)
        lat = lattice(4, tuple(center), tuple(1.05 * ext), wrap=workload == "wrapped")
        rows = stack_rows(workload, mesh, lat, (1, 2)) + sffd_rows(workload, mesh, lat, (2, 3, 4))
    elif workload == "sphere4":
        mesh = sphere_mesh("sphere")
        lat = lattice()
        rows = stack_rows(workload, mesh, lat, (2,)) + sffd_rows(workload, mesh, lat, (4,))
    else:   # dense: 199,692 triangles
        mesh = cube_sphere_mesh("dense")
        lat = lattice(8, size=(2.1, 2.1, 2.1), wrap=True)
        moves = ("one", "corner", "all")
        rows = stack_rows(workload, mesh, lat, (1,), moves) + sffd_rows(workload, mesh, lat, (2,), moves)
    bpy.data.meshes.remove(mesh)
    clear_objects()
    return rows


def _find(rows, workload, name, move="one"):
    return next(r for r in rows if r["workload"] == workload and r["name"] == name
                and r["move"] == move)


def _verdict(ok):
    return "met" if ok else "NOT met"


def workload_targets(workloads):
    """The live-update targets (docs/benchmarks.md): rows for each workload, then one line per target."""
    ver = bpy.app.version_string.split()[0]
    print(f"Blender {bpy.app.version_string}, {os.cpu_count()} CPUs, CPU backend; one live update "
          f"= move lattice points + depsgraph update until the evaluated mesh is ready; median of "
          f"{REPEATS}; lattices B-spline; load average {_load()}")
    rows = []
    for w in workloads:
        rows += workload_rows(w)
    print(f"load average at the end: {_load()}; ms are medians (phases too, so they need not add "
          f"up); speedup = the stack's ms / Smooth FFD's ms")
    print(f"{'Blender':8s} {'workload':8s} {'tris in':>8s} {'':24s} {'move':6s} {'tris out':>10s} "
          f"{'update ms':>9s}   split (ms)")
    for r in rows:
        print(f"{ver:8s} {r['workload']:8s} {r['tris_in']:8d} {r['name']:24s} {r['move']:6s} "
              f"{r['tris']:10d} {r['ms']:9.1f}   {r['detail']}")

    def pair(w, a, b, move="one"):
        s, f = _find(rows, w, a, move), _find(rows, w, b, move)
        return s, f, s["ms"] / f["ms"]

    # " live": the 4.5+ viewport while a point is dragged (positions only), beside the exact rows.
    for sfx in [""] + [" live"] * any(r["name"].endswith(" live") for r in rows):
        for w in [w for w in ("suzanne", "wrapped") if w in workloads]:
            s, f, x = pair(w, "Lattice + Subsurf 1", "Smooth FFD level 2" + sfx)
            print(f"target (a) {ver} {w}: Smooth FFD level 2{sfx} ({f['tris']} tris) "
                  f"{f['ms']:.1f} ms vs Lattice + Subsurf 1 ({s['tris']} tris) {s['ms']:.1f} ms: "
                  f"speedup {x:.2f}x; target >= 2x: {_verdict(x >= 2)}")
            for lv, sub in ((3, 1), (3, 2), (4, 2)):
                s, f, x = pair(w, f"Lattice + Subsurf {sub}", f"Smooth FFD level {lv}{sfx}")
                per_tri = (s["ms"] / s["tris"]) / (f["ms"] / f["tris"])
                print(f"  (a) level {lv}{sfx} ({f['tris']} tris) vs Subsurf {sub} ({s['tris']} tris): "
                      f"{x:.2f}x in time, {per_tri:.2f}x per output triangle")
        if "adaptive" in workloads and not sfx:
            for lv in (2, 3, 4):
                u, a = _find(rows, "adaptive", f"Smooth FFD level {lv}"), _find(rows, "adaptive", f"Smooth FFD tolerance e_{lv}")
                print(f"adaptive {ver}: level {lv} ({u['tris']} tris) {u['ms']:.1f} ms vs tolerance e_{lv} "
                      f"({a['tris']} tris, {a['tris'] / u['tris']:.2f}x) {a['ms']:.1f} ms "
                      f"({a['ms'] / u['ms']:.2f}x the time)")
        if "sphere4" in workloads:
            s, f, x = pair("sphere4", "Lattice + Subsurf 2", "Smooth FFD level 4" + sfx)
            ups = 1e3 / f["ms"]
            print(f"target (b) {ver} sphere4: Smooth FFD level 4{sfx} ({f['tris']} tris) {ups:.1f} "
                  f"updates/s ({f['ms']:.1f} ms), Lattice + Subsurf 2 ({s['tris']} tris) "
                  f"{1e3 / s['ms']:.1f}/s: speedup {x:.2f}x; target >= 10 updates/s: "
                  f"{_verdict(ups >= 10)}")
        if "dense" in workloads:
            f1, fc, fa = (_find(rows, "dense", "Smooth FFD level 2" + sfx, m)
                          for m in ("one", "corner", "all"))
            s1, sc, sa = (_find(rows, "dense", "Lattice + Subsurf 1", m)
                          for m in ("one", "corner", "all"))
            print(f"target (c) {ver} dense: Smooth FFD level 2{sfx} ({f1['tris']} tris) middle "
                  f"point {f1['ms']:.1f} ms, point (1,1,1) {fc['ms']:.1f} ms, all points "
                  f"{fa['ms']:.1f} ms (all/middle {fa['ms'] / f1['ms']:.2f}, all/(1,1,1) "
                  f"{fa['ms'] / fc['ms']:.2f}); Lattice + Subsurf 1 ({s1['tris']} tris) middle "
                  f"{s1['ms']:.1f}, (1,1,1) {sc['ms']:.1f}, all {sa['ms']:.1f}; stack / Smooth FFD: "
                  f"middle {s1['ms'] / f1['ms']:.2f}x, (1,1,1) {sc['ms'] / fc['ms']:.2f}x, all "
                  f"{sa['ms'] / fa['ms']:.2f}x (reported; no numeric target)")
    sys.stdout.flush()


def main():
    smooth_ffd.register()
    if "sphere" in WORKLOADS:
        workload_sphere()
    targets = [w for w in WORKLOADS if w != "sphere"]
    if targets:
        workload_targets(targets)

main()
