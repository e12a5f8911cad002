"""Mesh data in and out of Blender through numpy (foreach_get/foreach_set with matching
dtypes, which Blender copies as raw memory instead of item by item)."""
import numpy as np

from . import compat, inputs, result_arrays


class SourceMesh:
    """The numpy snapshot of a source mesh that the core needs, plus a fingerprint."""

    def __init__(self, mesh, group_index=None, invert=False, group_names=()):
        nv, nl, nf = len(mesh.vertices), len(mesh.loops), len(mesh.polygons)
        if nf == 0:
            raise inputs.SmoothFFDError("the mesh has no faces")
        self.positions = compat.get_positions(mesh)
        self.corner_vertices = compat.get_corner_verts(mesh)
        starts = _get(mesh.polygons, "loop_start", np.int32, nf)
        self.face_offsets = np.append(starts, np.int32(nl)).astype(np.int32)
        if np.any(np.diff(self.face_offsets) < 3):
            raise inputs.SmoothFFDError("the mesh has faces with fewer than 3 corners")
        self.material_index = compat.get_material_index(mesh)
        self.corner_normals = compat.read_corner_normals(mesh)
        uv_layer = _active_uv(mesh)
        self.uv_name = uv_layer.name if uv_layer is not None else None
        self.uvs = compat.get_uvs(mesh, uv_layer) if uv_layer is not None else None
        # Every UV map, in order, for the result: [(name, (C, 2) uvs)]; the core interpolates
        # the render one (self.uvs), the add-on the others (carry.py).
        self.uv_layers = [(layer.name, self.uvs if layer.name == self.uv_name
                           else compat.get_uvs(mesh, layer)) for layer in mesh.uv_layers]
        active = mesh.uv_layers.active
        self.uv_active = active.name if active is not None else None
        self.uv_render = self.uv_name
        # Vertex groups (names in the object's order), read only when the object has some.
        self.group_names = list(group_names)
        dvert = _deform_vertices(mesh) if (self.group_names or group_index is not None) \
            else None
        self.groups = _groups(nv, len(self.group_names), dvert)
        self.weights = None if group_index is None else \
            inputs.vertex_weights(nv, group_index, *dvert, invert)
        # Topology decides whether a cached plan can be reused; the rest only its inputs.
        self.topology_key = inputs.digest(self.corner_vertices, self.face_offsets, nv)
        self._set_key()
        # What the add-on carries besides the core's output (changes need no new plan).
        self.extras_key = inputs.digest(
            repr([n for n, _ in self.uv_layers]), self.uv_active, self.uv_render,
            *[uv for _, uv in self.uv_layers], repr(self.group_names),
            *[a for g in self.groups for a in g])

    def _set_key(self):
        self.key = inputs.digest(self.topology_key, self.positions, self.corner_normals,
                                self.uvs, self.weights, self.material_index)

    def keep_normals_of(self, old, tol=1e-6):
        """Takes old's corner normals when this read differs from it only by rounding.

        Blender 3.4 recomputes split normals of an unchanged mesh with differences of about
        2e-7 (measured on a 46.8k-triangle sphere), which changed the key and so rebuilt the
        plan on every re-read (a weight edit, a material change)."""
        if old is None or old.topology_key != self.topology_key or \
                not np.array_equal(old.positions, self.positions) or \
                self.corner_normals.shape != old.corner_normals.shape:
            return
        if self.corner_normals is not old.corner_normals and \
                np.abs(self.corner_normals - old.corner_normals).max(initial=0.0) <= tol:
            self.corner_normals = old.corner_normals
            self._set_key()

    @property
    def num_vertices(self):
        return len(self.positions)


def _get(collection, prop, dtype, count):
    out = np.empty(count, dtype=dtype)
    collection.foreach_get(prop, out)
    return out


def _active_uv(mesh):
    layers = mesh.uv_layers
    if len(layers) == 0:
        return None
    for layer in layers:
        if layer.active_render:   # what render and export use
            return layer
    return layers.active


def _deform_vertices(mesh):
    """Flat (vertex, group, weight) triples of the mesh's deform-vertex layer."""
    # No bulk (foreach) access exists for deform weights: a Python loop, run only when the
    # mesh itself changed and the object has vertex groups.
    idx, grp, wts = [], [], []
    for v in mesh.vertices:
        for g in v.groups:
            idx.append(v.index)
            grp.append(g.group)
            wts.append(g.weight)
    return (np.asarray(idx, np.int64), np.asarray(grp, np.int64), np.asarray(wts, np.float32))


def _groups(num_vertices, num_groups, dvert):
    """Per group: (member (V,) bool, weight (V,) float32) as stored (not clamped)."""
    out = []
    for g in range(num_groups):
        member = np.zeros(num_vertices, dtype=bool)
        weight = np.zeros(num_vertices, dtype=np.float32)
        sel = dvert[1] == g
        member[dvert[0][sel]] = True
        weight[dvert[0][sel]] = dvert[2][sel]
        out.append((member, weight))
    return out


SOURCE_FACE_ATTRIBUTE = "smooth_ffd_source_face"
REST_ATTRIBUTE = "smooth_ffd_rest_position"
FIT_ERROR_ATTRIBUTE = "smooth_ffd_fit_error"


# --- result mesh ------------------------------------------------------------------------------

def write_topology(mesh, res, source, materials):
    """Rebuilds the result mesh from a core Result (new plan or first update)."""
    mesh.clear_geometry()
    # Materials first: clearing a mesh's material slots resets its faces' material indices.
    mesh.materials.clear()
    for mat in materials:
        mesh.materials.append(mat)
    n, t = len(res.positions), len(res.triangles)
    loops, starts, totals = result_arrays.triangle_loops(res.triangles)
    mesh.vertices.add(n)
    mesh.loops.add(3 * t)
    mesh.polygons.add(t)
    compat.set_positions(mesh, res.positions)
    compat.set_corner_verts(mesh, loops)
    compat.set_loop_starts(mesh, starts, totals)
    face_index = np.asarray(res.face_index, dtype=np.int64)
    if source.material_index.any():   # the cleared mesh's new faces have index 0
        compat.set_material_index(mesh, source.material_index[face_index])
    mesh.update(calc_edges=True)
    # Which source face each output triangle came from: for tools, tests and debugging.
    attr = mesh.attributes.new(SOURCE_FACE_ATTRIBUTE, 'INT', 'FACE')
    attr.data.foreach_set("value", np.ascontiguousarray(res.face_index, np.int32))
    # Where each output vertex sits on the undeformed input (a rest-pose texture space).
    mesh.attributes.new(REST_ATTRIBUTE, 'FLOAT_VECTOR', 'POINT')
    write_rest_positions(mesh, res)
    # UV maps and vertex groups: carry.py, after this.
    compat.set_all_faces_smooth(mesh)
    write_sharp_edges(mesh, res, cleared=True)


def write_sharp_edges(mesh, res, cleared=False):
    """Marks the result's sharp edges on the mesh's edges (the mesh holds res's triangles).
    cleared: its edges are new and all smooth (write_topology)."""
    n = len(res.positions)
    sharp = res.sharp_edges is not None and len(res.sharp_edges) > 0
    if sharp or not cleared:   # a new mesh without sharp edges has nothing to mark
        flags = result_arrays.edge_flags(compat.get_edges(mesh), res.sharp_edges, n)
        compat.set_sharp_edges(mesh, flags)
        sharp = bool(flags.any())
    # 3.4-4.0: auto smooth makes Blender compute split normals for the whole dense mesh on
    # every evaluation; only needed with sharp edges (custom normals turn it on themselves).
    compat.enable_split_normals(mesh, sharp)


def write_fit_error(mesh, res, face_error):
    """The smooth_ffd_fit_error face attribute: each result triangle's bound on the distance
    from the exact FFD of its input face (that face's, Deformer.estimate_errors), for viewing
    (spreadsheet, an Attribute node). face_error None (this update did not estimate it):
    removed, so that no value of other control points stays."""
    attr = mesh.attributes.get(FIT_ERROR_ATTRIBUTE)
    if attr is not None and (face_error is None or attr.domain != 'FACE' or attr.data_type != 'FLOAT'):
        mesh.attributes.remove(attr)
        attr = None
    if face_error is None:
        return
    if attr is None:
        attr = mesh.attributes.new(FIT_ERROR_ATTRIBUTE, 'FLOAT', 'FACE')
    attr.data.foreach_set("value", np.ascontiguousarray(np.asarray(face_error)[res.face_index], np.float32))


def write_rest_positions(mesh, res):
    """The smooth_ffd_rest_position attribute (another plan of the same output topology)."""
    mesh.attributes[REST_ATTRIBUTE].data.foreach_set(
        "vector", np.ascontiguousarray(res.rest_positions, np.float32).ravel())


def write_positions(mesh, res):
    """Same plan as last time: only the coordinates change (topology, UVs, flags are kept)."""
    compat.set_positions(mesh, res.positions)


def write_vertices(mesh, positions):
    """Makes a mesh of vertices only hold `positions` (resized when their number changed)."""
    if len(mesh.vertices) != len(positions):
        mesh.clear_geometry()
        mesh.vertices.add(len(positions))
    compat.set_positions(mesh, positions)
    mesh.update()


def is_compact(res):
    """Whether res is the core's compact layout (normals once per render vertex)."""
    return hasattr(res, "render_triangles")


def write_normals(mesh, res, scratch):
    """Exact custom normals from a core result, the cheapest way this Blender takes them;
    returns the path used. scratch: a dict the caller keeps while the plan lasts (per-plan
    facts and buffers).

    Compact layout (the add-on's): where no normal splits (no render vertex repeats an output
    vertex) one normal a vertex: on 4.5+ the point-domain `custom_normal` attribute, on
    3.4-4.4 normals_split_custom_set_from_vertices; else one a corner, gathered through
    render_triangles (one row per corner, written into a buffer kept in scratch).

    Corner layout (where normals split, plans.layout): a normal per corner from the
    core, written as it is; on 4.5+, where nothing splits after all (LAYOUT forced), one
    corner's normal a vertex (point domain). scratch["splits"]: whether the plan has more
    render vertices than output vertices."""
    if is_compact(res):
        if "per_vertex" not in scratch:   # once per plan
            rv = np.asarray(res.render_vertex)
            n = len(res.positions)
            identity = len(rv) == n and np.array_equal(rv, np.arange(n, dtype=rv.dtype))
            scratch["per_vertex"] = identity or \
                int(np.bincount(rv, minlength=n).max(initial=0)) <= 1
            scratch["identity"] = identity
        if scratch["per_vertex"]:
            normals = res.normals
            if not scratch["identity"]:   # loose input vertices: no render vertex, no normal
                normals = np.zeros((len(res.positions), 3), np.float32)
                normals[res.render_vertex] = res.normals
            return compat.write_vertex_normals(mesh, normals)
        if "gather" not in scratch:       # once per plan: np.take is fastest with intp
            idx = np.asarray(res.render_triangles).reshape(-1).astype(np.intp)
            scratch["gather"] = (idx, np.empty((len(idx), 3), np.float32))
        idx, buf = scratch["gather"]
        np.take(res.normals, idx, axis=0, out=buf)
        return compat.write_custom_normals(mesh, buf)
    corner_normals = np.asarray(res.corner_normals).reshape(-1, 3)
    if "vertex_corner" not in scratch:
        scratch["vertex_corner"] = None if scratch.get("splits", True) else _vertex_corners(res)
    if scratch["vertex_corner"] is not None:
        return compat.write_custom_normals(mesh, corner_normals[scratch["vertex_corner"]],
                                           'POINT')
    return compat.write_custom_normals(mesh, corner_normals)


def _vertex_corners(res):
    """Corner layout: one corner of each output vertex when the result has no sharp edges and
    Blender takes point-domain custom normals (4.5+); else None."""
    if not compat.HAS_FREE_NORMAL_ATTRIBUTE or len(res.sharp_edges):
        return None
    tri = np.asarray(res.triangles).ravel()
    corner = np.zeros(len(res.positions), dtype=np.int64)  # loose vertices: any normal
    corner[tri] = np.arange(tri.size)
    return corner
