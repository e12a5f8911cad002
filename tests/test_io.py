"""OBJ reading/writing (smoothffd.io): pure Python, no native core needed."""
import pathlib
import re
import warnings

import numpy as np
import pytest


def _import_pure(name):
    """Pure-Python submodules import without the native core (smoothffd/__init__.py)."""
    import importlib

    return importlib.import_module(f"smoothffd.{name}")


io = _import_pure("io")


def write_text(tmp_path, text, name="m.obj"):
    p = tmp_path / name
    p.write_text(text)
    return p


CUBE_QUADS = """\
# a unit cube, 6 quads, flat normals, one UV square per face
mtllib cube.mtl
o Cube
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 -1
vn 0 0 1
vn 0 -1 0
vn 1 0 0
vn 0 1 0
vn -1 0 0
usemtl Material
s off
g bottom
f 1/1/1 4/2/1 3/3/1 2/4/1
f 5/1/2 6/2/2 7/3/2 8/4/2
g sides
f 1/1/3 2/2/3 6/3/3 5/4/3
f 2/1/4 3/2/4 7/3/4 6/4/4
f 3/1/5 4/2/5 8/3/5 7/4/5
f 4/1/6 1/2/6 5/3/6 8/4/6
"""


def test_read_quads_with_normals_and_uvs(tmp_path):
    d = io.read_obj(write_text(tmp_path, CUBE_QUADS))
    assert d.positions.shape == (8, 3) and d.positions.dtype == np.float64
    assert d.face_offsets.tolist() == [0, 4, 8, 12, 16, 20, 24]
    assert d.corner_vertices[:4].tolist() == [0, 3, 2, 1]
    assert d.corner_normals.shape == (24, 3)
    np.testing.assert_array_equal(d.corner_normals[4:8], [[0, 0, 1]] * 4)
    np.testing.assert_array_equal(d.uvs[:4], [[0, 0], [1, 0], [1, 1], [0, 1]])
    # the pair Mesh() takes
    cv, fo = d.faces
    assert cv is d.corner_vertices and fo is d.face_offsets


def test_fast_and_slow_reader_agree(tmp_path):
    p = write_text(tmp_path, CUBE_QUADS)
    fast = io._read_fast(p.read_text(), str(p))
    slow = io._read_slow(p.read_text(), str(p))
    assert fast is not None
    for a, b in zip(fast, slow):
        np.testing.assert_array_equal(a, b)


def test_negative_indices_are_relative(tmp_path):
    text = """\
v 0 0 0
v 1 0 0
v 0 1 0
vn 0 0 1
f -3//-1 -2//-1 -1//-1
v 5 5 5
v 6 5 5
v 5 6 5
f -3//1 -2//1 -1//1
"""
    d = io.read_obj(write_text(tmp_path, text))
    assert d.corner_vertices.tolist() == [0, 1, 2, 3, 4, 5]
    np.testing.assert_array_equal(d.corner_normals, [[0, 0, 1]] * 6)
    assert d.uvs is None


def test_tolerated_odd_layouts(tmp_path):
    # CRLF, tabs, indentation, inline comments, vertex colours, 1D texture coordinates,
    # "v/t" corners, polylines and unknown keywords.
    text = (
        "v 0 0 0 1 0 0\r\n"
        "  v 1 0 0 0 1 0 # indented, with colour\r\n"
        "v\t0\t1\t0\t0 0 1\r\n"
        "vt 0.5\r\n"
        "vt 0.25 0.75 0\r\n"
        "l 1 2\r\n"
        "xyz whatever\r\n"
        "f 1/1 2/2 3/1\r\n"
    )
    d = io.read_obj(write_text(tmp_path, text))
    np.testing.assert_array_equal(d.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(d.uvs, [[0.5, 0], [0.25, 0.75], [0.5, 0]])
    assert d.corner_normals is None


def test_mixed_normals_are_dropped_and_missing_uvs_zeroed(tmp_path):
    text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvt 1 1\nf 1/1/1 2//1 3/1/1\nf 1 2 3\n"
    with pytest.warns(UserWarning) as rec:
        d = io.read_obj(write_text(tmp_path, text))
    msgs = " ".join(str(r.message) for r in rec)
    assert "normals" in msgs and "texture" in msgs
    assert d.corner_normals is None
    np.testing.assert_array_equal(d.uvs, [[1, 1], [0, 0], [1, 1], [0, 0], [0, 0], [0, 0]])


def test_forward_references_allowed(tmp_path):
    d = io.read_obj(write_text(tmp_path, "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"))
    assert d.corner_vertices.tolist() == [0, 1, 2]


@pytest.mark.parametrize(
    "text, line, pattern",
    [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "vertex index 4 .* out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2\n", 5, "at least 3 corners"),
        ("v 0 0 0\nv 1 x 0\nv 0 1 0\nf 1 2 3\n", 2, "non-numeric vertex value 'x'"),
        ("v 0 0\n", 1, "3 coordinates"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", 4, "index 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", 4, "vertex index -4 .* out of range"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1 2 3\nf 1/1 2/2 3/1\n", 6, "texture coordinate index 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\n# c\nf 1//1 2//2 3//1\n", 6, "normal index 2"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", 4, "non-integer index"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3/4/5/6\n", 4, "malformed face corner"),
        # slash totals match a uniform v/t/n layout (6 = 3 corners x 2) but one corner has 3
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2/1/1/1 3/1\n", 6, "malformed face corner"),
        ("v 0 0 0\nvn 0 nan 1\n", 2, "non-finite normal"),
        ("vt\n", 1, "texture coordinate needs"),
    ],
)
def test_malformed_input_names_file_and_line(tmp_path, text, line, pattern):
    p = write_text(tmp_path, text, "bad.obj")
    with pytest.raises(ValueError) as exc:
        io.read_obj(p)
    msg = str(exc.value)
    assert msg.startswith(f"{p}:{line}: "), msg
    assert re.search(pattern, msg), msg


def random_triangle_mesh(rng, V=50, T=80, dtype=np.float32):
    pos = rng.normal(size=(V, 3)).astype(dtype)
    tri = rng.integers(0, V, size=(T, 3)).astype(np.int32)
    vn = rng.normal(size=(V, 3)).astype(dtype)
    cn = vn[tri]  # mostly per-vertex normals ...
    cn[::7, 0] = rng.normal(size=(len(cn[::7]), 3))  # ... with some split corners
    uv = rng.random(size=(T, 3, 2)).astype(dtype)
    return pos, tri, cn, uv


@pytest.mark.parametrize("with_normals", [False, True])
@pytest.mark.parametrize("with_uvs", [False, True])
def test_triangle_round_trip_is_exact(tmp_path, with_normals, with_uvs):
    pos, tri, cn, uv = random_triangle_mesh(np.random.default_rng(1))
    p = tmp_path / "out.obj"
    io.write_obj(p, pos, tri, cn if with_normals else None, uv if with_uvs else None, header="test\nfile")
    assert p.read_text().startswith("# test\n# file\n")
    d = io.read_obj(p)
    # float32 written with 9 significant digits reads back to the same float32
    np.testing.assert_array_equal(d.positions.astype(np.float32), pos)
    np.testing.assert_array_equal(d.corner_vertices.reshape(-1, 3), tri)
    if with_normals:
        np.testing.assert_array_equal(d.corner_normals.astype(np.float32), cn.reshape(-1, 3))
    else:
        assert d.corner_normals is None
    if with_uvs:
        np.testing.assert_array_equal(d.uvs.astype(np.float32), uv.reshape(-1, 2))
    else:
        assert d.uvs is None


def test_float64_round_trip_is_exact(tmp_path):
    pos, tri, cn, _ = random_triangle_mesh(np.random.default_rng(2), dtype=np.float64)
    io.write_obj(tmp_path / "o.obj", pos, tri, cn)
    d = io.read_obj(tmp_path / "o.obj")
    np.testing.assert_array_equal(d.positions, pos)
    np.testing.assert_array_equal(d.corner_normals, cn.reshape(-1, 3))


def test_normals_and_uvs_are_deduplicated(tmp_path):
    # 2 triangles sharing an edge, all corners with the same normal and 2 distinct UVs
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    tri = np.array([[0, 1, 2], [2, 1, 3]])
    cn = np.tile(np.float32([0, 0, 1]), (2, 3, 1))
    uv = np.zeros((2, 3, 2), np.float32)
    uv[1, 2] = 1
    p = tmp_path / "d.obj"
    io.write_obj(p, pos, tri, cn, uv)
    lines = p.read_text().splitlines()
    assert sum(l.startswith("vn ") for l in lines) == 1
    assert sum(l.startswith("vt ") for l in lines) == 2
    assert sum(l.startswith("f ") for l in lines) == 2


def test_dedupe_is_exact_and_handles_signed_zero():
    rows = np.array([[0.0, 1, 2], [-0.0, 1, 2], [0.0, 1, 2], [3, 4, 5]], np.float32)
    uniq, inv = io._dedupe(rows)
    assert len(uniq) == 3  # -0.0 and 0.0 differ in bits, and both must survive a round trip
    np.testing.assert_array_equal(uniq[inv].view(np.uint32), rows.view(np.uint32))
    uniq, inv = io._dedupe_corners(rows, np.array([0, 0, 1, 1]), 2)
    assert len(uniq) == 3
    np.testing.assert_array_equal(uniq[inv].view(np.uint32), rows.view(np.uint32))


def test_polygon_round_trip(tmp_path):
    d = io.read_obj(write_text(tmp_path, CUBE_QUADS))
    # add a pentagon and a triangle to mix sizes
    cv = np.concatenate([d.corner_vertices, [0, 1, 2, 3, 4], [5, 6, 7]])
    fo = np.concatenate([d.face_offsets, [29, 32]])
    p = tmp_path / "poly.obj"
    io.write_obj(p, d.positions, (cv, fo))
    e = io.read_obj(p)
    np.testing.assert_array_equal(e.corner_vertices, cv)
    np.testing.assert_array_equal(e.face_offsets, fo)
    # with normals per corner (C, 3)
    cn = np.random.default_rng(3).normal(size=(len(cv), 3))
    io.write_obj(p, d.positions, (cv, fo), corner_normals=cn)
    np.testing.assert_array_equal(io.read_obj(p).corner_normals, cn)


def test_write_rejects_bad_input(tmp_path):
    pos = np.zeros((3, 3))
    with pytest.raises(ValueError, match="positions"):
        io.write_obj(tmp_path / "x.obj", np.zeros((3, 2)), [[0, 1, 2]])
    with pytest.raises(ValueError, match="out of range"):
        io.write_obj(tmp_path / "x.obj", pos, np.array([[0, 1, 3]]))
    with pytest.raises(ValueError, match="corner_normals"):
        io.write_obj(tmp_path / "x.obj", pos, np.array([[0, 1, 2]]), corner_normals=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="not finite"):
        io.write_obj(tmp_path / "x.obj", np.full((3, 3), np.nan), np.array([[0, 1, 2]]))
    with pytest.raises(ValueError, match="uvs: some values are not finite"):
        io.write_obj(tmp_path / "x.obj", pos, np.array([[0, 1, 2]]), uvs=np.full((3, 2), np.inf))
    with pytest.raises(ValueError, match="triangles: face_offsets"):
        io.write_obj(tmp_path / "x.obj", pos, (np.array([0, 1, 2]), np.array([0, 2])))


def test_read_obj_mesh_builds_core_mesh(tmp_path):
    pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")
    import smoothffd

    mesh = io.read_obj_mesh(write_text(tmp_path, CUBE_QUADS))
    assert isinstance(mesh, smoothffd.Mesh)
    assert mesh.vertex_count == 8 and mesh.face_count == 6
    np.testing.assert_array_equal(mesh.face_offsets, [0, 4, 8, 12, 16, 20, 24])
    np.testing.assert_allclose(mesh.corner_normals[4], [0, 0, 1])
    np.testing.assert_allclose(mesh.uvs[2], [1, 1])


@pytest.mark.parametrize("layout", ["v", "v/t", "v//n", "v/t/n", "v//n|v/t/n", "v|v/t"])
def test_fast_path_matches_slow_path_on_random_polygon_files(tmp_path, layout):
    rng = np.random.default_rng(len(layout))
    V, F = 40, 60
    sizes = rng.integers(3, 8, size=F)
    lines = [f"v {x:.6g} {y:.6g} {z:.6g}" for x, y, z in rng.normal(size=(V, 3))]
    lines += [f"vt {u:.6g} {v:.6g}" for u, v in rng.random(size=(30, 2))]
    lines += [f"vn {x:.6g} {y:.6g} {z:.6g}" for x, y, z in rng.normal(size=(25, 3))]
    for n in sizes:
        corners = []
        for _ in range(n):
            v, t, k = rng.integers(1, V + 1), rng.integers(1, 31), rng.integers(1, 26)
            form = rng.choice(layout.split("|"))  # "a|b": corners mix two layouts
            corners.append(form.replace("v", str(v), 1).replace("t", str(t)).replace("n", str(k)))
        lines.append("f " + " ".join(corners))
    text = "\n".join(lines) + "\n"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # mixed layouts warn about missing UVs
        fast = io._read_fast(text, "x.obj")
        slow = io._read_slow(text, "x.obj")
    if "|" not in layout or "//" in layout:  # v|v/t has no uniform skeleton: slow path only
        assert fast is not None
    if fast is None:
        return
    for a, b in zip(fast, slow):
        if a is None or b is None:
            assert a is None and b is None
        else:
            np.testing.assert_array_equal(a, b)
    assert fast.face_offsets[-1] == sizes.sum()


def test_gzip_round_trip(tmp_path):
    pos, tri, cn, uv = random_triangle_mesh(np.random.default_rng(7))
    p = tmp_path / "m.obj.gz"
    io.write_obj(p, pos, tri, cn, uv)
    assert p.read_bytes()[:2] == b"\x1f\x8b"  # gzip magic
    d = io.read_obj(p)
    np.testing.assert_array_equal(d.positions.astype(np.float32), pos)
    np.testing.assert_array_equal(d.uvs.astype(np.float32), uv.reshape(-1, 2))


# One reader behaviour: the strict grammar of io.py (_NUM, _INTEGER, lines, blanks).
sio = _import_pure("io")
_ODD = {
    "bom": "\ufeffv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    "form feed before v": "v 0 0 0\nv 1 0 0\nv 0 1 0\n\fv 5 5 5\nf 1 2 3\n",
    "no-break space in v": "v 0 0 0\nv 1 0 0\nv 0\u00a01 0\nf 1 2 3\n",
    "index 3-": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3-\n",
    "index 4-1": "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4-1\n",
    "underscore number": "v 0 0 0\nv 1_000 0 0\nv 0 1 0\nf 1 2 3\n",
    "arabic-indic digits": "v 0 0 0\nv \u0661 0 0\nv 0 1 0\nf 1 2 3\n",
    "arabic-indic index": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \u0663\n",
    "crlf and cr": "v 0 0 0\r\nv 1 0 0\rv 0 1 0\r\nf 1 2 3\r\n",
}


@pytest.mark.parametrize("name", sorted(_ODD))
def test_both_readers_agree(name, tmp_path):
    """Where the fast reader takes a file the slow one reads the same, and read_obj's answer
    (data or a ValueError naming the line) does not depend on which reader ran."""
    text = _ODD[name].lstrip("\ufeff")
    fast = sio._read_fast(text, "x.obj")
    try:
        slow = sio._read_slow(text, "x.obj")
    except ValueError as e:
        assert fast is None, f"fast reader accepted what the slow one refuses: {e}"
        slow = None
    if fast is not None:
        for f in ("positions", "corner_vertices", "face_offsets"):
            assert np.array_equal(getattr(fast, f), getattr(slow, f)), f


def test_bom_keeps_the_first_vertex(tmp_path):
    p = tmp_path / "bom.obj"
    p.write_bytes(_ODD["bom"].encode("utf-8"))
    d = sio.read_obj(p)
    assert len(d.positions) == 3 and np.array_equal(d.positions[0], [0, 0, 0])
    assert d.corner_vertices.tolist() == [0, 1, 2]


_UV_TRIANGLE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n"


@pytest.mark.parametrize("encoding,bom", [
    ("utf-16-le", b"\xff\xfe"), ("utf-16-be", b"\xfe\xff"),
    ("utf-32-le", b"\xff\xfe\x00\x00"), ("utf-32-be", b"\x00\x00\xfe\xff"),
    ("utf-8", b"\xef\xbb\xbf")])
@pytest.mark.parametrize("suffix", [".obj", ".obj.gz"])
def test_unicode_text_with_a_byte_order_mark_is_read(tmp_path, encoding, bom, suffix):
    """UTF-16 and UTF-32 files as Windows tools save them (a byte order mark first) read as
    their UTF-8 twin: it used to be 'the mesh has no vertices' (every line a NUL-spaced
    unknown keyword)."""
    want = sio.read_obj(_write_bytes(tmp_path / f"plain{suffix}", _UV_TRIANGLE.encode()))
    got = sio.read_obj(_write_bytes(tmp_path / f"bom{suffix}", bom + _UV_TRIANGLE.encode(encoding)))
    for f in ("positions", "corner_vertices", "face_offsets", "uvs"):
        assert np.array_equal(getattr(got, f), getattr(want, f)), f


@pytest.mark.parametrize("data,line", [
    (_UV_TRIANGLE.encode("utf-16-le"), 1),              # UTF-16 without its byte order mark
    (_UV_TRIANGLE.encode("utf-32-be"), 1),
    (b"v 0 0 0\nv 1 0 0\nv 0 1 0\x00\nf 1 2 3\n", 3),  # a NUL byte in UTF-8 text
])
def test_nul_characters_are_refused_naming_the_encoding(tmp_path, data, line):
    with pytest.raises(ValueError, match=rf"nul\.obj:{line}: NUL character in UTF-8 text: UTF-16 or "
                                         r"UTF-32 without a byte order mark, or not a text file"):
        sio.read_obj(_write_bytes(tmp_path / "nul.obj", data))


@pytest.mark.parametrize("text,needle", [
    ("v 3.1+e2 0 0\n", ":1: non-numeric vertex value '3.1+e2' (an exponent's sign follows the e: 3.1e+2)"),
    ("v 0 0 0\nvn 0 0 -1.5-E3\n", ":2: non-numeric normal value '-1.5-E3' (an exponent's sign follows the e: -1.5E-3)"),
    ("vt .5+e1 0\n", ":1: non-numeric texture coordinate value '.5+e1' (an exponent's sign follows the e: .5e+1)"),
])
def test_exponent_sign_before_the_e_is_refused_with_the_spelling_meant(tmp_path, text, needle):
    """Blender's importer reads "v 3.1+e2 5 6" as (3.1, 0, 0): its number parser stops at the
    "+", and the rest of the line parses as nothing, which it turns into zeros. A silently
    different mesh; refused here instead, naming the spelling that was probably meant."""
    p = tmp_path / "exp.obj"
    p.write_text(text + "v 1 0 0\nv 0 1 0\nf 1 2 3\n", encoding="utf-8")
    with pytest.raises(ValueError, match=re.escape(needle)):
        sio.read_obj(p)


def _write_bytes(path, data):
    if str(path).endswith(".gz"):
        import gzip
        data = gzip.compress(data)
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("name,needle", [
    ("index 3-", "non-integer index in face corner '3-'"),
    ("index 4-1", "non-integer index in face corner '4-1'"),
    ("underscore number", "non-numeric vertex value '1_000'"),
    ("arabic-indic digits", "non-numeric vertex value"),
    ("arabic-indic index", "non-integer index in face corner"),
    ("no-break space in v", ":3: vertex needs 3 coordinates"),
])
def test_strict_syntax_refused_with_the_line(tmp_path, name, needle):
    p = tmp_path / "odd.obj"
    p.write_text(_ODD[name], encoding="utf-8")
    with pytest.raises(ValueError, match=re.escape(needle)):
        sio.read_obj(p)


def test_control_characters_separate_tokens_as_in_blender(tmp_path):
    """Blender's importer takes every ASCII control character as a blank: "\fv 5 5 5" is a
    vertex there. Ignored here as an unknown keyword "\fv", it shifted every later vertex's
    index by one without a word."""
    p = tmp_path / "ff.obj"
    p.write_text(_ODD["form feed before v"], encoding="utf-8")
    assert sio.read_obj(p).positions.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]
    p.write_text("v 0 0 0\nv 1\x0b0\x1f0\nv\x010 1 0\x0c\nf\t1 2\x1e3\n", encoding="utf-8")
    d = sio.read_obj(p)
    assert d.positions.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    assert d.corner_vertices.tolist() == [0, 1, 2]


def test_backslash_continues_a_line(tmp_path):
    """The OBJ specification's line continuation, which Blender's importer follows; later
    lines keep their numbers in error messages."""
    p = tmp_path / "cont.obj"
    p.write_bytes(b"v 0 0 0\nv 1 0 \\\n0\r\nv 0 1 0\nf 1 \\\r\n2 \\\n3\n")
    d = sio.read_obj(p)
    assert d.positions.tolist() == [[0, 0, 0], [1, 0, 0], [0, 1, 0]]
    assert d.corner_vertices.tolist() == [0, 1, 2] and d.face_offsets.tolist() == [0, 3]
    p.write_bytes(b"v 0 0 0\nv 1 0 \\\n0\nv 0 1 0\nv x 0 0\n")
    with pytest.raises(ValueError, match=r"cont\.obj:5: non-numeric vertex value 'x'"):
        sio.read_obj(p)


@pytest.mark.parametrize("corners,lacking", [("1//1 2//1 3//1", ["normals"]),
                                             ("1/1 2/2 3/3", ["texture coordinates"]),
                                             ("1/1/1 2/2/2 3/3/3", ["texture coordinates", "normals"])])
def test_indices_of_elements_the_file_lacks_are_ignored(tmp_path, corners, lacking):
    """Some exporters write "f 1//1" with no vn in the file; Blender's importer ignores such
    indices, and so does this reader, with a warning (they were an out-of-range error)."""
    p = tmp_path / "lacks.obj"
    p.write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf {corners}\n", encoding="utf-8")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = sio.read_obj(p)
    said = [str(w.message) for w in caught]
    assert len(said) == len(lacking), said
    for what in lacking:
        assert any(f"face corners refer to {what}, but the file defines none" in m for m in said), said
    assert d.corner_vertices.tolist() == [0, 1, 2]
    assert d.corner_normals is None and d.uvs is None


def test_long_bad_number_is_not_echoed_whole(tmp_path):
    p = tmp_path / "long.obj"
    p.write_text("v 0 0 0\nv 1 0 0\nv 0 1 " + "9" * 5000 + "x\nf 1 2 3\n", encoding="utf-8")
    with pytest.raises(ValueError) as e:
        sio.read_obj(p)
    assert len(str(e.value)) < 200, str(e.value)
