"""BlenderLattice point weights: the lattice's vertex group (Lattice.vertex_group) of Blender's
Lattice modifier, against the literal transcription of lattice_deform.cc in tests/reference.py
(weight_blend, then interp_v3_v3v3) and finite differences of it; the evaluators' layouts, code
paths and threads against each other; the Deformer's plan reuse; validation and lattice JSON.
The add-on against Blender's own modifier: tests/blender/check_lattice_weights.py.
"""

import zlib

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
import smoothffd  # noqa: E402
from smoothffd import _core, lattice_json  # noqa: E402

import reference as ref  # noqa: E402
from meshes import edge_counts, sphere_mesh  # noqa: E402

TYPES = ref.BLENDER_TYPES
KINDS = [(k,) * 3 for k in TYPES] + [("LINEAR", "CARDINAL", "BSPLINE")]
SHAPES = [(4, 3, 5), (2, 2, 2), (1, 3, 4), (6, 1, 2)]
PATTERNS = ("random", "ones", "zeros", "onehot", "ramp")


def seed(*key):
    return zlib.crc32(repr(key).encode())


def weights(pattern, shape, rng):
    if pattern == "random":
        return rng.uniform(0, 1, shape)
    if pattern == "ones":
        return np.ones(shape)
    if pattern == "zeros":
        return np.zeros(shape)
    if pattern == "onehot":  # one point in the group, the rest absent (weight 0)
        w = np.zeros(shape)
        w[tuple(rng.integers(0, n) for n in shape)] = 1.0
        return w
    ramp = np.linspace(0.0, 1.0, shape[0]) if shape[0] > 1 else np.ones(1)
    return np.broadcast_to(ramp[:, None, None], shape).copy()


def case(rng, shape, kinds, pattern):
    """(BlenderLattice kwargs with point_weights, points inside and far outside, scale)."""
    rest = ref.blender_rest(shape)
    pts = rest + rng.normal(0, 0.12, rest.shape)
    A = ref.rotation(rng.normal(size=3), rng.uniform(0, np.pi)) @ np.diag(rng.uniform(0.6, 1.8, 3))
    l2o = ref.affine(A, rng.uniform(-1, 1, 3))
    kw = dict(rest_points=rest, points=pts, interpolation=kinds, lattice_to_object=l2o,
              strength=float(rng.choice([1.0, 0.6, 1.7])), point_weights=weights(pattern, shape, rng))
    q_in = rng.uniform(-0.6, 0.6, (30, 3))
    q_out = rng.uniform(-5, 5, (15, 3))
    to_obj = lambda q: q @ l2o[:3, :3].T + l2o[:3, 3]  # noqa: E731
    return kw, to_obj(q_in), to_obj(q_out), float(np.abs(to_obj(q_out)).max())


def reference(kw, p, strength=None):
    return ref.blender_lattice_jacobian_reference(
        kw["rest_points"], kw["points"], kw["interpolation"], kw["lattice_to_object"],
        kw["strength"] if strength is None else strength, p, point_weights=kw["point_weights"])


# ----------------------------------------------------------------------------- the map (float64)

@pytest.mark.parametrize("pattern", PATTERNS)
@pytest.mark.parametrize("kinds", KINDS, ids=lambda k: "-".join(k))
@pytest.mark.parametrize("shape", SHAPES, ids=lambda s: "x".join(map(str, s)))
def test_evaluate_matches_blender_formula(shape, kinds, pattern):
    """Positions and Jacobians inside and far outside the lattice (the clamped stencil blends
    the boundary weights there as it does the displacements)."""
    rng = np.random.default_rng(seed(shape, kinds, pattern))
    kw, p_in, p_out, scale = case(rng, shape, kinds, pattern)
    lat = smoothffd.BlenderLattice(**kw)
    for p in (p_in, p_out):
        pos, jac = lat.evaluate(p)
        rpos, rjac = reference(kw, p)
        assert np.abs(pos - rpos).max() <= 1e-12 * max(1.0, scale)
        assert np.abs(jac - rjac).max() <= 1e-9 * max(1.0, np.abs(rjac).max())


@pytest.mark.parametrize("kinds", KINDS, ids=lambda k: "-".join(k))
def test_jacobian_vs_finite_differences_of_the_reference(kinds):
    rng = np.random.default_rng(seed("fd", kinds))
    kw, p_in, p_out, _ = case(rng, (4, 3, 5), kinds, "random")
    p = np.concatenate([p_in[:15], p_out[:5]])
    _, jac = smoothffd.BlenderLattice(**kw).evaluate(p)
    fd = ref.jacobian_fd(lambda x: reference(kw, x)[0], p, 1e-6)
    assert np.abs(jac - fd).max() <= 1e-6 * max(1.0, np.abs(fd).max())


def test_weights_are_interpolated_not_per_point_scales():
    """Blender blends by the interpolated weight s(p): scaling each point's displacement by
    its own weight instead differs (the case that was 0.023 off in Blender)."""
    rng = np.random.default_rng(3)
    kw, p, _, _ = case(rng, (4, 4, 4), ("BSPLINE",) * 3, "random")
    kw["strength"] = 1.0
    lat = smoothffd.BlenderLattice(**kw)
    rest, pts, lw = kw["rest_points"], kw["points"], kw["point_weights"]
    scaled = smoothffd.BlenderLattice(rest, rest + lw[..., None] * (pts - rest), kw["interpolation"],
                                      kw["lattice_to_object"])
    a, b = lat.evaluate(p)[0], scaled.evaluate(p)[0]
    assert np.abs(a - b).max() > 1e-3
    assert np.abs(a - reference(kw, p)[0]).max() <= 1e-12


@pytest.mark.parametrize("strength", [1.0, 0.5])
def test_all_ones_is_the_unweighted_map_times_strength(strength):
    """Weights 1 everywhere: s = strength, so p' = p + strength^2 d (Blender applies its factor
    to both sums); at strength 1 the unweighted map up to rounding."""
    rng = np.random.default_rng(9)
    kw, p, q, _ = case(rng, (3, 4, 5), ("CATMULL_ROM",) * 3, "ones")
    kw["strength"] = strength
    p = np.concatenate([p, q])
    pos, jac = smoothffd.BlenderLattice(**kw).evaluate(p)
    plain = dict(kw, point_weights=None, strength=strength * strength)
    upos, ujac = smoothffd.BlenderLattice(**plain).evaluate(p)
    assert np.abs(pos - upos).max() <= 1e-14 * max(1.0, np.abs(p).max())
    assert np.abs(jac - ujac).max() <= 1e-12


def test_all_zeros_is_the_identity():
    rng = np.random.default_rng(10)
    kw, p, q, _ = case(rng, (3, 3, 3), ("BSPLINE",) * 3, "zeros")
    p = np.concatenate([p, q])
    pos, jac = smoothffd.BlenderLattice(**kw).evaluate(p)
    np.testing.assert_array_equal(pos, p)
    np.testing.assert_array_equal(jac, np.broadcast_to(np.eye(3), jac.shape))


# ----------------------------------------------------------------------------- smooth FFD (float32)

def sphere_case(pattern="random", mesh_weights=True, strength=0.8, interp="BSPLINE"):
    rng = np.random.default_rng(seed("sphere", pattern, mesh_weights, strength, interp))
    m0 = sphere_mesh(2)
    w = rng.uniform(0.2, 1.0, len(m0.positions)) if mesh_weights else None
    mesh = smoothffd.Mesh(m0.positions, (m0.corner_vertices, m0.face_offsets),
                          corner_normals=m0.corner_normals, vertex_weights=w)
    shape = (4, 3, 5)
    rest = ref.blender_rest(shape)
    pts = rest + rng.uniform(-0.09, 0.09, rest.shape)
    M = ref.affine(2.4 * ref.rotation([1, 2, 3], 0.7), [0.1, -0.2, 0.05])
    lw = weights(pattern, shape, rng)
    lat = smoothffd.BlenderLattice(rest, pts, (interp,) * 3, M, strength=strength, point_weights=lw)
    kw = dict(rest_points=rest, points=pts, interpolation=(interp,) * 3, lattice_to_object=M,
              strength=strength, point_weights=lw)
    return mesh, w, lat, kw


@pytest.mark.parametrize("interp", TYPES)
@pytest.mark.parametrize("pattern", ["random", "ramp", "onehot"])
def test_input_vertices_follow_blender(pattern, interp):
    """The deformed input vertices against Blender's formula with the modifier's factor
    strength * (vertex-group weight) per vertex, clipped and watertight at several levels."""
    mesh, w, lat, kw = sphere_case(pattern, interp=interp)
    V = len(w)
    expect = np.array([reference(kw, mesh.positions[i][None], kw["strength"] * w[i])[0][0]
                       for i in range(V)])
    for level in (1, 4):
        r = smoothffd.deform(mesh, lat, level=level, device="cpu")
        # measured 8.5e-8 (coordinates up to about 2.4: float32 steps of 2.4e-7)
        assert np.abs(r.positions[:V] - expect).max() <= 3e-7
        assert np.all(edge_counts(r.triangles) == 2)
        assert np.isfinite(r.corner_normals).all()


def test_normals_at_input_vertices_are_the_cofactor_of_finite_differences():
    """At an input vertex each corner normal is the rest normal mapped by the cofactor of the
    map's Jacobian (Barr 1984): here from central differences of the reference. Measured
    1.2e-7 rad (float rounding of the output normals); a Jacobian without the weights'
    gradient is 0.06 rad off."""
    mesh, _, lat, kw = sphere_case("random", mesh_weights=False)
    r = smoothffd.deform(mesh, lat, level=3, device="cpu")
    V = len(mesh.positions)
    J = ref.jacobian_fd(lambda x: reference(kw, x)[0], mesh.positions, 1e-6)
    n = mesh.positions / np.linalg.norm(mesh.positions, axis=1, keepdims=True)  # sphere normals
    expect = np.einsum("nrc,nc->nr", ref.cofactor(J), n)
    expect /= np.linalg.norm(expect, axis=1, keepdims=True)
    tri = r.triangles.reshape(-1)
    at_input = tri < V
    got = r.corner_normals.reshape(-1, 3)[at_input].astype(np.float64)
    e = expect[tri[at_input]]
    err = np.arctan2(np.linalg.norm(np.cross(got, e), axis=1), np.sum(got * e, axis=1))
    assert at_input.sum() > 500
    assert err.max() < 5e-7, f"normals differ by up to {err.max():.2e} rad"
    # J without d (grad s)^T: I + r (J_u - I), r = strength s the blend factor, J_u the
    # unweighted map's Jacobian. Its normals are far off: the bound above tells them apart.
    P = mesh.positions
    Fw = reference(kw, P)[0]
    Fu, Ju = reference(dict(kw, point_weights=None), P)
    r = np.sum((Fw - P) * (Fu - P), axis=1) / np.sum((Fu - P) ** 2, axis=1)
    wrong = np.einsum("nrc,nc->nr", ref.cofactor(np.eye(3) + r[:, None, None] * (Ju - np.eye(3))), n)
    wrong /= np.linalg.norm(wrong, axis=1, keepdims=True)
    assert np.arccos(np.clip(np.sum(wrong * expect, axis=1), -1, 1)).max() > 2e-2


def test_all_ones_deform_equals_unweighted():
    """Weights 1, strength 1, no mesh vertex group: the unweighted result up to float rounding."""
    mesh, _, _, kw = sphere_case("ones", mesh_weights=False, strength=1.0)
    weighted = smoothffd.deform(mesh, smoothffd.BlenderLattice(**kw), level=4, device="cpu")
    plain = smoothffd.deform(mesh, smoothffd.BlenderLattice(**dict(kw, point_weights=None)), level=4,
                             device="cpu")
    np.testing.assert_array_equal(weighted.triangles, plain.triangles)
    assert np.abs(weighted.positions - plain.positions).max() <= 2e-6
    assert np.abs(weighted.corner_normals - plain.corner_normals).max() <= 2e-5


def test_all_zeros_deform_equals_the_identity_lattice():
    """Weights all 0 give the identity lattice's result: the samples (input vertices
    included) and the normals bitwise; the patches' centres to float rounding, since a plain
    lattice's come from the plan's centre rows (plan/centre_rows.hpp) and a weighted one's
    (not linear in the control values) from the fit."""
    mesh, _, _, kw = sphere_case("zeros")
    weighted = smoothffd.deform(mesh, smoothffd.BlenderLattice(**kw), level=4, device="cpu")
    identity = dict(kw, points=kw["rest_points"], point_weights=None)
    plain = smoothffd.deform(mesh, smoothffd.BlenderLattice(**identity), level=4, device="cpu")
    assert np.abs(weighted.positions - plain.positions).max() <= 5e-7  # unit sphere: a few ulp
    np.testing.assert_array_equal(weighted.corner_normals, plain.corner_normals)
    np.testing.assert_array_equal(weighted.positions[:len(mesh.positions)],
                                  mesh.positions.astype(np.float32))


def test_layouts_paths_and_threads_agree():
    """Full, compact and positions-only layouts give bitwise the same positions; both CPU code
    paths (baseline and AVX2) agree to float rounding; thread counts bitwise."""
    mesh, _, lat, _ = sphere_case("random")
    d = smoothffd.Deformer(mesh, lat, level=5, device="cpu", threads=2)
    assert d.plan.components == 4
    full = d.deform()
    compact = d.deform(layout="compact")
    positions = d.deform(normals=False)
    np.testing.assert_array_equal(full.positions, compact.positions)
    np.testing.assert_array_equal(full.positions, positions.positions)
    cn = compact.corner_normals().astype(np.float64)
    fc = full.corner_normals.astype(np.float64)
    # measured 2.1e-7 rad (in double: float32's arccos cannot resolve less than 3e-4 rad)
    assert np.arctan2(np.linalg.norm(np.cross(cn, fc), axis=-1), np.sum(cn * fc, axis=-1)).max() < 1e-6
    values = np.ascontiguousarray(lat._core_values(), dtype=np.float32)
    assert values.shape == (60, 4)
    for isa in sorted({"x86-64-v2", _core.cpu_isa()}):
        p, n, _ = _core.CpuEvaluator(d.plan, 1, isa=isa).evaluate(values)
        # measured 3.6e-7 and 2.4e-7 between the paths (coordinates up to about 2.4)
        assert np.abs(p - full.positions).max() <= 1.2e-6
        assert np.abs(n - full.corner_normals).max() <= 1e-6
    one = smoothffd.Deformer(mesh, lat, level=5, device="cpu", threads=1).deform()
    np.testing.assert_array_equal(one.positions, full.positions)
    np.testing.assert_array_equal(one.corner_normals, full.corner_normals)


def test_weights_change_per_frame_without_replanning():
    """Weights are per-frame values like the points: with_points keeps them or takes new ones,
    and the Deformer reuses its plan; adding or dropping the weights is a new structure."""
    mesh, w, lat, kw = sphere_case("random")
    d = smoothffd.Deformer(mesh, lat, level=3, device="cpu")
    plan = d.plan
    rng = np.random.default_rng(4)
    new_w = rng.uniform(0, 1, kw["point_weights"].shape)
    new_p = kw["points"] + rng.uniform(-0.03, 0.03, kw["points"].shape)
    # Points only: the weights stay.
    r1 = d.deform(new_p)
    assert d.plan is plan
    np.testing.assert_array_equal(d.lattice.point_weights, kw["point_weights"])
    lat2 = lat.with_points(new_p, point_weights=new_w)
    assert lat2.structure_key() == lat.structure_key()
    r2 = d.deform(lat2)
    assert d.plan is plan
    kw2 = dict(kw, points=new_p, point_weights=new_w)
    V = len(w)
    expect = np.array([reference(kw2, mesh.positions[i][None], kw["strength"] * w[i])[0][0]
                       for i in range(V)])
    assert np.abs(r2.positions[:V] - expect).max() <= 1e-5 * 2.4
    assert np.abs(r1.positions[:V] - expect).max() > 1e-3   # the weights made a difference
    fresh = smoothffd.Deformer(mesh, smoothffd.BlenderLattice(**kw2), level=3, device="cpu").deform()
    np.testing.assert_array_equal(r2.positions, fresh.positions)
    # Without weights: another structure, a new plan of 3 values a point.
    plain = smoothffd.BlenderLattice(**dict(kw2, point_weights=None))
    assert plain.structure_key() != lat.structure_key()
    d.deform(plain)
    assert d.plan is not plan and d.plan.components == 3


def test_bad_point_weights():
    rest = ref.blender_rest((2, 3, 2))
    pts = rest + 0.05
    ok = smoothffd.BlenderLattice(rest, pts, point_weights=np.ones((2, 3, 2)))
    for bad, exc, match in [(np.ones((2, 3)), ValueError, "point_weights: expected shape"),
                            (np.ones(12), ValueError, "point_weights: expected shape"),
                            (np.ones((2, 3, 2, 1)), ValueError, "point_weights: expected shape"),
                            (np.full((2, 3, 2), np.nan), ValueError, "point_weights: contains NaN"),
                            (np.full((2, 3, 2), np.inf), ValueError, "point_weights: contains NaN"),
                            (np.full((2, 3, 2), "a"), TypeError, "point_weights"),
                            (np.ones((2, 3, 2), bool), TypeError, "point_weights")]:
        with pytest.raises(exc, match=match):
            smoothffd.BlenderLattice(rest, pts, point_weights=bad)
        with pytest.raises(exc, match=match):
            ok.with_points(pts, point_weights=bad)
    with pytest.raises(ValueError, match="point_weights: this lattice has none"):
        smoothffd.BlenderLattice(rest, pts).with_points(pts, point_weights=np.ones((2, 3, 2)))
    huge = smoothffd.BlenderLattice(rest, pts, point_weights=np.full((2, 3, 2), 1e38))
    mesh = sphere_mesh(1)
    with pytest.raises(ValueError, match="point_weights: strength"):
        smoothffd.deform(mesh, huge, level=1, device="cpu")
    plan = smoothffd.Deformer(mesh, ok, level=1, device="cpu").plan
    with pytest.raises(ValueError, match=r"control values: expected an \(nu\*nv\*nw, 4\)"):
        _core.CpuEvaluator(plan).evaluate(np.zeros((12, 3), np.float32))


def test_lattice_json_round_trip(tmp_path):
    _, _, lat, _ = sphere_case("random")
    path = tmp_path / "w.json"
    lattice_json.save_lattice(path, lat)
    back = lattice_json.load_lattice(path)
    np.testing.assert_array_equal(back.point_weights, lat.point_weights)
    assert back.structure_key() == lat.structure_key()
    p = np.random.default_rng(1).uniform(-1, 1, (10, 3))
    np.testing.assert_array_equal(back.evaluate(p)[0], lat.evaluate(p)[0])
    doc = lattice_json.lattice_to_dict(lat)
    doc["point_weights"] = doc["point_weights"][:-1]
    with pytest.raises(ValueError, match="key 'point_weights': expected null or a list of 60"):
        lattice_json.parse_lattice(doc)
    doc["point_weights"] = [0.5] * 59 + ["x"]
    with pytest.raises(ValueError, match=r"key 'point_weights\[59\]'"):
        lattice_json.parse_lattice(doc)
    doc["point_weights"] = None
    _, kw = lattice_json.parse_lattice(doc)
    assert kw["point_weights"] is None
    assert "point_weights" not in lattice_json.lattice_to_dict(smoothffd.BlenderLattice(**kw))
