"""smoothffd.metrics.quality and its parts (pure numpy), and the `quality` command."""
import importlib
import os
import types

import numpy as np
import pytest

metrics = importlib.import_module("smoothffd.metrics")
HERE = os.path.dirname(os.path.abspath(__file__))
CORPUS = os.path.join(HERE, "data", "real")


def _mesh(positions, faces, normals=None):
    """A duck-typed smoothffd.Mesh (metrics only reads these fields)."""
    cv = np.concatenate([np.asarray(f) for f in faces])
    fo = np.concatenate([[0], np.cumsum([len(f) for f in faces])])
    return types.SimpleNamespace(positions=np.asarray(positions, float), corner_vertices=cv,
                                 face_offsets=fo, corner_normals=normals)


def test_polygon_normals_newell():
    # A non-planar quad: Newell's normal is the cross product of its diagonals.
    p = np.array([[0, 0, 0], [1, 0, 0.2], [1, 1, 0], [0, 1, 0.3]], float)
    n = metrics.polygon_normals(p, [0, 1, 2, 3], [0, 4])
    np.testing.assert_allclose(n[0], np.cross(p[2] - p[0], p[3] - p[1]), atol=1e-15)
    t = metrics.polygon_normals(p, [0, 1, 2], [0, 3])
    np.testing.assert_allclose(t[0], np.cross(p[1] - p[0], p[2] - p[0]), atol=1e-15)


def test_flat_faces():
    p = np.array([[0, 0, 0], [1, 0, 0.2], [1, 1, 0], [0, 1, 0.3], [2, 0, 0]], float)
    fn = metrics.polygon_normals(p, [0, 1, 2, 3], [0, 4])[0]
    fn /= np.linalg.norm(fn)
    tn = np.cross(p[4] - p[1], p[2] - p[1])
    tn /= np.linalg.norm(tn)
    flat = _mesh(p, [[0, 1, 2, 3], [1, 4, 2]], np.array([fn] * 4 + [tn] * 3))
    assert metrics.flat_faces(flat).tolist() == [True, True]
    tilted = np.array([fn] * 3 + [fn + [0.1, 0, 0]] + [tn] * 3)
    assert metrics.flat_faces(_mesh(p, [[0, 1, 2, 3], [1, 4, 2]], tilted)).tolist() == [False, True]
    # Without normals a face is flat where the smooth vertex normals equal its own: none here.
    assert not metrics.flat_faces(_mesh(p, [[0, 1, 2, 3], [1, 4, 2]])).any()


def test_triangle_shapes():
    p = np.array([[0, 0, 0], [1, 0, 0], [0.5, 3 ** 0.5 / 2, 0], [0, 1, 0], [2, 0, 0]], float)
    area, ang, asp = metrics.triangle_shapes(p, [[0, 1, 2], [0, 1, 3], [0, 1, 4]])
    np.testing.assert_allclose(area[:2], [3 ** 0.5 / 4, 0.5])
    np.testing.assert_allclose(ang[:2], [60, 45])
    np.testing.assert_allclose(asp[0], 1.0)
    np.testing.assert_allclose(asp[1], 2 * 3 ** 0.5 / 2)  # hypotenuse^2 sqrt(3) / (4 * 1/2)
    assert area[2] == 0 and asp[2] == np.inf and ang[2] == 0


def test_quality_counts_reversed_tiny_and_flat_deviation():
    # Tetrahedron, outward; one output triangle flipped, one vertex moved off its face.
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    tris = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    mesh = _mesh(p, tris)
    fn = metrics.polygon_normals(p, tris.ravel(), np.arange(0, 13, 3))
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    mesh.corner_normals = np.repeat(fn, 3, axis=0)  # flat shaded: every face flat
    out = p.copy()
    res = types.SimpleNamespace(positions=out, triangles=tris.copy(), face_index=np.arange(4),
                                corner_normals=np.repeat(fn[:, None], 3, axis=1),
                                rest_positions=p.copy())
    q = metrics.quality(res, mesh)
    assert (q.reversed, q.degenerate, q.tiny, q.flat_faces, q.flat_deviation, q.flat_slide) == \
        (0, 0, 0, 4, 0.0, 0.0)
    assert q.watertight and q.volume_change == 0.0 and q.against_face == 0
    assert q.min_angle == pytest.approx(45) and q.input_min_angle is None
    res.corner_normals = res.corner_normals.copy()
    res.corner_normals[1] *= -1
    out[3] = [0, 0, 1.1]
    q = metrics.quality(res, mesh, input_triangles=tris)
    assert q.reversed == 1
    # off the planes: 0.1 along z is 0.1 / sqrt(3) off face (1, 2, 3), in the planes x = 0 and
    # y = 0; relative to the diagonal sqrt(3)
    assert q.flat_deviation == pytest.approx(0.1 / 3)
    assert q.flat_slide == pytest.approx(0.1 / np.sqrt(3))
    assert q.volume_change == pytest.approx(0.1)
    assert q.input_min_angle == pytest.approx(45)
    with pytest.raises(ValueError, match="corner_normals"):
        metrics.quality(types.SimpleNamespace(corner_normals=None), mesh)


def test_quality_command(capsys):
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    from smoothffd import cli

    assert cli.main(["quality", "-q", os.path.join(CORPUS, "cube.obj"), "--levels", "1", "2",
                     "--device", "cpu", "--twist", "30"]) == 0
    out = capsys.readouterr().out
    assert "6 faces, 6 flat" in out and "twist 30" in out
    assert len([ln for ln in out.splitlines() if ln.split()[:1] in (["1"], ["2"])]) == 2
    assert cli.main(["quality", "-q", os.path.join(CORPUS, "cube.obj"), "--levels", "1",
                     "--device", "cpu", "--json"]) == 0
    import json

    rows = json.loads(capsys.readouterr().out)
    assert rows[0]["level"] == 1 and rows[0]["reversed"] == 0 and rows[0]["watertight"]
