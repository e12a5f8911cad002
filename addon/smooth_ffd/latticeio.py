"""Reads a Blender lattice object into the core's BlenderLattice (docs/algorithm.md, "Blender's Lattice modifier, exactly")."""
import numpy as np

from . import inputs, state


def read_lattice(lattice_obj, depsgraph):
    """(rest (nu,nv,nw,3), points (nu,nv,nw,3), interpolation, shape, key, weights) in
    lattice space; weights: the lattice's vertex group (lattice_weights), or None.

    Deformed points come from the *evaluated* lattice, so shape keys, hooks, lattice
    modifiers and animation count, as they do for Blender's Lattice modifier.
    """
    if lattice_obj is None:
        raise inputs.SmoothFFDError("no lattice object set")
    if lattice_obj.type != 'LATTICE':
        raise inputs.SmoothFFDError(f"{lattice_obj.name!r} is not a lattice object")
    data = lattice_obj.data
    ev = lattice_obj.evaluated_get(depsgraph).data if depsgraph is not None else data
    shape = (data.points_u, data.points_v, data.points_w)
    count = shape[0] * shape[1] * shape[2]
    if len(ev.points) != count:   # evaluated copy lagging behind a resize: use the original
        ev = data
    pts = np.empty(count * 3, dtype=np.float32)
    ev.points.foreach_get("co_deform", pts)
    rest = _rest_points(data, shape)
    # Blender's names ('KEY_BSPLINE', ...), which BlenderLattice takes as they are.
    interp = (data.interpolation_type_u, data.interpolation_type_v, data.interpolation_type_w)
    weights = lattice_weights(lattice_obj, count)
    key = inputs.digest(rest, pts, interp, shape, weights)
    grid = None if weights is None else inputs.lattice_weight_grid(weights, shape)
    return (inputs.lattice_grid(rest, shape), inputs.lattice_grid(pts, shape), interp, shape, key,
            grid)


def lattice_weights(lattice_obj, count):
    """The lattice's vertex group (Lattice.vertex_group), which Blender's Lattice modifier
    blends each vertex by (docs/algorithm.md): (count,) float64 weights in Blender's point
    order, 0 for a point not in the group; None where the modifier ignores it: no group
    named, no group of that name, or no point in any group (Blender then has no weight layer,
    lt->dvert is null, and deforms fully; a layer emptied again by hand reads the same here).

    Read from the original lattice: evaluation changes no weights. In edit mode the weights
    being edited live in the edit lattice, which LatticePoint.groups does not read (it takes
    its index from the edit lattice's points into the object-mode layer); VertexGroup.weight
    does (and raises for a point not in the group)."""
    data = lattice_obj.data
    name = data.vertex_group
    group = lattice_obj.vertex_groups.get(name) if name else None
    if group is None:
        return None
    w = np.zeros(count, dtype=np.float64)
    if data.is_editmode:
        member = False
        for i in range(count):
            try:
                w[i] = group.weight(i)
                member = True
            except RuntimeError:   # not in the group
                pass
        if not member:   # is there a weight layer at all? any point in any other group
            member = any(_edit_member(g, count) for g in lattice_obj.vertex_groups if g != group)
        return w if member else None
    index, member = group.index, False
    for i, p in enumerate(data.points):
        for g in p.groups:
            member = True
            if g.group == index:
                w[i] = g.weight
    return w if member else None


def _edit_member(group, count):
    for i in range(count):
        try:
            group.weight(i)
            return True
        except RuntimeError:
            pass
    return False


def _rest_points(data, shape):
    """LatticePoint.co, the rest positions (never derived from the ranges: old or resized
    lattices differ: docs/algorithm.md, "Blender's Lattice modifier, exactly"). In edit mode co is garbage (the edit lattice has
    no rest layout), so the last object-mode reading is used, else Blender's default."""
    count = shape[0] * shape[1] * shape[2]
    if not data.is_editmode:
        rest = np.empty(count * 3, dtype=np.float32)
        data.points.foreach_get("co", rest)
        state.lattice_rest[data.name_full] = (shape, rest)
        return rest
    cached = state.lattice_rest.get(data.name_full)
    if cached is not None and cached[0] == shape:
        return cached[1]
    axes = [np.linspace(-0.5, 0.5, n) if n > 1 else np.zeros(1) for n in shape]
    w, v, u = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")   # u fastest
    return np.stack([u, v, w], axis=-1).astype(np.float32).ravel()


def world_matrix(obj, depsgraph):
    """The evaluated world matrix (animation, constraints, parents) as a (4, 4) float64 array."""
    ob = obj.evaluated_get(depsgraph) if depsgraph is not None else obj
    return np.array(ob.matrix_world, dtype=np.float64)


# --- reading before evaluation (depsgraph_update_pre) --------------------------------------

def animated(id_data):
    """Whether animation or drivers may change id_data's properties on evaluation."""
    ad = getattr(id_data, "animation_data", None)
    return ad is not None and (ad.action is not None or len(ad.drivers) > 0
                               or len(ad.nla_tracks) > 0)


def evaluates_to_original(lattice_obj):
    """Whether the evaluated lattice points are the original ones (read_lattice(obj, None)):
    no lattice modifiers (hooks), shape keys or animated points."""
    data = lattice_obj.data
    return (len(lattice_obj.modifiers) == 0 and data.shape_keys is None
            and not animated(data))


def basis_matrix(obj):
    """The world matrix the depsgraph will compute, from the original object, when it is
    just the object's own loc/rot/scale (Blender computes both with the same function, so
    they are bitwise equal); None when a parent, constraint, animation or rigid body may
    change it."""
    if obj.parent is not None or len(obj.constraints) > 0 or animated(obj) \
            or getattr(obj, "rigid_body", None) is not None:
        return None
    return np.array(obj.matrix_basis, dtype=np.float64)
