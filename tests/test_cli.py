"""Command line (python3 -m smoothffd ...) and the sample data it ships.

make-lattice, info and the error paths are pure Python; deform needs the native core.
"""
import json
import re
import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT / "python" / "smoothffd" / "data"


def _import_pure(name):
    """Pure-Python submodules import without the native core (smoothffd/__init__.py)."""
    import importlib

    return importlib.import_module(f"smoothffd.{name}")


cli = _import_pure("cli")
io = _import_pure("io")
lattice_json = _import_pure("lattice_json")
metrics = _import_pure("metrics")


def run_main(argv, capsys):
    """main() in-process -> (exit status, stdout, stderr); argparse's SystemExit included."""
    try:
        rc = cli.main([str(a) for a in argv])
    except SystemExit as e:
        rc = e.code
    out, err = capsys.readouterr()
    return rc, out, err


# ---------------------------------------------------------------- example deformations

BOX = (np.array([-1.0, -2.0, 0.0]), np.array([1.0, 2.0, 4.0]))


def test_twist_rotates_ends_by_half_the_angle_each():
    lo, hi = BOX
    pts = np.array([[1.0, 0, 0], [1.0, 0, 4], [1.0, 0, 2]])
    out = cli.deform_points(pts, lo, hi, "twist", 90.0, axis=2)
    np.testing.assert_allclose(out[0], [np.cos(np.pi / 4), -np.sin(np.pi / 4), 0], atol=1e-15)
    np.testing.assert_allclose(out[1], [np.cos(np.pi / 4), np.sin(np.pi / 4), 4], atol=1e-15)
    np.testing.assert_allclose(out[2], pts[2], atol=1e-15)  # the middle does not turn
    # distances from the axis are kept
    q = np.random.default_rng(0).uniform(lo, hi, size=(20, 3))
    tq = cli.deform_points(q, lo, hi, "twist", 123.0, axis=2)
    np.testing.assert_allclose(np.hypot(tq[:, 0], tq[:, 1]), np.hypot(q[:, 0], q[:, 1]))
    np.testing.assert_array_equal(tq[:, 2], q[:, 2])


def test_bend_keeps_centre_and_axis_length_and_turns_the_ends():
    lo, hi = BOX
    z = np.linspace(0, 4, 41)
    axis_pts = np.stack([np.zeros_like(z), np.zeros_like(z), z], 1)
    out = cli.deform_points(axis_pts, lo, hi, "bend", 60.0, axis=2)
    np.testing.assert_allclose(out[20], [0, 0, 2], atol=1e-15)
    seg = np.linalg.norm(np.diff(out, axis=0), axis=1).sum()
    assert seg == pytest.approx(4.0, rel=1e-3)  # chord sum of a circular arc of length 4
    # end tangents turned by +-30 degrees, towards +x (the next axis after z)
    t_end = out[-1] - out[-2]
    assert np.degrees(np.arctan2(t_end[0], t_end[2])) == pytest.approx(30.0, abs=1.0)
    assert out[0, 0] > 0 and out[-1, 0] > 0
    np.testing.assert_array_equal(cli.deform_points(axis_pts, lo, hi, "bend", 0.0), axis_pts)


def test_bulge_scales_the_middle_only():
    lo, hi = BOX
    pts = np.array([[0.5, 0.5, 0.0], [0.5, 0.5, 2.0], [0.5, 0.5, 4.0]])
    out = cli.deform_points(pts, lo, hi, "bulge", 0.5, axis=2)
    np.testing.assert_allclose(out, [[0.5, 0.5, 0], [0.75, 0.75, 2], [0.5, 0.5, 4]])


def test_greville_grid_of_linear_lattice_is_uniform():
    g = cli.greville_grid([0, 0, 0], [1, 2, 3], (3, 4, 2), (1, 1, 1))
    np.testing.assert_allclose(g[:, 0, 0, 0], [0, 0.5, 1])
    np.testing.assert_allclose(g[0, :, 0, 1], [0, 2 / 3, 4 / 3, 2])
    g2 = cli.greville_grid([0, 0, 0], [1, 1, 1], (4, 4, 4), (2, 2, 2))
    np.testing.assert_allclose(g2[:, 0, 0, 0], [0, 0.25, 0.75, 1])  # knots 0 0 0 .5 1 1 1


def test_blender_lattice_doc_identity_points_equal_rest():
    doc = cli.make_lattice_doc(*BOX, (3, 1, 4), kind="blender")
    kind, kw = lattice_json.parse_lattice(doc)
    np.testing.assert_allclose(kw["points"], kw["rest_points"], atol=1e-15)
    m = kw["lattice_to_object"]
    corner = m[:3, :3] @ [0.5, 0.5, 0.5] + m[:3, 3]
    np.testing.assert_allclose(corner, BOX[1])


# ---------------------------------------------------------------- make-lattice / info

def test_make_lattice_from_sample_mesh(tmp_path, capsys):
    out = tmp_path / "l.json"
    rc, _, err = run_main(["make-lattice", "--bbox-of", DATA / "vase.obj", "--shape", 4, 5, 6,
                           "--degree", 2, 3, 2, "--bend", 30, "-o", out], capsys)
    assert rc == 0, err
    assert "write" in err and str(out) in err
    kind, kw = lattice_json.parse_lattice(json.loads(out.read_text()))
    assert kind == "bspline" and kw["control_points"].shape == (4, 5, 6, 3)
    assert kw["degree"] == (2, 3, 2)
    v = io.read_obj(DATA / "vase.obj").positions
    assert (kw["box_min"] < v.min(0)).all() and (kw["box_max"] > v.max(0)).all()


@pytest.mark.parametrize("box", [("-1e-3", "-2.5E+0", "-.5", "1e-3", "2", "5e-1"),
                                 ("-1", "-1.5", "-0", "1", "1.5", "1e0")])
def test_make_lattice_box_takes_negative_numbers_in_any_float_syntax(tmp_path, capsys, box):
    out = tmp_path / "l.json"
    rc, _, err = run_main(["make-lattice", "--box", *box, "--shape", 3, 3, 3, "-o", out], capsys)
    assert rc == 0, err
    _, kw = lattice_json.parse_lattice(json.loads(out.read_text()))
    np.testing.assert_allclose(kw["box_min"], [float(v) for v in box[:3]])
    np.testing.assert_allclose(kw["box_max"], [float(v) for v in box[3:]])


def test_info_on_mesh_and_lattice(capsys):
    rc, out, _ = run_main(["info", DATA / "vase.obj"], capsys)
    assert rc == 0
    assert "vertices    480" in out and "956 triangles" in out
    assert "split at 96 vertices" in out  # 4 sharp rings (rim x2, bottom, floor) x 24
    assert "0 boundary, 0 non-manifold, 0 misoriented" in out and "volume" in out
    rc, out, _ = run_main(["info", DATA / "vase_twist.json"], capsys)
    assert rc == 0 and "bspline 4x4x5" in out


def test_info_reads_a_utf16_obj_as_its_utf8_twin(tmp_path, capsys):
    """A UTF-16 OBJ with its byte order mark (as Windows tools save it) was 'the mesh has no
    vertices'."""
    text = (DATA / "vase.obj").read_text(encoding="utf-8")
    utf16 = tmp_path / "vase16.obj"
    utf16.write_bytes(b"\xff\xfe" + text.encode("utf-16-le"))
    rc8, out8, _ = run_main(["info", DATA / "vase.obj"], capsys)
    rc16, out16, _ = run_main(["info", utf16], capsys)
    assert rc8 == rc16 == 0
    assert out16.splitlines()[1:] == out8.splitlines()[1:]   # all but the "file" line


@pytest.mark.parametrize(
    "argv, pattern",
    [
        (["info", "{tmp}/missing.obj"], "missing.obj: no such file"),
        (["info", "{tmp}/bad.obj"], r"bad\.obj:3: face needs at least 3 corners"),
        (["info", "{tmp}/bad.json"], r"bad\.json: key 'version'"),
        (["make-lattice", "--box", 0, 0, 0, 1, 1, 1, "--shape", 2, 2, 2, "-o", "{tmp}/x.json"],
         r"--shape: degree 2 needs at least 3 points on axis x, got 2"),
        (["make-lattice", "--box", 0, 0, 0, 1, -1, 1, "-o", "{tmp}/x.json"], "--box"),
        (["make-lattice", "--bbox-of", "{tmp}/bad.obj", "-o", "{tmp}/x.json"], r"bad\.obj:3"),
    ],
)
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv, pattern):
    (tmp_path / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nf 1 2\n")
    (tmp_path / "bad.json").write_text('{"format": "smoothffd-lattice", "version": 9}')
    rc, out, err = run_main([str(a).replace("{tmp}", str(tmp_path)) for a in argv], capsys)
    assert rc == 2
    last = err.strip().splitlines()[-1]
    assert last.startswith("smoothffd: error: ")
    assert re.search(pattern, last), last


def test_usage_errors_exit_2(capsys):
    rc, _, err = run_main(["make-lattice", "--twist", "10", "--bend", "5", "--box", *[0] * 6, "-o", "x"], capsys)
    assert rc == 2 and "not allowed with" in err
    rc, _, _ = run_main(["deform", "x.obj"], capsys)  # --lattice and -o missing
    assert rc == 2


# ---------------------------------------------------------------- deform (needs the core)

@pytest.fixture
def core():
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    import smoothffd

    return smoothffd


def test_deform_sample_end_to_end(core, tmp_path, capsys):
    out = tmp_path / "out.obj"
    rc, stdout, err = run_main(["deform", DATA / "vase.obj", "--lattice", DATA / "vase_twist.json",
                                "-o", out, "--level", 3, "--device", "cpu", "--stats"], capsys)
    assert rc == 0, err
    for stage in ("read", "plan", "deform", "write"):
        assert re.search(rf"smoothffd: {stage}\s.*\(\d+\.\d\d s\)", err), err
    stats = json.loads(stdout)
    assert stats["level"] == 3 and stats["device"] == "cpu"
    d = io.read_obj(out)
    tri = d.corner_vertices.reshape(-1, 3)
    assert len(tri) == stats["output_triangles"]
    assert metrics.is_watertight(tri)
    assert d.corner_normals is not None and d.uvs is not None
    # the first V output vertices are the deformed input vertices: exact FFD at the vertices
    src = io.read_obj(DATA / "vase.obj")
    lat = lattice_json.load_lattice(DATA / "vase_twist.json")
    want = lat.evaluate(src.positions)[0]
    assert metrics.geometry_error(d.positions[: len(want)], want).max < 1e-5


def test_deform_with_identity_lattice_keeps_vertices(core, tmp_path, capsys):
    lat = tmp_path / "id.json"
    assert run_main(["make-lattice", "--bbox-of", DATA / "vase.obj", "-o", lat, "-q"], capsys)[0] == 0
    # cross-check the pure-Python Greville grid against the core's identity lattice
    doc = json.loads(lat.read_text())
    ident = core.BSplineLattice.identity(doc["box_min"], doc["box_max"], shape=doc["shape"])
    np.testing.assert_allclose(np.reshape(doc["control_points"], (5, 5, 5, 3)), ident.control_points, atol=1e-14)
    out = tmp_path / "o.obj"
    rc, _, err = run_main(["deform", DATA / "vase.obj", "--lattice", lat, "-o", out, "--level", 2, "-q"], capsys)
    assert rc == 0 and err == ""
    src = io.read_obj(DATA / "vase.obj").positions
    np.testing.assert_allclose(io.read_obj(out).positions[: len(src)], src, atol=1e-6)


def test_deform_bad_inputs_exit_2(core, tmp_path, capsys):
    rc, _, err = run_main(["deform", DATA / "vase.obj", "--lattice", tmp_path / "none.json", "-o", tmp_path / "o.obj"], capsys)
    assert rc == 2 and "none.json: no such file" in err
    rc, _, err = run_main(["deform", DATA / "vase.obj", "--lattice", DATA / "vase_twist.json",
                           "-o", tmp_path / "o.obj", "--level", 0], capsys)
    assert rc == 2 and "level" in err.splitlines()[-1]
    assert len(err.strip().splitlines()[-1].split("\n")) == 1


def test_python_dash_m_runs(core, tmp_path):
    out = tmp_path / "bend.obj"
    import smoothffd  # the subprocess imports the same package as this process
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(smoothffd.__file__)))
    r = subprocess.run([sys.executable, "-m", "smoothffd", "deform", str(DATA / "vase.obj"), "--lattice",
                        str(DATA / "vase_bend.json"), "-o", str(out), "--level", "2"], env=env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert out.stat().st_size > 0
    r = subprocess.run([sys.executable, "-m", "smoothffd", "info", str(tmp_path / "nope.obj")], env=env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1


def test_sample_data_is_small_and_sharp():
    for f in DATA.iterdir():
        assert f.stat().st_size < 200_000, f
    d = io.read_obj(DATA / "vase.obj")
    tri_count = int((np.diff(d.face_offsets) - 2).sum())
    assert 500 <= tri_count <= 1000
    # split normals: some vertex carries corners with different normals (the sharp rim)
    cv, n = d.corner_vertices, d.corner_normals
    order = np.lexsort((n[:, 2], n[:, 1], n[:, 0], cv))
    diff = (np.diff(cv[order]) == 0) & (np.abs(np.diff(n[order], axis=0)).max(1) > 0.5)
    assert diff.any()


def test_deform_blender_lattice_and_error_report(core, tmp_path, capsys):
    lat = tmp_path / "bl.json"
    rc, _, err = run_main(["make-lattice", "--bbox-of", DATA / "vase.obj", "--kind", "blender",
                           "--shape", 3, 3, 4, "--interpolation", "CATMULL_ROM", "--twist", 45, "-o", lat], capsys)
    assert rc == 0, err
    out = tmp_path / "o.obj"
    rc, _, err = run_main(["deform", DATA / "vase.obj", "--lattice", lat, "-o", out, "--level", 2, "--errors"], capsys)
    assert rc == 0, err
    assert re.search(r"smoothffd: check .*geometry mean .* volume error", err), err
    lattice = lattice_json.load_lattice(lat)
    assert isinstance(lattice, core.BlenderLattice)
    src = io.read_obj(DATA / "vase.obj").positions
    want = lattice.evaluate(src)[0]
    assert metrics.geometry_error(io.read_obj(out).positions[: len(src)], want).max < 1e-5


def test_deform_estimates_the_fit_error(core, tmp_path, capsys):
    lat = tmp_path / "l.json"
    rc, _, err = run_main(["make-lattice", "--bbox-of", DATA / "vase.obj", "--twist", 60, "-o", lat], capsys)
    assert rc == 0, err
    out = tmp_path / "o.obj"
    rc, stdout, err = run_main(["deform", DATA / "vase.obj", "--lattice", lat, "-o", out, "--level", 2,
                                "--estimate-error", "--stats"], capsys)
    assert rc == 0, err
    m = re.search(r"fit error at most (\S+) \((\S+) of the mesh's size, face (\d+)\), normals about (\S+) deg", err)
    assert m, err
    stats = json.loads(stdout)
    mesh = io.read_obj_mesh(DATA / "vase.obj")
    fe, fn = core.Deformer(mesh, lattice_json.load_lattice(lat), level=2, device="cpu").estimate_errors()
    assert float(m.group(1)) == pytest.approx(float(fe.max()), rel=1e-3)
    assert int(m.group(3)) == int(np.argmax(fe))
    assert stats["max_face_error"] == pytest.approx(float(fe.max()), rel=1e-6)
    assert stats["max_face_normal_error_deg"] == pytest.approx(float(fn.max()), rel=1e-6)
    assert fe.max() > 0


def test_deform_to_a_tolerance(core, tmp_path, capsys):
    """--tolerance T --relative: the adaptive mesh, its bound in the progress line and stats, the
    same triangles as the package's Deformer with that tolerance."""
    lat = tmp_path / "l.json"
    rc, _, err = run_main(["make-lattice", "--bbox-of", DATA / "vase.obj", "--twist", 60, "-o", lat], capsys)
    assert rc == 0, err
    out = tmp_path / "o.obj"
    rc, stdout, err = run_main(["deform", DATA / "vase.obj", "--lattice", lat, "-o", out, "--tolerance", 1e-3,
                                "--relative", "--device", "cpu", "--stats"], capsys)
    assert rc == 0, err
    m = re.search(r"tessellation bound (\S+) \(every triangle within it\)", err)
    assert m, err
    mesh = io.read_obj_mesh(DATA / "vase.obj")
    size = float(np.linalg.norm(np.ptp(mesh.positions, axis=0)))
    res = core.Deformer(mesh, lattice_json.load_lattice(lat), tolerance=1e-3 * size, device="cpu").deform()
    stats = json.loads(stdout)
    assert stats["output_triangles"] == len(res.triangles) and stats["tolerance_met"]
    assert float(m.group(1)) == pytest.approx(res.stats["max_tessellation_bound"], rel=2e-3)  # 3 digits
    assert 0 < res.stats["max_tessellation_bound"] <= 1e-3 * size
    got = io.read_obj_mesh(out)
    assert got.face_count == len(res.triangles)
    assert "--tolerance 0.001 --relative" in open(out).readline()
    uniform = core.Deformer(mesh, lattice_json.load_lattice(lat), level=10, device="cpu")
    assert len(res.triangles) < uniform.plan.output_triangles


# ---------------------------------------------------------------- one clear line, no traceback

@pytest.mark.parametrize("argv,needle", [
    (["--degree", 9, 9, 9], "--degree: each degree must be between 1 and 5, got 9"),
    (["--shape", 3, 3, 3, "--degree", 3, 3, 3], "--shape: degree 3 needs at least 4 points on axis x, got 3"),
])
def test_make_lattice_explains_bad_shape_and_degree(argv, needle, tmp_path, capsys):
    rc, _, err = run_main(["make-lattice", "--box", 0, 0, 0, 1, 1, 1, *argv, "-o", tmp_path / "l.json"], capsys)
    assert rc == 2 and needle in err.strip().splitlines()[-1] and "Traceback" not in err, err
    assert not (tmp_path / "l.json").exists()


@pytest.mark.parametrize("doc,needle", [
    ('{"format": "smoothffd-lattice", "version": 1, "kind": ["bspline"], "shape": 3}',
     "'kind': expected 'bspline' or 'blender'"),
    ('{"format": "smoothffd-lattice", "version": 1, "kind": "blender", "shape": [1, 1, 1], "points": [[1'
     + "0" * 400 + ', 0, 0]]}', "'points[0]': expected [x, y, z] finite numbers"),
])
def test_lattice_json_odd_values_are_clear_errors(doc, needle, tmp_path, capsys):
    p = tmp_path / "l.json"
    p.write_text(doc)
    rc, _, err = run_main(["info", p], capsys)
    last = err.strip().splitlines()[-1]
    assert rc == 2 and needle in last and "Traceback" not in err and len(last) < 300, err[-500:]


def test_truncated_gzip_obj_is_a_clear_error(tmp_path, capsys):
    import gzip
    whole = gzip.compress((DATA / "vase.obj").read_bytes())
    p = tmp_path / "cut.obj.gz"
    p.write_bytes(whole[: len(whole) // 2])
    rc, _, err = run_main(["info", p], capsys)
    assert rc == 2 and "damaged or truncated gzip file" in err and "Traceback" not in err, err[-500:]


def test_errors_on_an_open_mesh(core, tmp_path, capsys):
    """--errors on a mesh with a boundary: geometry and normal errors, no volume (it was a
    ZeroDivisionError traceback)."""
    p = tmp_path / "open.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\n")
    lat = tmp_path / "l.json"
    assert run_main(["make-lattice", "--bbox-of", p, "-o", lat], capsys)[0] == 0
    rc, _, err = run_main(["deform", p, "--lattice", lat, "-o", tmp_path / "o.obj", "--level", 2,
                           "--errors"], capsys)
    assert rc == 0 and "no volume error (the mesh is not closed)" in err, err[-800:]
