"""Reads a Blender lattice object into the core's BlenderLattice (reference-facts section 1)."""
import numpy as np

from . import logic


def read_lattice(lattice_obj, depsgraph):
    """(rest (nu,nv,nw,3), points (nu,nv,nw,3), interpolation, shape, key) in lattice space.

    Deformed points come from the *evaluated* lattice, so shape keys, hooks, lattice
    modifiers and animation count, as they do for Blender's Lattice modifier.
    """
    if lattice_obj is None:
        raise logic.SmoothFFDError("no lattice object set")
    if lattice_obj.type != 'LATTICE':
        raise logic.SmoothFFDError(f"{lattice_obj.name!r} is not a lattice object")
    data = lattice_obj.data
    ev = lattice_obj.evaluated_get(depsgraph).data if depsgraph is not None else data
    shape = (data.points_u, data.points_v, data.points_w)
    count = shape[0] * shape[1] * shape[2]
    if len(ev.points) != count:   # evaluated copy lagging behind a resize: use the original
        ev = data
    rest = np.empty(count * 3, dtype=np.float32)
    pts = np.empty(count * 3, dtype=np.float32)
    # co is read-only rest position; never derive it from the ranges (see reference-facts).
    data.points.foreach_get("co", rest)
    ev.points.foreach_get("co_deform", pts)
    interp = logic.interpolation_names((data.interpolation_type_u, data.interpolation_type_v,
                                        data.interpolation_type_w))
    key = logic.digest(rest, pts, interp, shape)
    return logic.lattice_grid(rest, shape), logic.lattice_grid(pts, shape), interp, shape, key


def world_matrix(obj, depsgraph):
    """The evaluated world matrix (animation, constraints, parents) as a (4, 4) float64 array."""
    ob = obj.evaluated_get(depsgraph) if depsgraph is not None else obj
    return np.array(ob.matrix_world, dtype=np.float64)
