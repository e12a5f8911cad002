"""Lattice JSON format (smoothffd.lattice_json): validation and round trips.

Validation and (de)serialization are pure Python; the round trips through real lattice
objects need the native core and are skipped without it.
"""
import copy
import json
import pathlib
import re
from types import SimpleNamespace

import numpy as np
import pytest


def _import_pure(name):
    """Pure-Python submodules import without the native core (smoothffd/__init__.py)."""
    import importlib

    return importlib.import_module(f"smoothffd.{name}")


lj = _import_pure("lattice_json")

DOCS = pathlib.Path(__file__).resolve().parents[1] / "docs" / "formats.md"


def bspline_doc(shape=(3, 3, 4), degree=(2, 2, 2)):
    g = np.stack(np.meshgrid(*[np.linspace(0, 1, n) for n in shape], indexing="ij"), -1)
    return {"format": "smoothffd-lattice", "version": 1, "kind": "bspline",
            "shape": list(shape), "degree": list(degree), "knots": None,
            "box_min": [0, 0, 0], "box_max": [1, 1, 1],
            "control_points": g.reshape(-1, 3).tolist()}


def blender_doc(shape=(2, 3, 1)):
    rest = lj.blender_rest_grid(shape)
    return {"format": "smoothffd-lattice", "version": 1, "kind": "blender",
            "shape": list(shape), "interpolation": ["LINEAR", "CARDINAL", "BSPLINE"],
            "lattice_to_object": np.diag([2.0, 3.0, 4.0, 1.0]).tolist(), "strength": 0.5,
            "rest_points": rest.reshape(-1, 3).tolist(),
            "points": (rest * 1.25 + 0.1).reshape(-1, 3).tolist()}


def test_parse_bspline_point_order_is_w_fastest():
    doc = bspline_doc(shape=(3, 3, 4))
    kind, kw = lj.parse_lattice(doc)
    assert kind == "bspline"
    cp = kw["control_points"]
    assert cp.shape == (3, 3, 4, 3)
    np.testing.assert_array_equal(cp[1, 2, 3], doc["control_points"][(1 * 3 + 2) * 4 + 3])
    assert kw["degree"] == (2, 2, 2) and kw["knots"] is None
    np.testing.assert_array_equal(kw["box_max"], [1, 1, 1])


def test_parse_defaults():
    doc = bspline_doc()
    for k in ("degree", "knots", "box_min", "box_max"):
        del doc[k]
    _, kw = lj.parse_lattice(doc)
    assert kw["degree"] == (2, 2, 2) and kw["box_min"] is None and kw["knots"] is None
    doc = blender_doc()
    for k in ("rest_points", "interpolation", "lattice_to_object", "strength"):
        del doc[k]
    _, kw = lj.parse_lattice(doc)
    np.testing.assert_array_equal(kw["rest_points"], lj.blender_rest_grid((2, 3, 1)))
    assert kw["interpolation"] == ("BSPLINE",) * 3 and kw["strength"] == 1.0
    np.testing.assert_array_equal(kw["lattice_to_object"], np.eye(4))


def test_blender_rest_grid_matches_blender_default():
    g = lj.blender_rest_grid((3, 1, 2))
    np.testing.assert_array_equal(g[:, 0, 0, 0], [-0.5, 0, 0.5])
    np.testing.assert_array_equal(g[0, :, 0, 1], [0])  # one-point axis at 0
    np.testing.assert_array_equal(g[0, 0, :, 2], [-0.5, 0.5])


def test_docs_example_parses():
    blocks = re.findall(r"```json\n(.*?)```", DOCS.read_text(), re.S)
    assert blocks
    kind, kw = lj.parse_lattice(json.loads(blocks[0]))
    assert kind == "bspline" and kw["control_points"][1, 0, 1, 2] == 1.5


def mutate(doc, path, value):
    d = copy.deepcopy(doc)
    target = d
    for p in path[:-1]:
        target = target[p]
    if value is KeyError:
        del target[path[-1]]
    else:
        target[path[-1]] = value
    return d


@pytest.mark.parametrize(
    "maker, path, value, key",
    [
        (bspline_doc, ["format"], "other", "format"),
        (bspline_doc, ["version"], 2, "version"),
        (bspline_doc, ["version"], "1", "version"),
        (bspline_doc, ["kind"], "nurbs", "kind"),
        (bspline_doc, ["knot"], None, "knot"),
        (bspline_doc, ["shape"], [3, 3], "shape"),
        (bspline_doc, ["shape"], [3, 3, 5], "control_points"),
        (bspline_doc, ["degree"], [2, 6, 2], "degree[1]"),
        (bspline_doc, ["degree"], [2, 2, 4], "shape[2]"),
        (bspline_doc, ["knots"], [[0] * 6, [0] * 6, [0] * 6], "knots[0]"),
        (bspline_doc, ["knots"], [[0, 0, 0, 1, 1, 1], [0, 0, 0, 1, 1, 1], [0, 0, 0, 0.5, 0.4, 1, 1, 1]], "knots[2]"),
        (bspline_doc, ["box_min"], [0, 0], "box_min"),
        (bspline_doc, ["box_max"], [1, 0, 1], "box_max"),
        (bspline_doc, ["control_points", 5], [0, 0, "x"], "control_points[5]"),
        (bspline_doc, ["control_points", 7], [0, 0], "control_points[7]"),
        (bspline_doc, ["control_points"], KeyError, "control_points"),
        (blender_doc, ["interpolation"], ["LINEAR", "CUBIC", "BSPLINE"], "interpolation"),
        (blender_doc, ["lattice_to_object", 3], [0, 0, 1, 1], "lattice_to_object"),
        (blender_doc, ["lattice_to_object"], [[1, 0, 0]], "lattice_to_object"),
        (blender_doc, ["strength"], True, "strength"),
        (blender_doc, ["points"], KeyError, "points"),
        (blender_doc, ["shape"], [2, 3, 0], "shape[2]"),
        (blender_doc, ["degree"], [2, 2, 2], "degree"),  # a B-spline key on a Blender lattice
    ],
)
def test_validation_names_the_key(maker, path, value, key):
    with pytest.raises(ValueError) as exc:
        lj.parse_lattice(mutate(maker(), path, value), "L.json")
    msg = str(exc.value)
    assert msg.startswith(f"L.json: key '{key}':"), msg


def test_load_reports_json_syntax_line(tmp_path):
    p = tmp_path / "bad.json"
    p.write_text('{\n  "format": "smoothffd-lattice",\n  "version": 1,\n  oops\n}\n')
    with pytest.raises(ValueError, match=r"bad\.json:4: invalid JSON"):
        lj.load_lattice(p)


def test_dict_round_trip_through_text_is_exact(tmp_path):
    rng = np.random.default_rng(0)
    doc = bspline_doc()
    doc["control_points"] = rng.normal(size=(36, 3)).tolist()
    doc["knots"] = [[0, 0, 0, 0.3, 1, 1], [0, 0, 0, 0.7, 1, 1], [0, 0, 0, 0.1, 1 / 3, 1, 1]]
    p = tmp_path / "l.json"
    lj.save_lattice(p, doc)
    back = json.loads(p.read_text())
    assert back == json.loads(json.dumps(doc))
    # one point per line keeps diffs of edited lattices readable
    assert p.read_text().count("\n") > 36


def test_save_from_attributes_without_core(tmp_path):
    # save_lattice only reads the documented attributes, so a stand-in object works
    cp = np.stack(np.meshgrid(*[np.linspace(0, 1, 3)] * 3, indexing="ij"), -1)
    fake = SimpleNamespace(control_points=cp, degree=(2, 2, 2), knots=None,
                           box_min=np.zeros(3), box_max=np.ones(3))
    p = tmp_path / "f.json"
    lj.save_lattice(p, fake, name="fake")
    kind, kw = lj.parse_lattice(json.loads(p.read_text()))
    assert kind == "bspline"
    np.testing.assert_array_equal(kw["control_points"], cp)
    fake_b = SimpleNamespace(rest_points=cp, points=cp + 1, interpolation=("LINEAR",) * 3,
                             lattice_to_object=np.eye(4), strength=0.25)
    lj.save_lattice(p, fake_b)
    kind, kw = lj.parse_lattice(json.loads(p.read_text()))
    assert kind == "blender" and kw["strength"] == 0.25
    np.testing.assert_array_equal(kw["points"], cp + 1)
    with pytest.raises(TypeError, match="lattice"):
        lj.save_lattice(p, object())


def test_save_refuses_non_finite(tmp_path):
    cp = np.zeros((2, 2, 2, 3))
    cp[1, 1, 1, 0] = np.nan
    fake = SimpleNamespace(control_points=cp, degree=(1, 1, 1), knots=None,
                           box_min=np.zeros(3), box_max=np.ones(3))
    with pytest.raises(ValueError, match="control_points"):
        lj.save_lattice(tmp_path / "n.json", fake)


@pytest.fixture
def core():
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    import smoothffd

    return smoothffd


def test_bspline_object_round_trip(core, tmp_path):
    rng = np.random.default_rng(4)
    knots = [np.array([0, 0, 0.5, 1, 1.0]), np.array([0, 0, 0, 0.25, 1, 1, 1]), np.array([0, 0, 0, 0, 1, 1, 1, 1.0])]
    lat = core.BSplineLattice(rng.normal(size=(3, 4, 4, 3)), degree=(1, 2, 3), knots=knots,
                              box_min=[-1, -2, -3], box_max=[1, 2, 3])
    p = tmp_path / "b.json"
    lj.save_lattice(p, lat)
    back = lj.load_lattice(p)
    assert isinstance(back, core.BSplineLattice)
    assert back.structure_key() == lat.structure_key()
    np.testing.assert_array_equal(back.control_points, lat.control_points)
    pts = rng.uniform(-1.5, 1.5, size=(50, 3))
    np.testing.assert_array_equal(back.evaluate(pts)[0], lat.evaluate(pts)[0])


def test_identity_bspline_round_trip_keeps_default_knots(core, tmp_path):
    lat = core.BSplineLattice.identity([0, 0, 0], [1, 2, 3], shape=(4, 5, 6))
    lj.save_lattice(tmp_path / "i.json", lat)
    assert json.loads((tmp_path / "i.json").read_text())["knots"] is None
    back = lj.load_lattice(tmp_path / "i.json")
    assert back.structure_key() == lat.structure_key()


def test_blender_object_round_trip(core, tmp_path):
    _, kw = lj.parse_lattice(blender_doc())
    lat = core.BlenderLattice(**kw)
    p = tmp_path / "bl.json"
    lj.save_lattice(p, lat)
    back = lj.load_lattice(p)
    assert isinstance(back, core.BlenderLattice)
    assert back.structure_key() == lat.structure_key()
    np.testing.assert_array_equal(back.points, lat.points)
    assert back.strength == 0.5
    pts = np.random.default_rng(5).uniform(-2, 2, size=(40, 3))
    np.testing.assert_array_equal(back.evaluate(pts)[0], lat.evaluate(pts)[0])


def test_constructor_errors_carry_the_file_name(core, tmp_path):
    doc = blender_doc()
    doc["lattice_to_object"] = [[0, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    p = tmp_path / "sing.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"sing\.json: .*lattice_to_object"):
        lj.load_lattice(p)
