"""A plan that follows the pose (Deformer.follow; native follow_plan, docs/algorithm.md "A plan
that follows the pose"): a mesh of the same faces in a new pose moves the plan instead of
planning it again.

* After every pose of a bend animation (a bone's smooth-skinned bend of a real mesh, its corner
  normals turned with it), the result is bitwise that of a plan built for the pose with
  build_plan(like=the plan before it), evaluated on its own evaluator;
* the deformed input vertices are the exact FFD of the posed vertices (the independent numpy
  B-spline volume of tests/reference.py) within float rounding, as a freshly planned Deformer's
  are, whatever triangulation that one chose;
* the first plan's triangles stay; a small pose change keeps the output topology (the very
  same triangle arrays), a vertex crossing a knot plane does not;
* a mesh with other faces is refused and the Deformer keeps working;
* on CUDA, the followed frames equal the CPU's within float rounding.
"""

import numpy as np
import pytest

import agreement
import smoothffd
from smoothffd import _core
from smoothffd.deform import _control_values_f32

import test_real_meshes as real

LEVEL = 3


def bend(mesh, angle):
    """The mesh bent about the y axis through its centre, as a two-bone Armature with smooth
    weights bends it: vertices past the centre in x turn by up to `angle` (radians), blended over
    the middle fifth of the mesh's width; each corner normal turns with its vertex."""
    P = mesh.positions
    c = 0.5 * (P.min(axis=0) + P.max(axis=0))
    t = np.clip((P[:, 0] - c[0]) / (0.2 * float(np.ptp(P[:, 0]))) + 0.5, 0.0, 1.0)
    a = angle * t * t * (3 - 2 * t)

    def turn(v, a, about):
        x, z = v[:, 0] - about[0], v[:, 2] - about[2]
        return np.stack([np.cos(a) * x + np.sin(a) * z + about[0], v[:, 1],
                         -np.sin(a) * x + np.cos(a) * z + about[2]], axis=1)

    normals = None
    if mesh.corner_normals is not None:
        normals = turn(mesh.corner_normals.astype(np.float64), a[mesh.corner_vertices], np.zeros(3))
    return smoothffd.Mesh(turn(P, a, c), (mesh.corner_vertices, mesh.face_offsets),
                          corner_normals=normals, uvs=mesh.uvs)


def _evaluate(plan, values):
    ev = _core.CpuEvaluator(plan, 0)
    positions, normals, _ = ev.evaluate(values)
    return positions, normals


def _plan_like(mesh, lattice, like):
    return _core.build_plan(mesh.positions, mesh.corner_vertices, mesh.face_offsets,
                            mesh.corner_normals, mesh.uvs, mesh.vertex_weights, lattice._spec, LEVEL,
                            like=like, centre_rows=False)


@pytest.mark.parametrize("name", ["suzanne", "figure", "goblet"])
def test_follow_equals_a_plan_built_like_it_and_the_exact_ffd(name):
    mesh = real.load(name)
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    values = _control_values_f32(lattice)
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    exact = real.reference_lattice(lattice)
    d = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    first = d.plan.input_triangles()
    d.deform()
    V = mesh.vertex_count
    for f in range(1, 5):
        posed = bend(mesh, 0.15 * f)
        reference = _plan_like(posed, lattice, d.plan)
        d.follow(posed)
        res = d.deform()
        pos, nrm = _evaluate(reference, values)
        assert np.array_equal(res.positions, pos)
        assert np.array_equal(res.corner_normals, nrm)
        assert np.array_equal(res.triangles, reference.triangles())
        assert np.array_equal(res.rest_positions, reference.rest_positions())
        # The first plan's triangles, whatever this pose's shape would choose.
        for a, b in zip(d.plan.input_triangles(), first):
            assert np.array_equal(a, b)
        # The deformed input vertices: the exact FFD of the posed ones (float rounding of
        # coordinates up to about 1.5 x the mesh's size), as a fresh plan's.
        F, _J = exact(posed.positions)
        assert np.abs(res.positions[:V] - F).max() / size < 2e-6
        fresh = smoothffd.Deformer(posed, lattice, level=LEVEL, device="cpu").deform()
        assert np.abs(fresh.positions[:V] - res.positions[:V]).max() / size < 2e-6
        assert res.positions.shape[0] > V  # the patches' own points are there too


def test_small_pose_change_keeps_the_topology_and_a_crossing_does_not():
    # Suzanne under a 5x5x5 lattice: the knot planes cut many of her faces. A pose change of
    # 1e-6 of her size moves no cut past a snap threshold.
    mesh = real.load("suzanne")
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    d = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    r0 = d.deform()
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    nudged = smoothffd.Mesh(mesh.positions * (1 + 1e-6), (mesh.corner_vertices, mesh.face_offsets),
                            corner_normals=mesh.corner_normals, uvs=mesh.uvs)
    assert d.follow(nudged) is True
    r1 = d.deform()
    assert r1.triangles is r0.triangles and r1.face_index is r0.face_index
    assert r1.sharp_edges is r0.sharp_edges
    assert not np.array_equal(r1.rest_positions, r0.rest_positions)
    assert 0 < np.abs(r1.positions - r0.positions).max() < 1e-4 * size
    # A bend that takes half her vertices through knot planes: new pieces, new topology.
    assert d.follow(bend(mesh, 0.4)) is False
    r2 = d.deform()
    assert r2.triangles is not r1.triangles
    assert r2.triangles.shape != r1.triangles.shape or not np.array_equal(r2.triangles, r1.triangles)


def test_other_faces_are_refused_and_the_deformer_keeps_working():
    mesh = real.load("suzanne")
    lattice = real.lattice_for(mesh)
    d = smoothffd.Deformer(mesh, lattice, level=2, device="cpu")
    before = d.deform().positions.copy()
    other = real.load("figure")
    with pytest.raises(ValueError, match="faces differ"):
        d.follow(other)
    shuffled = smoothffd.Mesh(mesh.positions, (np.roll(mesh.corner_vertices, 1), mesh.face_offsets))
    with pytest.raises(ValueError, match="faces differ"):
        d.follow(shuffled)
    with pytest.raises(TypeError):
        d.follow(mesh.positions)
    assert np.array_equal(d.deform().positions, before)
    with pytest.raises(TypeError):
        _core.follow_plan(None, mesh.positions, mesh.corner_vertices, mesh.face_offsets,
                          mesh.corner_normals, mesh.uvs, mesh.vertex_weights, lattice._spec)
    # The core refuses to change a plan an evaluator still reads.
    ev = _core.CpuEvaluator(d.plan, 0)
    with pytest.raises(RuntimeError, match="evaluator"):
        _core.follow_plan(d.plan, mesh.positions, mesh.corner_vertices, mesh.face_offsets,
                          mesh.corner_normals, mesh.uvs, mesh.vertex_weights, lattice._spec)
    del ev


def test_adaptive_deformer_follows():
    mesh = real.load("figure")
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    tol = 1e-3 * size
    d = smoothffd.Deformer(mesh, lattice, tolerance=tol, device="cpu")
    d.deform()
    posed = bend(mesh, 0.3)
    reference = _core.build_plan(posed.positions, posed.corner_vertices, posed.face_offsets,
                                 posed.corner_normals, posed.uvs, posed.vertex_weights, lattice._spec, 1,
                                 like=d.plan, centre_rows=False)
    d.follow(posed)
    res = d.deform()
    ref = _core.adaptive_frame(reference, _control_values_f32(lattice), tol, smoothffd.MAX_LEVEL,
                               0, True, None, True)
    assert np.array_equal(res.triangles, ref["triangles"])
    assert np.array_equal(res.positions, ref["positions"])
    assert res.stats["tolerance_met"]


_USABLE, _WHY = smoothffd.cuda_status()


@pytest.mark.skipif(not _USABLE, reason=f"no usable CUDA device: {_WHY}")
def test_cuda_follows_as_the_cpu():
    mesh = real.load("suzanne")
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    cpu = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    gpu = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cuda")
    # A new clipping on each pose, then the pieces held (checked: a small step; always: a
    # large one), up to a strong bend, where many shading normals are bounded: there the
    # patches around a vertex differ by up to the plan's sharp angle, and the per-corner
    # layouts differ by as much (the CPU's keeps each patch's own normal, the CUDA backend's is
    # each render vertex's, docs/api.md "The compact layout"). The render vertices' normals
    # agree to float rounding.
    steps = [(0.15, False), (0.3, False), (0.305, True), (0.45, "always"), (0.5, False), (0.52, "always")]
    for angle, hold in steps:
        posed = bend(mesh, angle)
        assert cpu.follow(posed, hold=hold) == gpu.follow(posed, hold=hold)
        assert cpu.plan.pieces_held == gpu.plan.pieces_held == bool(hold)
        a, b = cpu.deform(layout="compact"), gpu.deform()
        assert gpu.device == "cuda"
        assert np.array_equal(a.triangles, b.triangles)
        assert agreement.positions(b.positions, a.positions, size) <= agreement.POSITIONS
        assert agreement.normals(b.corner_normals, a.corner_normals()) <= agreement.NORMALS
        c = gpu.deform(layout="compact")
        assert agreement.normals(c.normals, a.normals) <= agreement.NORMALS


def test_pooled_evaluators_give_the_same_frames():
    # A new evaluator that takes over a destroyed one's buffers (a Deformer that follows gets one
    # each pose) starts from zeroed buffers: its frames, whole and incremental, are bitwise a
    # fresh evaluator's.
    mesh = real.load("goblet")
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    d = smoothffd.Deformer(mesh, lattice, level=4, device="cpu")
    values = _control_values_f32(lattice)
    moved = values.copy()
    moved[7] += 0.01
    pool = _core.BufferPool()
    ev = _core.CpuEvaluator(d.plan, 0, pool=pool)
    ev.evaluate(moved)
    assert pool.bytes == 0
    del ev
    assert pool.bytes > 0
    pooled = _core.CpuEvaluator(d.plan, 0, pool=pool)
    assert pool.bytes == 0
    plain = _core.CpuEvaluator(d.plan, 0)
    for a, b in zip(pooled.evaluate(values)[:2], plain.evaluate(values)[:2]):
        assert np.array_equal(a, b)
    pos_a, nrm_a, _ = pooled.evaluate(values)
    pos_b, nrm_b, _ = plain.evaluate(values)
    pooled.evaluate(moved, positions=pos_a, corner_normals=nrm_a, incremental=True)
    plain.evaluate(moved, positions=pos_b, corner_normals=nrm_b, incremental=True)
    assert np.array_equal(pos_a, pos_b) and np.array_equal(nrm_a, nrm_b)


def test_a_held_follow_takes_the_evaluators_tables_over():
    # A Deformer that follows holding the pieces gets a new CPU evaluator each pose, which takes
    # its predecessor's sample batches over (the samples that changed lattice pieces batched
    # again) and, where the output topology was kept, its output tables: its frames are
    # bitwise those of an evaluator that made its own. (The first follow starts the pool: the
    # evaluator of the first plan has none to leave its tables in.)
    loaded = real.load("suzanne")
    mesh = smoothffd.Mesh(loaded.positions, (loaded.corner_vertices, loaded.face_offsets))
    lattice = real.lattice_for(mesh, degree=(2, 2, 2), mode="twist", amount=30.0)
    values = _control_values_f32(lattice)
    d = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    d.deform()
    took_batches = took_tables = 0
    for f in range(1, 11):
        kept = d.follow(bend(mesh, 0.01 * f), hold=True)
        ev = d._evaluator
        assert ev.took_output_tables == (kept and f > 1)
        # Held pieces, the same samples: their batches (a new clipping makes new samples).
        assert ev.took_sample_batches == (d.plan.pieces_held and f > 1)
        took_batches += ev.took_sample_batches
        took_tables += ev.took_output_tables
        del ev  # the next follow changes the plan, which no other evaluator may read then
        res = d.deform()
        own = _core.CpuEvaluator(d.plan, 0).evaluate(values)
        assert np.array_equal(res.positions, own[0]) and np.array_equal(res.corner_normals, own[1])
    print(f"of 10 follows: sample batches taken over {took_batches}, output tables {took_tables}")
    assert took_batches >= 3 and took_tables >= 2


def _blender_lattice_around(mesh, lattice_to_object, seed=3):
    """A 4x4x4 Blender lattice (B-spline interpolation) whose rest box spans the mesh's box, its
    points displaced; placed by lattice_to_object after the fit."""
    import reference as ref
    lo, hi = mesh.positions.min(axis=0), mesh.positions.max(axis=0)
    rest = ref.blender_rest((4, 4, 4))
    fit = np.eye(4)
    fit[:3, :3] = np.diag(1.1 * (hi - lo))
    fit[:3, 3] = 0.5 * (lo + hi)
    rng = np.random.default_rng(seed)
    pts = rest + rng.uniform(-0.06, 0.06, rest.shape)
    return smoothffd.BlenderLattice(rest, pts, "BSPLINE", lattice_to_object @ fit)


def test_a_lattice_that_moves_with_a_bone_is_followed():
    # The lattice turns and slides with a bone while the mesh stays: its placement changes every
    # frame (a new structure key), its basis does not.
    import reference as ref
    mesh = real.load("suzanne")
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    d = smoothffd.Deformer(mesh, _blender_lattice_around(mesh, np.eye(4)), level=LEVEL, device="cpu")
    d.deform()
    for f in range(1, 4):
        place = ref.affine(ref.rotation([0, 0, 1], 0.05 * f), [0.01 * f * size, 0, 0])
        lat = _blender_lattice_around(mesh, place)
        assert lat.structure_key() != d.lattice.structure_key()
        reference = _plan_like(mesh, lat, d.plan)
        d.follow(lattice=lat)
        assert d.lattice is lat
        res = d.deform()
        pos, nrm = _evaluate(reference, _control_values_f32(lat))
        assert np.array_equal(res.positions, pos) and np.array_equal(res.corner_normals, nrm)
        # The input vertices: Blender's own lattice formula (tests/reference.py) at them.
        want = ref.blender_lattice_reference(lat.rest_points, lat.points, lat.interpolation,
                                             lat.lattice_to_object, lat.strength, mesh.positions)
        assert np.abs(res.positions[:mesh.vertex_count] - want).max() / size < 2e-6
    other = smoothffd.BlenderLattice(ref.blender_rest((5, 4, 4)), ref.blender_rest((5, 4, 4)), "BSPLINE")
    with pytest.raises(ValueError, match="basis"):
        d.follow(lattice=other)


def _geometry_errors(res, exact, size):
    """Each output vertex against the exact FFD of its rest point (the independent reference),
    relative to the mesh's size: (max, mean)."""
    F, _J = exact(np.asarray(res.rest_positions, np.float64))
    e = np.linalg.norm(np.asarray(res.positions, np.float64) - F, axis=1) / size
    return float(e.max()), float(e.mean())


@pytest.mark.parametrize("name,degree", [("suzanne", (2, 2, 2)), ("figure", (3, 3, 3))])
def test_holding_the_pieces_keeps_the_topology_at_the_same_accuracy(name, degree):
    # A bend animation in small steps (a character's skin between frames): following with
    # hold=True keeps the pieces, hence the output triangles, on most frames where a new
    # clipping changes them on nearly every one, and the results are as close to the exact FFD
    # of their rest points as the exactly followed ones.
    # Without corner normals: bend() turns each corner normal with its vertex, which would
    # make flat faces smooth (a new topology, the kFlatFace flags) on any pose.
    loaded = real.load(name)
    mesh = smoothffd.Mesh(loaded.positions, (loaded.corner_vertices, loaded.face_offsets))
    lattice = real.lattice_for(mesh, degree=degree, mode="twist", amount=30.0)
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    exact = real.reference_lattice(lattice)
    held = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    plain = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    last = held.deform()
    plain.deform()
    clipped = _geometry_errors(last, exact, size)  # of the pose the held pieces were cut in
    V = mesh.vertex_count
    frames, n_held, n_kept, n_plain_kept = 10, 0, 0, 0
    for f in range(1, frames + 1):
        posed = bend(mesh, 0.01 * f)
        kept = held.follow(posed, hold=True)
        n_plain_kept += plain.follow(posed)
        res, ref_res = held.deform(), plain.deform()
        n_held += held.plan.pieces_held
        assert kept <= held.plan.pieces_held  # no face crossing as before without the hold
        if kept:
            n_kept += 1
            assert res.triangles is last.triangles
        gh, ge = _geometry_errors(res, exact, size), _geometry_errors(ref_res, exact, size)
        print(f"frame {f}: held {held.plan.pieces_held} max {gh[0]:.3e} vs {ge[0]:.3e}, "
              f"mean {gh[1]:.3e} vs {ge[1]:.3e} (clipped {clipped[0]:.3e}, {clipped[1]:.3e})")
        if held.plan.pieces_held:
            # As close as the pieces were where they were cut, or as this pose's new clipping
            # (other pieces, other output points: the means differ by up to 10%). Measured: the
            # largest error within 1.0001 of that, the mean within 1.016 after 9 frames held
            # (the figure under a cubic lattice: its pieces drift on past the planes).
            assert gh[0] <= 1.002 * max(ge[0], clipped[0])
            assert gh[1] <= 1.025 * max(ge[1], clipped[1])
        else:
            clipped = gh
        F, _J = exact(posed.positions)
        assert np.abs(res.positions[:V] - F).max() / size < 2e-6
        last = res
    print(f"{name}: pieces held on {n_held}/{frames} frames, the topology kept on {n_kept}; a new "
          f"clipping kept it on {n_plain_kept}/{frames}")
    assert n_kept >= 3 and n_plain_kept == 0
    # A bend that takes pieces far past their planes: clipped again, as without hold.
    posed = bend(mesh, 0.4)
    reference = _plan_like(posed, lattice, held.plan)
    assert held.follow(posed, hold=True) is False and not held.plan.pieces_held
    res = held.deform()
    assert np.array_equal(res.positions, _evaluate(reference, _control_values_f32(lattice))[0])


def test_hold_always_keeps_the_pieces_however_far_and_bad_values_are_refused():
    # hold='always' (a render's motion-blur subframes): the pieces stay wherever the bend takes
    # them; the patches that now reach across knot planes fit a little worse, the input
    # vertices stay the exact FFD.
    loaded = real.load("suzanne")
    mesh = smoothffd.Mesh(loaded.positions, (loaded.corner_vertices, loaded.face_offsets))
    lattice = real.lattice_for(mesh, mode="twist", amount=30.0)
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    exact = real.reference_lattice(lattice)
    d = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    first = d.deform()
    with pytest.raises(ValueError, match="hold"):
        d.follow(mesh, hold="sometimes")
    with pytest.raises(ValueError, match="hold"):
        d.follow(mesh, hold=1)
    posed = bend(mesh, 0.1)
    assert d.follow(posed, hold=True) is False and not d.plan.pieces_held
    d.follow(mesh)
    first = d.deform()
    d.follow(posed, hold="always")
    res = d.deform()
    # The same triangles (the output topology may still be rebuilt where an edge's normals
    # split or join at the new pose: its render vertices).
    assert d.plan.pieces_held and np.array_equal(res.triangles, first.triangles)
    F, _J = exact(posed.positions)
    assert np.abs(res.positions[:mesh.vertex_count] - F).max() / size < 2e-6
    plain = smoothffd.Deformer(mesh, lattice, level=LEVEL, device="cpu")
    plain.follow(posed)
    held, clipped = _geometry_errors(res, exact, size), _geometry_errors(plain.deform(), exact, size)
    print(f"bend 0.1 held always: max {held[0]:.3e} mean {held[1]:.3e}; clipped: max "
          f"{clipped[0]:.3e} mean {clipped[1]:.3e}")
    assert held[0] <= 1.02 * clipped[0] and held[1] <= 1.02 * clipped[1]  # measured 1.005, 0.999
