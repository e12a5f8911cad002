"""Unit tests of addon/smooth_ffd/inputs.py (settings and Blender data -> the core's inputs;
numpy only, no bpy). The `inputs` fixture (conftest.py) loads it by path."""
import numpy as np
import pytest


def test_lattice_grid_u_fastest(inputs):
    nu, nv, nw = 2, 3, 4
    flat = np.array([(u, v, w) for w in range(nw) for v in range(nv) for u in range(nu)], float)
    g = inputs.lattice_grid(flat, (nu, nv, nw))
    assert g.shape == (nu, nv, nw, 3)
    assert tuple(g[1, 2, 3]) == (1, 2, 3)


def test_lattice_weight_grid_u_fastest(inputs):
    """Point weights in Blender's order land where lattice_grid puts the points."""
    nu, nv, nw = 2, 3, 4
    flat = np.array([100 * u + 10 * v + w for w in range(nw) for v in range(nv) for u in range(nu)], float)
    g = inputs.lattice_weight_grid(flat, (nu, nv, nw))
    assert g.shape == (nu, nv, nw) and g.flags.c_contiguous
    assert g[1, 2, 3] == 123 and g[0, 1, 2] == 12
    pts = np.stack([flat] * 3, axis=1)
    assert np.array_equal(inputs.lattice_grid(pts, (nu, nv, nw))[..., 0], g)


def test_lattice_to_object(addon_core):
    core, inputs = addon_core.core, addon_core.inputs
    m = np.diag([2.0, 2.0, 2.0, 1.0]); m[:3, 3] = (1, 0, 0)
    lat = np.eye(4); lat[:3, 3] = (3, 0, 0)
    l2o = core.lattice_to_object(m, lat)
    assert np.allclose(l2o @ [0, 0, 0, 1], [1, 0, 0, 1])   # (3 - 1) / 2
    with pytest.raises(inputs.SmoothFFDError, match="singular"):
        core.lattice_to_object(np.diag([0.0, 1, 1, 1]), lat)
    # The core's check (relative to the largest entry), not a threshold of the add-on's own:
    # a tiny uniform scale is fine, one axis 1e-13 of the others is singular.
    assert np.allclose(core.lattice_to_object(np.diag([1e-20, 1e-20, 1e-20, 1.0]), np.eye(4)),
                       np.diag([1e20, 1e20, 1e20, 1.0]))
    with pytest.raises(inputs.SmoothFFDError, match="singular"):
        core.lattice_to_object(np.diag([1.0, 1.0, 1e-13, 1.0]), lat)


def test_vertex_weights(inputs):
    w = inputs.vertex_weights(4, 1, [0, 1, 1, 3], [1, 0, 1, 1], [0.5, 0.9, 0.25, 2.0], False)
    assert np.allclose(w, [0.5, 0.25, 0, 1])
    wi = inputs.vertex_weights(4, 1, [0, 1, 1, 3], [1, 0, 1, 1], [0.5, 0.9, 0.25, 2.0], True)
    assert np.allclose(wi, [0.5, 0.75, 1, 0])
    assert inputs.vertex_weights(4, None, [], [], [], False) is None


def test_parse(addon_core):
    """Levels and backends as the core defines them (smoothffd.MAX_LEVEL, smoothffd.DEVICES)."""
    core, inputs, sf = addon_core.core, addon_core.inputs, addon_core.core.smoothffd()
    assert sf.DEVICES == ("auto", "cpu", "cuda")
    assert core.parse_backend(" CPU ") == "cpu"
    assert core.parse_backend("CUDA") == "cuda"       # a menu item's name (4.1+)
    assert core.parse_backend("") == "auto"
    with pytest.raises(inputs.SmoothFFDError, match="auto, cpu, cuda"):
        core.parse_backend("gpu")
    assert core.parse_level(3, "x") == 3
    assert core.parse_level(sf.MAX_LEVEL, "x") == sf.MAX_LEVEL == 64
    for bad in (0, sf.MAX_LEVEL + 1):
        with pytest.raises(inputs.SmoothFFDError, match=f"between 1 and {sf.MAX_LEVEL}"):
            core.parse_level(bad, "x")


def test_digest(inputs):
    a = np.arange(6, dtype=np.float32)
    assert inputs.digest(a, 1) == inputs.digest(a.copy(), 1)
    assert inputs.digest(a, 1) != inputs.digest(a.astype(np.float64), 1)


def test_missing_core_says_what_to_install(addon_core, monkeypatch):
    """Without the core (no bundled copy, no installed package) the add-on's import error
    names this Python and this platform, so the user knows which package to get."""
    import platform
    import sys

    core, state = addon_core.core, addon_core.state
    monkeypatch.setitem(sys.modules, "smoothffd", None)   # `import smoothffd` raises ImportError
    loaded, state.core_module[0] = state.core_module[0], None
    try:
        with pytest.raises(ImportError) as e:
            core.smoothffd()
    finally:
        state.core_module[0] = loaded
    msg = str(e.value)
    assert "cannot import the smoothffd core" in msg
    assert f"Python {sys.version_info[0]}.{sys.version_info[1]}, {platform.system()} {platform.machine()}" in msg
