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
