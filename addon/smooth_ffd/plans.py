"""The second and third steps of an update: the plan cache (one core Deformer per modifier,
kept while the source mesh, the lattice's structure, the level and the backend stay, and
moved to each new pose of the same faces: follow) and the core's frame on it."""
import bpy
import numpy as np

from . import core, inputs, live, state


def lattice(st, rest, pts, interp, l2o, strength, weights):
    """The BlenderLattice of these inputs. Where only the points (and the weights' values)
    changed since the last one (a point dragged, an animation), that one's with_points: the
    same values without building and checking the structure again on every update."""
    key = (np.asarray(rest).tobytes(), tuple(interp), np.asarray(l2o).tobytes(), strength,
           weights is None)
    if st.lattice[0] == key:
        return st.lattice[1].with_points(pts, weights)
    built = core.smoothffd().BlenderLattice(rest, pts, interpolation=interp,
                                            lattice_to_object=l2o, strength=strength,
                                            point_weights=weights)
    st.lattice = (key, built)
    return built


class _progress:
    """Blender's progress cursor around a long first plan (big mesh, high level)."""

    def __init__(self, long):
        wm = getattr(bpy.context, "window_manager", None)
        self.wm = wm if long and wm is not None and not bpy.app.background else None

    def __enter__(self):
        if self.wm is not None:
            self.wm.progress_begin(0, 1)

    def __exit__(self, *exc):
        if self.wm is not None:
            self.wm.progress_end()


def ensure_plan(st, source, lattice, level, backend, tess=None, hold=False):
    """st.deformer for these inputs: the cached one while its key holds, else one that
    follows the new pose (follow; hold: keeping its pieces, hold_pieces), else a new plan.
    st.plan_key is the plan's key; st.pieces_token names its pieces (the sub-mesh the
    adaptive counts are per: holds.py), kept by follows that hold them. tess
    (tessellation.Tess) adaptive: one adaptive plan on the backend serves every tolerance and
    max level, which are set on it for each frame (the plan does not depend on them: a camera
    moving in Screen mode replans nothing)."""
    adaptive = tess is not None and tess.adaptive
    structure, mode = lattice.structure_key(), "adaptive" if adaptive else level
    plan_key = (source.key, structure, mode, backend)
    if st.deformer is None or st.plan_key != plan_key:
        faces_key = (source.topology_key, inputs.digest(source.material_index),
                     source.uvs is None, source.weights is None, lattice.basis_key(), mode,
                     backend)
        if not follow(st, source, lattice, faces_key, plan_key, adaptive, hold):
            st.deformer = st.result = None
            st.outs = {}
            long = len(source.corner_vertices) * (1 if adaptive else level * level) > 2_000_000
            with _progress(long):
                st.deformer = core.make_deformer(source, lattice, level, backend,
                                                 tess.tolerance if adaptive else None,
                                                 tess.max_level if adaptive else None)
            st.topology_token = st.pieces_token = inputs.digest(plan_key)
            state.plans_built[0] += 1
        st.plan_key, st.faces_key = plan_key, faces_key
    if adaptive:
        st.deformer.tolerance = float(tess.tolerance)
        st.deformer.max_level = int(tess.max_level)


def hold_pieces(st, render, frame):
    """How this update's follow treats the plan's pieces (Deformer.follow's hold,
    docs/algorithm.md, "Holding the pieces"):
    - in the viewport while an animation plays: True, kept while every piece still lies in its
      knot box (playback then writes positions only where they hold; a stopped animation,
      scrubbing and renders clip anew);
    - in a render with motion blur (state.flags.render_shutter, from render_pre): the first
      evaluation in the render's shutter is clipped anew, which is the frame rendered (Cycles
      evaluates it first, and holdframes.hold_shutter does too); every later one, the
      shutter's other times (the subframes its deformation blur is made of) and the frame
      again, keeps those pieces wherever they lie ('always'), so that they all share the
      frame's output topology, and adaptive counts taken over the shutter apply to each;
    - else False.
    st.pieces_for: the render shutter in which the plan's pieces were last clipped (the
    render's serial number is part of it: a new render of the same frame clips anew)."""
    if not render:
        st.pieces_for = None
        return live.playing()
    sh = state.flags.render_shutter
    if sh is None or not sh[0] - 1e-4 <= frame <= sh[1] + 1e-4:
        st.pieces_for = None
        return False
    if st.pieces_for == sh:
        return "always"
    st.pieces_for = sh
    return False


def follow(st, source, lattice, faces_key, plan_key, adaptive, hold=False):
    """Moves st's plan to the new pose of the same faces (an Armature, shape keys, a Wave
    above: only positions, normals, UVs or weights changed) and to where the lattice now lies
    relative to the object (a lattice parented to a bone: the same basis, another placement),
    Deformer.follow, instead of planning again. False where it cannot: no plan yet, other
    faces or materials, another lattice basis (kind, interpolation, resolution, point
    weighting), level or backend, or a UV map or Vertex Group weighting added or removed.
    hold: keep the pieces (hold_pieces); st.pieces_note says so on a render's subframe.

    Where the core keeps the output topology (no face crosses the lattice's knot planes
    differently, no normal splits or joins) st.topology_token and st.output stay: the result
    mesh keeps its triangles, carried UV maps and vertex groups, and the write is positions,
    normals and rest positions only (write.write_result; UV maps and groups again only where
    they changed). Otherwise the token is new: the output is compared again (pipeline) and
    the mesh rebuilt where it differs, as after a new plan. An adaptive plan's output topology
    comes with each frame: its token is new with every pose (not counted as kept)."""
    if st.deformer is None or st.faces_key != faces_key:
        return False
    try:
        kept = st.deformer.follow(core.make_mesh(source), lattice=lattice, hold=hold)
    except ValueError:   # faces the core reads as other ones, positions out of range
        return False
    except Exception:
        st.deformer = st.plan_key = st.faces_key = None   # never half a pose
        raise
    state.plans_followed[0] += 1
    if hold:
        state.plans_followed_held[0] += st.deformer.plan.pieces_held
        sh = state.flags.render_shutter
        if hold == "always" and sh is not None:
            st.pieces_note = f"pieces held over the shutter {sh[0]:g}-{sh[1]:g}"
    if not (hold and st.deformer.plan.pieces_held):
        st.pieces_token = inputs.digest(plan_key)
    old = st.plan_key
    if kept and not adaptive:
        state.plans_followed_kept[0] += 1
        if st.output[0] is old:   # the output digest of the kept topology
            st.output = (plan_key, st.output[1])
    else:
        st.result = None
        st.outs = {}
        st.topology_token = inputs.digest(plan_key)
    return True


def is_adaptive(st):
    return st.deformer is not None and getattr(st.deformer, "tolerance", None) is not None


def frame(st, lattice, exact, hold=None):
    """The core's frame on st's plan: positions, and the normals where exact.

    out=: overwrite the previous update's arrays in place (no fresh pages each edit);
    incremental: recompute only what the lattice points that moved since reach (the previous
    update's arrays are read only here and by the writes). Without exact normals (3.4-4.4
    viewport: Blender shades the dense mesh from its own geometry, write.write_result) the
    core computes positions only: the same positions in well under half the time
    (res.normals is None then).

    Adaptive plans (ensure_plan) run a whole adaptive frame each time (a new topology may
    come out), in the corner layout, with the counts `hold` where given (holds.py)."""
    if is_adaptive(st):
        res = st.result = st.deformer.deform(lattice, normals=exact, layout="corners",
                                             hold=hold)
        state.deform_calls["normals" if exact else "positions_only"] += 1
        return res
    chosen = state.LAYOUT or layout(st.deformer)
    res = st.result = st.outs[chosen] = st.deformer.deform(
        lattice, out=st.outs.get(chosen), normals=exact, layout=chosen, incremental=True)
    state.deform_calls["normals" if exact else "positions_only"] += 1
    return res


def layout(deformer):
    """The cheapest layout for this plan's normals. Where no normal splits, "compact": one
    normal per render vertex = per output vertex, which Blender takes as per-vertex custom
    normals (meshio.write_normals), a third to a sixth of the per-corner values. Where normals
    split (the core's splits_normals), Blender needs one normal a corner, and the core's
    "corners" layout writes them directly, cheaper than gathering the compact normals through
    render_triangles in numpy (blender_scenes/bench_layout.py: at level 10, 89 against 184 ms
    on bpy 5.0)."""
    return "corners" if deformer.splits_normals else "compact"


def counts(st, lattice):
    """The adaptive counts of this lattice's frame on st's plan, without its mesh."""
    return st.deformer.tessellation_counts(lattice)


def fit_errors(st):
    """Per input face, the bound on the distance between its fitted patches and the exact FFD
    of the face (object units), for the lattice of st's last frame (Deformer.estimate_errors:
    about one more CPU frame)."""
    face_error, _normal = st.deformer.estimate_errors()
    return face_error
