"""Unit tests of addon/smooth_ffd/result_arrays.py (arrays for the result mesh; numpy only,
no bpy). The `result_arrays` fixture (conftest.py) loads it by path."""
import numpy as np


def test_triangle_loops(result_arrays):
    loops, starts, totals = result_arrays.triangle_loops(np.array([[0, 1, 2], [2, 1, 3]]))
    assert loops.dtype == np.int32 and loops.tolist() == [0, 1, 2, 2, 1, 3]
    assert starts.tolist() == [0, 3] and totals.tolist() == [3, 3]


def test_edge_flags(result_arrays):
    edges = np.array([[0, 1], [1, 2], [2, 0], [2, 3]])
    flags = result_arrays.edge_flags(edges, np.array([[2, 1], [3, 2], [5, 4]]), 6)
    assert flags.tolist() == [False, True, False, True]
    assert not result_arrays.edge_flags(edges, np.zeros((0, 2)), 6).any()


def test_edge_flags_match_a_set_of_pairs(result_arrays):
    """Random meshes' edges and flagged pairs (some not edges, some repeated, either order),
    against a plain set lookup; the edges as Blender gives them (int32, any order)."""
    rng = np.random.default_rng(5)
    for trial in range(20):
        n = int(rng.integers(3, 400))
        tri = rng.integers(0, n, size=(int(rng.integers(1, 600)), 3))
        e = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
        e = e[e[:, 0] != e[:, 1]]
        e = np.unique(np.sort(e, axis=1), axis=0)
        flip = rng.random(len(e)) < 0.5
        e[flip] = e[flip][:, ::-1]
        e = e[rng.permutation(len(e))].astype(np.int32)
        picked = e[rng.random(len(e)) < rng.random()]
        extra = rng.integers(0, n, size=(int(rng.integers(0, 30)), 2))
        pairs = np.concatenate([picked, picked[: len(picked) // 3, ::-1], extra])
        want = {tuple(sorted(p)) for p in pairs.tolist()}
        expect = [tuple(sorted(x)) in want for x in e.tolist()]
        assert result_arrays.edge_flags(e, pairs, n).tolist() == expect, trial


def test_interpolate_group_membership_and_exactness(result_arrays):
    weight = np.array([0.3, 0.7, 0.0, 0.3, 1.0], np.float32)
    member = np.array([True, True, False, True, True])
    src = np.array([[0, 1, 2], [0, 1, 2], [2, 2, 2], [0, 3, 2], [4, 4, 4]])
    bary = np.array([[0.5, 0.5, 0.0], [0.2, 0.0, 0.8], [1 / 3, 1 / 3, 1 / 3],
                     [0.1, 0.6, 0.3], [0.3, 0.3, 0.4]], np.float32)   # as Plan.vertex_sources
    w, m = result_arrays.interpolate_group(weight, member, src, bary)
    assert m.tolist() == [True, True, False, True, True]
    assert np.allclose(w[:2], [0.5, 0.06])
    assert w[2] == 0.0
    assert np.isclose(w[3], 0.1 * 0.3 + 0.6 * 0.3)           # non-member corner counts as 0
    # Equal weights at every corner in use: exactly that weight, not a rounded sum.
    assert w[4] == np.float32(1.0)
    w2, m2 = result_arrays.interpolate_group(weight, member, np.array([[0, 3, 2]]),
                                             np.array([[0.25, 0.75, 0.0]]))
    assert m2.tolist() == [True] and w2[0] == np.float32(0.3)


def test_weight_batches(result_arrays):
    batches = result_arrays.weight_batches([4, 9, 2, 7], np.array([0.5, 1.0, 0.5, 0.25], np.float32))
    assert batches == [(0.25, [7]), (0.5, [4, 2]), (1.0, [9])]
    assert result_arrays.weight_batches([], []) == []
