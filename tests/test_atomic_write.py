"""Files the package writes (OBJ results, lattice JSON) are written whole or not at all: a
failure while writing (a full disk, Ctrl-C, a formatting error) leaves the previous file as it
was and no temporary file behind; a result may be written over its own input; names in any
script work."""
import errno
import os
import pathlib

import numpy as np
import pytest

from smoothffd import io as objio
from smoothffd import lattice_json

ROOT = pathlib.Path(__file__).resolve().parents[1]
DATA = ROOT / "python" / "smoothffd" / "data"
TRI = np.array([[0, 1, 2]])
POS = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])


def _fail_midway(monkeypatch, exc):
    """The second block of rows raises exc, after the first was written to the file."""
    real = objio._write_rows
    calls = []

    def flaky(fh, template, values, chunk=200_000):
        calls.append(1)
        if len(calls) == 2:
            fh.flush()
            raise exc
        return real(fh, template, values, chunk)
    monkeypatch.setattr(objio, "_write_rows", flaky)


@pytest.mark.parametrize("exc", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt()],
                         ids=["disk-full", "ctrl-c"])
@pytest.mark.parametrize("name", ["out.obj", "out.obj.gz"])
def test_failed_write_keeps_the_previous_file(tmp_path, monkeypatch, exc, name):
    path = tmp_path / name
    objio.write_obj(path, POS, TRI)
    before = path.read_bytes()
    _fail_midway(monkeypatch, exc)
    with pytest.raises(type(exc)):
        objio.write_obj(path, POS * 2, TRI, corner_normals=np.tile([0.0, 0, 1], (3, 1)))
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == [name], "a temporary file was left behind"


def test_failed_first_write_leaves_nothing(tmp_path, monkeypatch):
    _fail_midway(monkeypatch, OSError(errno.ENOSPC, "No space left on device"))
    with pytest.raises(OSError):
        objio.write_obj(tmp_path / "new.obj", POS, TRI, corner_normals=np.tile([0.0, 0, 1], (3, 1)))
    assert list(tmp_path.iterdir()) == []


def test_written_file_has_the_usual_permissions(tmp_path):
    path = tmp_path / "a.obj"
    objio.write_obj(path, POS, TRI)
    umask = os.umask(0)
    os.umask(umask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~umask


def test_lattice_json_written_whole(tmp_path, monkeypatch):
    path = tmp_path / "lat.json"
    lat = lattice_json.load_lattice(DATA / "vase_bend.json")
    lattice_json.save_lattice(path, lat)
    before = path.read_bytes()
    monkeypatch.setattr(lattice_json, "dumps_lattice", lambda doc: "{" + 1 / 0)  # fails while formatting
    with pytest.raises(ZeroDivisionError):
        lattice_json.save_lattice(path, lat)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["lat.json"]


def test_non_ascii_names_and_output_over_input(tmp_path):
    """`deform maillé.obj -o maillé.obj`: the input is read whole first, the result replaces it."""
    pytest.importorskip("smoothffd._core")
    from smoothffd import cli
    src = tmp_path / "maillé.obj"
    src.write_bytes((DATA / "vase.obj").read_bytes())
    lat = tmp_path / "déformation.json"
    lat.write_bytes((DATA / "vase_bend.json").read_bytes())
    before = objio.read_obj_mesh(src)
    assert cli.main(["deform", str(src), "--lattice", str(lat), "-o", str(src), "--level", "2", "--quiet"]) == 0
    after = objio.read_obj_mesh(src)
    assert after.vertex_count > before.vertex_count  # the tessellated result, whole
    assert "maillé.obj" in src.read_text(encoding="utf-8").splitlines()[0]  # the header names it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["déformation.json", "maillé.obj"]


def test_output_under_a_file_is_a_clear_error(tmp_path, capsys):
    pytest.importorskip("smoothffd._core")
    from smoothffd import cli
    (tmp_path / "notadir").write_text("x")
    rc = cli.main(["deform", str(DATA / "vase.obj"), "--lattice", str(DATA / "vase_bend.json"),
                   "-o", str(tmp_path / "notadir" / "x.obj"), "--level", "1", "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert rc == 2 and "notadir is a file, not a folder" in err, err
