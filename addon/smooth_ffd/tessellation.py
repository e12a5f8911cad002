"""How finely an update tessellates: a fixed level, or adaptively to a tolerance (the core's
Deformer(tolerance=..., max_level=...) on the Backend's device), for the viewport and the render separately
(the group's tessellation inputs, nodegroup.TESS_INPUTS). The render's Screen mode turns a
pixel size into an object-space tolerance on every update, from the scene's render camera:
the world size of one pixel at the depth of the object's nearest point (its source's and its
lattice's bounding box), from the render resolution and the camera's lens and sensor (or its
orthographic scale), divided by the object's largest scale."""
import numpy as np

from . import compat, core, inputs, nodegroup


class Tess:
    """One update's tessellation: mode 'level' (tolerance None) or adaptive ('tolerance',
    'screen'): tolerance (object units), max_level; setting: what the user chose (the
    counts held over frames are keyed by it, not by the tolerance a camera gives); note: a
    remark for the status (no camera)."""

    def __init__(self, mode, tolerance=None, max_level=None, setting=None, note=None,
                 pixel=None):
        self.mode = mode
        self.tolerance = tolerance
        self.max_level = max_level
        self.setting = setting
        self.note = note
        self.pixel = pixel   # Screen: the world size of one pixel at the object

    @property
    def adaptive(self):
        return self.tolerance is not None

    def key(self):
        return (self.mode, self.tolerance, self.max_level)


def _get(mod, name, default):
    try:
        return compat.get_modifier_input(mod, name)
    except KeyError:   # a group of an older layout, not migrated yet: the default
        return default


def read(mod, render):
    """(mode, tolerance setting, max level, pixel size) of the viewport's or the render's
    settings; mode 'level' where the group has no such inputs."""
    which = "Render" if render else "Viewport"
    try:
        mode = nodegroup.parse_mode(f"{which} Tessellation",
                                    _get(mod, f"{which} Tessellation", "level"))
    except ValueError as e:
        raise inputs.SmoothFFDError(str(e)) from None
    tolerance = float(_get(mod, f"{which} Tolerance", 0.001))
    max_level = int(_get(mod, f"{which} Max Level", 16))
    pixel = float(_get(mod, "Render Pixel Size", 1.0)) if render else None
    return mode, tolerance, max_level, pixel


def tess(mod, render, obj=None, scene=None, depsgraph=None, box=None):
    """The Tess of an update. box: (8+, 3) points in the object's space bounding what the
    result can cover (Screen mode; None: the plain tolerance)."""
    mode, tolerance, max_level, pixel = read(mod, render)
    if mode == "level":
        return Tess("level")
    if not np.isfinite(tolerance) or tolerance <= 0:
        raise inputs.SmoothFFDError(f"tolerance must be a positive distance, not {tolerance:g}")
    max_level = core.parse_level(max_level, "max level")
    setting = (mode, tolerance, max_level, pixel if mode == "screen" else None)
    if mode == "tolerance":
        return Tess(mode, tolerance, max_level, setting)
    if not np.isfinite(pixel) or pixel <= 0:
        raise inputs.SmoothFFDError(f"pixel size must be positive, not {pixel:g}")
    world = pixel_size(scene, obj, depsgraph, box)
    if world is None:
        return Tess(mode, tolerance, max_level, setting,
                    note=f"no render camera: tolerance {tolerance:g} used")
    scale = object_scale(obj, depsgraph)
    t = pixel * world / scale
    if not np.isfinite(t) or t <= 0:
        return Tess(mode, tolerance, max_level, setting,
                    note=f"camera at the object: tolerance {tolerance:g} used")
    return Tess(mode, float(t), max_level, setting, pixel=world)


def object_scale(obj, depsgraph):
    """The object's largest world scale (an object-space distance times it is at most the
    world distance)."""
    m = _matrix(obj, depsgraph)[:3, :3]
    return float(np.linalg.norm(m, axis=0).max())


def _matrix(ob, depsgraph):
    ev = ob.evaluated_get(depsgraph) if depsgraph is not None else ob
    return np.array(ev.matrix_world, dtype=np.float64)


def pixel_size(scene, obj, depsgraph, box):
    """World size of one render pixel at the depth of box's nearest point (box: points in
    obj's space) seen from the scene's camera; None without a camera (or one that is not a
    camera)."""
    cam = getattr(scene, "camera", None) if scene is not None else None
    if cam is None or cam.type != 'CAMERA' or box is None:
        return None
    r = scene.render
    pct = r.resolution_percentage / 100.0
    rx = max(1.0, r.resolution_x * pct * r.pixel_aspect_x)
    ry = max(1.0, r.resolution_y * pct * r.pixel_aspect_y)
    data = cam.evaluated_get(depsgraph).data if depsgraph is not None else cam.data
    fit = data.sensor_fit
    if fit == 'AUTO':
        pixels, sensor = max(rx, ry), data.sensor_width
    elif fit == 'HORIZONTAL':
        pixels, sensor = rx, data.sensor_width
    else:
        pixels, sensor = ry, data.sensor_height
    if data.type == 'ORTHO':
        return data.ortho_scale / pixels
    world = _matrix(obj, depsgraph)
    pts = np.c_[np.asarray(box, np.float64), np.ones(len(box))] @ world.T
    view = np.linalg.inv(_matrix(cam, depsgraph))
    depth = -(pts @ view.T)[:, 2]
    nearest = max(float(depth.min()), float(data.clip_start))
    if data.type == 'PANO':
        return None
    return nearest * sensor / data.lens / pixels


def bounding_box(positions, lattice_points, l2o):
    """The corners of the box around the source's positions and the lattice's points (in the
    object's space): the result lies within it."""
    pts = np.asarray(lattice_points, np.float64).reshape(-1, 3)
    pts = pts @ np.asarray(l2o)[:3, :3].T + np.asarray(l2o)[:3, 3]
    allp = np.concatenate([np.asarray(positions, np.float64).reshape(-1, 3), pts])
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                     for z in (lo[2], hi[2])])
