"""The last step of an update: the core's result written into the hidden result mesh (or,
positions only before 3.6, into the Result Points), with the UV maps and vertex groups
carried onto it and the normals Blender shows."""
import time

from . import carry, compat, inputs, meshio, objects, state


def result_matches(mesh, st):
    """False when something else (undo, the user) changed the result mesh behind our back."""
    if not st.plan_key:
        return mesh.get(state.TOPOLOGY_KEY) is None
    return mesh.get(state.TOPOLOGY_KEY) == st.topology_token and \
        mesh.get(state.POSE_KEY) == inputs.digest(st.plan_key)


def _materials(obj):
    return [slot.material for slot in obj.material_slots] if obj.material_slots else \
        list(obj.data.materials)


def write_result(obj, mod, ro, res, source, topology_token, exact, st, groups=True, fit_error=None):
    """Writes res into the result mesh; returns timings (ms) and the normals path used.
    topology_token: st.topology_token, the output topology of st's plan (it stays while the
    plan follows new poses of the source keeping that topology, plans.follow): where the mesh
    holds it, the triangles, the UV maps carried from other layers and the vertex groups stay
    and only values are written (positions, normals, render UVs, and the rest positions when
    the pose changed). groups: carry the vertex groups (else the result has none). fit_error:
    per input face (plans.fit_errors), written as the result's face attribute; None removes
    it."""
    mesh = ro.data
    t0 = time.perf_counter()
    pose = inputs.digest(st.plan_key)
    mode = "exact" if exact else "fast"
    same = (mesh.get(state.OUTPUT_KEY) == st.output[1] and mesh.get(state.TOPOLOGY_KEY) is not None
            and len(mesh.vertices) == len(res.positions)
            and len(mesh.polygons) == len(res.triangles))
    # Going back from exact to fast needs the custom normals gone: on 3.4-4.4 a rebuild, on
    # 4.5+ the attribute removed (below).
    rebuild = not same or (mesh.get(state.NORMALS_KEY) == "exact" and mode == "fast"
                           and not compat.HAS_FREE_NORMAL_ATTRIBUTE)
    extras_token = inputs.digest(topology_token, source.extras_key, groups)
    if not rebuild and mode == "fast" and mesh.get(state.NORMALS_KEY) == "fast" \
            and mesh.get(state.TOPOLOGY_KEY) == topology_token \
            and mesh.get(state.EXTRAS_KEY) == extras_token and objects.sends_points(mod) \
            and mesh.get(state.SHARP_KEY) == st.sharp \
            and ro.users == 1 and meshio.FIT_ERROR_ATTRIBUTE not in mesh.attributes:
        # Only the positions change: before 3.6 a write to the result mesh makes the
        # depsgraph copy all of it again, the points object is vertices only (nodegroup).
        # The result mesh gets them too, untagged: it stays the result for everyone who
        # reads it (stack_input, bake, Apply) and in the saved file. Its evaluated copy keeps
        # the old positions, so only while nothing but this modifier evaluates it (users:
        # a Smooth FFD below has it as its Stack Object, stack_input).
        meshio.write_positions(mesh, res)
        if mesh.get(state.POSE_KEY) != pose:   # the plan followed a new pose of the source
            meshio.write_rest_positions(mesh, res)
            mesh[state.POSE_KEY] = pose
        state.mesh_writes["values"] += 1
        po = objects.points_object(obj, mod, ro)
        meshio.write_vertices(po.data, res.positions)
        objects.set_points(obj, mod, po)
        t1 = time.perf_counter()
        return {"normals": "from geometry", "rebuilt": False, "mesh_write_ms": 1e3 * (t1 - t0),
                "carry_ms": 0.0, "carry_add_calls": 0, "normals_ms": 0.0, "tag_ms": 0.0,
                "points": True}
    if rebuild:
        meshio.write_topology(mesh, res, source, _materials(obj))
        mesh[state.OUTPUT_KEY] = st.output[1]
        mesh[state.SHARP_KEY] = st.sharp
        state.mesh_writes["topology"] += 1
    else:
        meshio.write_positions(mesh, res)
        if mesh.get(state.SHARP_KEY) != st.sharp:   # the same triangles, other sharp edges
            meshio.write_sharp_edges(mesh, res)
            mesh[state.SHARP_KEY] = st.sharp
            state.mesh_writes["sharp"] += 1
        if mesh.get(state.TOPOLOGY_KEY) != topology_token or mesh.get(state.POSE_KEY) != pose:
            # Another plan or pose with the same output: the points on the input moved with it.
            meshio.write_rest_positions(mesh, res)
        state.mesh_writes["values"] += 1
    mesh[state.TOPOLOGY_KEY] = topology_token
    mesh[state.POSE_KEY] = pose
    # UV maps and vertex groups: with a new topology, or when only they changed.
    carry_ms, carry_calls = 0.0, 0
    if rebuild or mesh.get(state.EXTRAS_KEY) != extras_token:
        tc = time.perf_counter()
        plan = st.deformer.plan   # where the output lies on the input (docs/api.md)
        if getattr(st.deformer, "tolerance", None) is not None:
            # An adaptive result's topology is not the plan's: found from its rest positions.
            plan = carry.AdaptiveSources(res, plan, source)
        carry.write_uv_layers(mesh, res, source, plan)
        if groups:
            carry_calls = carry.write_vertex_groups(ro, source, plan)
        elif len(ro.vertex_groups):
            ro.vertex_groups.clear()
        mesh[state.EXTRAS_KEY] = extras_token
        carry_ms = 1e3 * (time.perf_counter() - tc)
    t1 = time.perf_counter()
    if exact:
        if st.scratch[0] != topology_token:
            st.scratch = (topology_token, {"splits": st.deformer.splits_normals})
        path = meshio.write_normals(mesh, res, st.scratch[1])
    else:
        # 3.4-4.4 viewport, live editing on 4.5+: Blender's own normals of the dense mesh.
        compat.remove_custom_normals(mesh)
        path = "from geometry"
    mesh[state.NORMALS_KEY] = mode
    meshio.write_fit_error(mesh, res, fit_error)
    t2 = time.perf_counter()
    mesh.update()
    objects.empty_points(obj, mod, ro)
    t3 = time.perf_counter()
    return {"normals": path, "rebuilt": rebuild, "mesh_write_ms": 1e3 * (t1 - t0),
            "carry_ms": carry_ms, "carry_add_calls": carry_calls,
            "normals_ms": 1e3 * (t2 - t1), "tag_ms": 1e3 * (t3 - t2), "points": False}
