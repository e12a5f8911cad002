"""Regression tests for the edge cases the fuzzers reach (docs/robustness.md, "Edge cases the fuzzers reach").

native/fuzz/fuzz_lattice_json.py, fuzz_cli.py and fuzz_bindings.py run in scripts/fuzz.sh; each
case below is one of their findings, reduced.
"""
import json
import math
import subprocess
import sys
import tracemalloc
import warnings

import numpy as np
import pytest

import smoothffd
from smoothffd import _core as core
from smoothffd import cli, lattice_json


def _doc_file(tmp_path, doc_or_text):
    p = tmp_path / "l.json"
    p.write_text(doc_or_text if isinstance(doc_or_text, str) else json.dumps(doc_or_text))
    return p


def _blender_doc(**changes):
    doc = {"format": "smoothffd-lattice", "version": 1, "kind": "blender", "shape": [2, 2, 2],
           "points": (lattice_json.blender_rest_grid((2, 2, 2)) * 1.1).reshape(-1, 3).tolist()}
    doc.update(changes)
    return doc


def _bspline_doc(**changes):
    g = np.stack(np.meshgrid(*[np.linspace(0, 1, 3)] * 3, indexing="ij"), -1)
    doc = {"format": "smoothffd-lattice", "version": 1, "kind": "bspline", "shape": [3, 3, 3],
           "degree": [2, 2, 2], "box_min": [0, 0, 0], "box_max": [1, 1, 1],
           "control_points": g.reshape(-1, 3).tolist()}
    doc.update(changes)
    return doc


def test_deeply_nested_lattice_json_is_a_value_error(tmp_path):
    """'[[[[...' deeper than the recursion limit raised RecursionError from json.loads."""
    p = _doc_file(tmp_path, "[" * 100000)
    with pytest.raises(ValueError, match="nested too deeply"):
        lattice_json.load_lattice(p)


@pytest.mark.parametrize("doc, needle", [
    # points - rest_points times strength beyond float64: a lattice of inf displacements
    (_blender_doc(points=[[1.7e308, 0, 0]] * 8, strength=10), "points"),
    # box_max - box_min overflows (RuntimeWarning, then a lattice mapping all space to a point)
    (_bspline_doc(box_min=[-1e308] * 3, box_max=[1e308] * 3), "box_min/box_max"),
    # knots spanning -1e308 .. 1e308: np.diff overflowed (RuntimeWarning) in the monotonic check
    (_bspline_doc(knots=[[-1e308] * 3 + [1e308] * 3] * 3, box_min=None, box_max=None), "box_min/box_max"),
])
def test_values_near_the_float64_limit_are_refused_by_name(tmp_path, doc, needle):
    p = _doc_file(tmp_path, doc)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy overflow warning on the way
        with pytest.raises(ValueError, match=needle):
            lattice_json.load_lattice(p)


def test_a_huge_but_regular_blender_matrix_is_not_called_singular():
    """lattice_to_object = diag(1e200): det overflowed (RuntimeWarning), then 'singular'."""
    m = np.diag([1e200, 1e200, 1e200, 1.0])
    rest = lattice_json.blender_rest_grid((2, 2, 2))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        lat = smoothffd.BlenderLattice(rest, rest * 1.1, lattice_to_object=m)
    assert np.isfinite(lat.control_values()).all()


def test_per_frame_points_beyond_float64_are_refused():
    rest = lattice_json.blender_rest_grid((2, 2, 2))
    lat = smoothffd.BlenderLattice(rest, rest, strength=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="points"):
            lat.with_points(np.full_like(rest, 1.7e308))
    b = smoothffd.BSplineLattice.identity((-1e308, 0, 0), (0, 1, 1), shape=(3, 3, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match="control_points"):
            b.with_control_points(np.full(b.control_points.shape, 1.7e308))


def test_make_lattice_refuses_a_huge_shape_at_once(tmp_path, capsys):
    """--shape 1000 1000 1000 asked numpy for 7.5 GiB; 300 300 300 for minutes and 1.5 GB."""
    out = tmp_path / "l.json"
    tracemalloc.start()   # numpy reports its arrays to tracemalloc
    try:
        rc = cli.main(["make-lattice", "--box", "0", "0", "0", "1", "1", "1", "--shape", "1000",
                       "1000", "1000", "-o", str(out)])
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    err = capsys.readouterr().err
    assert rc == 2 and "--shape" in err and "1,000,000,000 control points" in err, err
    assert not out.exists()
    assert peak < 2**20, f"refused after allocating {peak / 2**20:.0f} MiB"
    assert math.prod((101, 101, 101)) <= cli.MAKE_LATTICE_MAX_POINTS  # 101^3 still works


def test_build_plan_refuses_a_huge_level_at_once():
    """level 2^31 - 1 through the bindings allocated for 11 s before a MemoryError."""
    X = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]])
    m = np.hstack([np.eye(3), np.zeros((3, 1))])
    spec = core.LatticeSpec.blender(["LINEAR"] * 3, [2, 2, 2], m)
    # A ValueError naming the limit is the argument check, before any table is allocated
    # (running out of memory would be a MemoryError).
    with pytest.raises(ValueError, match=f"level: at most {core.MAX_LEVEL} "):
        core.build_plan(X, np.arange(3, dtype=np.int32), np.array([0, 3], np.int32), None, None,
                        None, spec, 2**31 - 1)


def test_evaluators_refuse_no_plan():
    """CpuEvaluator(None) was a null plan and a segfault: run in a child process."""
    code = ("import smoothffd._core as c\n"
            "for cls in (c.CpuEvaluator, c.CudaEvaluator):\n"
            "    try:\n"
            "        cls(None)\n"
            "    except TypeError:\n"
            "        print('TypeError')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.split() == ["TypeError", "TypeError"], out.stderr
