"""Unit tests of the add-on's pure logic (addon/smooth_ffd/logic.py: numpy only, no bpy).
The `logic` fixture (conftest.py) loads logic.py by path."""
import numpy as np
import pytest


def test_lattice_grid_u_fastest(logic):
    nu, nv, nw = 2, 3, 4
    flat = np.array([(u, v, w) for w in range(nw) for v in range(nv) for u in range(nu)], float)
    g = logic.lattice_grid(flat, (nu, nv, nw))
    assert g.shape == (nu, nv, nw, 3)
    assert tuple(g[1, 2, 3]) == (1, 2, 3)


def test_lattice_to_object(logic):
    m = np.diag([2.0, 2.0, 2.0, 1.0]); m[:3, 3] = (1, 0, 0)
    lat = np.eye(4); lat[:3, 3] = (3, 0, 0)
    l2o = logic.lattice_to_object(m, lat)
    assert np.allclose(l2o @ [0, 0, 0, 1], [1, 0, 0, 1])   # (3 - 1) / 2
    with pytest.raises(logic.SmoothFFDError):
        logic.lattice_to_object(np.diag([0.0, 1, 1, 1]), lat)


def test_vertex_weights(logic):
    w = logic.vertex_weights(4, 1, [0, 1, 1, 3], [1, 0, 1, 1], [0.5, 0.9, 0.25, 2.0], False)
    assert np.allclose(w, [0.5, 0.25, 0, 1])
    wi = logic.vertex_weights(4, 1, [0, 1, 1, 3], [1, 0, 1, 1], [0.5, 0.9, 0.25, 2.0], True)
    assert np.allclose(wi, [0.5, 0.75, 1, 0])
    assert logic.vertex_weights(4, None, [], [], [], False) is None


def test_edge_flags(logic):
    edges = np.array([[0, 1], [1, 2], [2, 0], [2, 3]])
    flags = logic.edge_flags(edges, np.array([[2, 1], [3, 2], [5, 4]]), 6)
    assert flags.tolist() == [False, True, False, True]
    assert not logic.edge_flags(edges, np.zeros((0, 2)), 6).any()


def test_parse(logic):
    assert logic.parse_backend(" CPU ") == "cpu"
    assert logic.parse_backend("") == "auto"
    with pytest.raises(logic.SmoothFFDError):
        logic.parse_backend("gpu")
    assert logic.parse_level(3, "x") == 3
    with pytest.raises(logic.SmoothFFDError):
        logic.parse_level(0, "x")
    assert logic.interpolation_names(["KEY_BSPLINE", "KEY_LINEAR", "KEY_CARDINAL"]) == \
        ("BSPLINE", "LINEAR", "CARDINAL")


def test_digest_and_loops(logic):
    a = np.arange(6, dtype=np.float32)
    assert logic.digest(a, 1) == logic.digest(a.copy(), 1)
    assert logic.digest(a, 1) != logic.digest(a.astype(np.float64), 1)
    loops, starts, totals = logic.triangle_loops(np.array([[0, 1, 2], [2, 1, 3]]))
    assert loops.dtype == np.int32 and loops.tolist() == [0, 1, 2, 2, 1, 3]
    assert starts.tolist() == [0, 3] and totals.tolist() == [3, 3]


# --- carrying UV maps and vertex groups (logic.py's barycentric helpers) ---------------------

def test_triangle_barycentrics_exact_at_corners_and_edges(logic):
    rng = np.random.default_rng(0)
    a, b, c = (rng.normal(size=(5, 3)) for _ in range(3))
    for k, x in enumerate((a, b, c)):
        got = logic.triangle_barycentrics(x, a, b, c)
        want = np.zeros((5, 3)); want[:, k] = 1.0
        assert np.array_equal(got, want)            # exactly one-hot: values copied exactly
    mid = logic.triangle_barycentrics(0.25 * a + 0.75 * b, a, b, c)
    assert np.all(mid[:, 2] == 0.0) and np.allclose(mid[:, :2], [0.25, 0.75])
    w = rng.dirichlet([1, 1, 1], size=5)
    x = w[:, :1] * a + w[:, 1:2] * b + w[:, 2:] * c
    assert np.allclose(logic.triangle_barycentrics(x, a, b, c), w, atol=1e-12)
    # Off the plane: the projection's coordinates; degenerate triangle: the nearest corner.
    n = np.cross(b - a, c - a)
    assert np.allclose(logic.triangle_barycentrics(x + 0.1 * n, a, b, c), w, atol=1e-12)
    deg = logic.triangle_barycentrics(np.array([[0.9, 0, 0]]), np.zeros((1, 3)),
                                      np.array([[1.0, 0, 0]]), np.array([[2.0, 0, 0]]))
    assert deg.tolist() == [[0.0, 1.0, 0.0]]


def test_patch_core_triangles_follows_the_diagonal(logic):
    # A square cut along 0-2 into triangles (0,1,2) and (0,2,3); a second face: a triangle.
    sq = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    tri_points = np.array([sq[[0, 1, 2]], sq[[0, 2, 3]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]])
    first, count = logic.face_triangle_ranges([0, 0, 1], 2)
    assert first.tolist() == [0, 2] and count.tolist() == [2, 1]
    # Patches (pieces of those triangles, e.g. after knot-plane clipping).
    patches = np.array([
        [[0, 0, 0], [0.5, 0, 0], [0.5, 0.5, 0]],      # in (0,1,2)
        [[0.5, 0.5, 0], [0, 1, 0], [0, 0.5, 0]],      # in (0,2,3)
        [[1, 0, 0], [1, 1, 0], [0.5, 0.5, 0]],        # in (0,1,2)
        [[0, 0, 1], [1, 0, 1], [0, 1, 1]],            # the triangle face
    ])
    got = logic.patch_core_triangles([0, 0, 0, 1], patches, first, count, tri_points)
    assert got.tolist() == [0, 1, 0, 2]
    # Folded (non-planar) quad: the plane distance decides.
    fold = tri_points.copy()
    fold[1] = [[0, 0, 0], [1, 1, 0], [0, 0.2, 1]]
    p = np.array([[[0.05, 0.08, 0.2], [0.3, 0.33, 0], [0.02, 0.14, 0.6]]])
    assert logic.patch_core_triangles([0], p, first, count, fold).tolist() == [1]
    with pytest.raises(ValueError):
        logic.face_triangle_ranges([1, 0], 2)


def test_output_corner_barycentrics_and_uvs(logic):
    # One face, one core triangle, level 2: 4 output triangles of the patch (its 4 sub-triangles).
    tri_points = np.array([[[0, 0, 0], [2, 0, 0], [0, 2, 0]]], float)
    rest = np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    triangles = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]])
    corners, bary = logic.output_corner_barycentrics(triangles, 2, np.array([0]),
                                                     np.array([[7, 8, 9]]), tri_points, rest)
    assert corners.shape == (12, 3) and np.all(corners == [7, 8, 9])
    uvs = np.zeros((10, 2)); uvs[7] = (0, 0); uvs[8] = (1, 0); uvs[9] = (0, 4)
    got = logic.interpolate_corner_values(uvs, corners, bary).reshape(4, 3, 2)
    assert np.array_equal(got[1, 1], [1, 0])                 # output vertex 1 = corner 8
    assert np.allclose(got[3], [[0.5, 0], [0.5, 2], [0, 2]])


def test_interpolate_group_membership_and_exactness(logic):
    weight = np.array([0.3, 0.7, 0.0, 0.3, 1.0], np.float32)
    member = np.array([True, True, False, True, True])
    src = np.array([[0, 1, 2], [0, 1, 2], [2, 2, 2], [0, 3, 2], [4, 4, 4]])
    bary = np.array([[0.5, 0.5, 0.0], [0.2, 0.0, 0.8], [1 / 3, 1 / 3, 1 / 3],
                     [0.1, 0.6, 0.3], [0.3, 0.3, 0.4]])
    w, m = logic.interpolate_group(weight, member, src, bary)
    assert m.tolist() == [True, True, False, True, True]
    assert np.allclose(w[:2], [0.5, 0.06])
    assert w[2] == 0.0
    assert np.isclose(w[3], 0.1 * 0.3 + 0.6 * 0.3)           # non-member corner counts as 0
    # Equal weights at every corner in use: exactly that weight, not a rounded sum.
    assert w[4] == np.float32(1.0)
    w2, m2 = logic.interpolate_group(weight, member, np.array([[0, 3, 2]]),
                                     np.array([[0.25, 0.75, 0.0]]))
    assert m2.tolist() == [True] and w2[0] == np.float32(0.3)


def test_vertex_representatives_and_batches(logic):
    rep = logic.vertex_representatives(np.array([[0, 1, 2], [2, 1, 3]]), 5)
    assert rep.tolist() == [0, 4, 3, 5, -1]
    batches = logic.weight_batches([4, 9, 2, 7], np.array([0.5, 1.0, 0.5, 0.25], np.float32))
    assert batches == [(0.25, [7]), (0.5, [4, 2]), (1.0, [9])]
    assert logic.weight_batches([], []) == []


def test_grid_table_and_patch_grid(logic):
    # Level 2 grid of a patch with corners P0, P1, P2; the 4 sub-triangles' corners in some order.
    P = np.array([[0, 0, 0], [4, 0, 0], [0, 4, 1]], float)
    grid = {(2, 0, 0): 0, (1, 1, 0): 1, (0, 2, 0): 2, (1, 0, 1): 3, (0, 1, 1): 4, (0, 0, 2): 5}
    local = [[(2, 0, 0), (1, 1, 0), (1, 0, 1)], [(1, 1, 0), (0, 2, 0), (0, 1, 1)],
             [(1, 0, 1), (0, 1, 1), (0, 0, 2)], [(1, 1, 0), (0, 1, 1), (1, 0, 1)]]
    pts = np.array([np.array(g) @ P / 2 for tri in local for g in tri])
    pts = pts.astype(np.float32)            # rest positions come as float32
    table = logic.grid_table(pts, P, 2)
    assert table.tolist() == [[x / 2 for x in g] for tri in local for g in tri]
    assert logic.grid_table(pts + 0.3, P, 2) is None            # not on the grid
    # Two patches; values at their core triangle corners (P, 3, k); patch 1 is the core
    # triangle's lower half (corners at core coordinates below).
    pb = np.array([np.eye(3), [[1, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5]]])
    vals = np.array([[[0, 0], [1, 0], [0, 1]], [[0, 0], [1, 0], [0, 1]]], float)
    out = logic.interpolate_patch_grid(table, pb, vals).reshape(2, 4, 3, 2)
    assert np.array_equal(out[0, 0, 0], [0, 0]) and np.array_equal(out[0, 1, 1], [1, 0])
    assert np.allclose(out[0, 3], [[0.5, 0], [0.5, 0.5], [0, 0.5]])
    assert np.allclose(out[1, 1, 1], [0.5, 0])                   # patch corner 1 = core (.5,.5,0)
    assert np.allclose(out[1, 2, 2], [0, 0.5])
