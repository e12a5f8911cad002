"""Wavefront OBJ reading and writing (pure Python + numpy; no native code needed).

Reading keeps what smooth FFD needs: positions, polygons of any size, per-corner normals
(``vn``) and per-corner UVs (``vt``). ``o``/``g``/``s``/``usemtl``/``mtllib``/``l``/``p`` and
unknown keywords are ignored. Indices may be positive (1-based) or negative (relative to the
elements defined so far, as the OBJ spec says).

Writing is vectorized: the whole file is produced by a few large ``%``-format calls, so a
2M-triangle result is written in seconds rather than minutes.
"""
from __future__ import annotations

import codecs
import contextlib
import gzip
import io as stdio
import os
import re
import tempfile
import zlib
import warnings
from typing import NamedTuple, Optional

import numpy as np

__all__ = ["ObjData", "read_obj", "read_obj_mesh", "write_obj", "write_result"]


class ObjData(NamedTuple):
    """Polygon mesh as read from an OBJ file (unpacks like a tuple).

    positions        (V, 3) float64
    corner_vertices  (C,) int64, 0-based vertex index of each face corner
    face_offsets     (F+1,) int64, face f owns corners face_offsets[f]:face_offsets[f+1]
    corner_normals   (C, 3) float64 or None (None unless every corner has a ``vn``)
    uvs              (C, 2) float64 or None (None unless some corner has a ``vt``)
    """

    positions: np.ndarray
    corner_vertices: np.ndarray
    face_offsets: np.ndarray
    corner_normals: Optional[np.ndarray]
    uvs: Optional[np.ndarray]

    @property
    def faces(self):
        """The ``(corner_vertices, face_offsets)`` pair that ``smoothffd.Mesh`` accepts."""
        return (self.corner_vertices, self.face_offsets)

    def to_mesh(self, vertex_weights=None):
        """``smoothffd.Mesh(positions, faces, corner_normals, uvs)`` (needs the native core)."""
        from . import Mesh  # lazy: io.py must import without the native core

        return Mesh(self.positions, self.faces, self.corner_normals, self.uvs,
                    vertex_weights=vertex_weights)


def _open(path, mode, **kw):
    """A file (text unless mode has "b"), gzip-compressed when the name ends with .gz (large
    results shrink ~4x)."""
    if path.endswith(".gz"):  # level 6: most of level 9's ratio at a fraction of its time
        return gzip.open(path, mode if "b" in mode else mode + "t", compresslevel=6, **kw)
    return open(path, mode, **kw)


@contextlib.contextmanager
def atomic_write(path, encoding="utf-8"):
    """A text file written as a whole or not at all: the data go to a temporary file in the
    same folder, which replaces ``path`` (os.replace) only when the block ends without an
    exception. Any failure (a full disk, Ctrl-C, an error while formatting) removes the
    temporary file and leaves an existing ``path`` as it was, so writing a result over its
    own input is safe. gzip-compressed when the name ends with .gz."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix="." + os.path.basename(path) + ".", suffix=".tmp")
    try:
        with open(fd, "wb") as raw:
            # level 6: most of level 9's ratio at a fraction of its time
            sink = gzip.GzipFile(fileobj=raw, mode="wb", compresslevel=6) if path.endswith(".gz") else raw
            fh = stdio.TextIOWrapper(sink, encoding=encoding, newline="\n")
            yield fh
            fh.flush()
            fh.detach()
            if sink is not raw:
                sink.close()  # the gzip trailer; raw stays open
            raw.flush()
            os.fsync(raw.fileno())
        # mkstemp makes the file private (0600): give it what a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _error(path, lineno, msg):
    return ValueError(f"{path}:{lineno}: {msg}")


# One grammar for both readers: lines end at \n, \r\n or \r, and a backslash at the end of a
# line continues it on the next; tokens are separated by spaces, tabs and the other ASCII
# control characters but NUL (a form feed, say: Blender's importer separates tokens by all of
# them); a number is ASCII decimal notation (no "1_000", no other scripts' digits, no "inf" or
# "nan"); an index is an ASCII integer, optionally negative.
_NUM = r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
_NUMBERS = re.compile(rf"(?:{_NUM}(?: {_NUM})*)?")
_NUMBER = re.compile(_NUM)
_INTEGERS = re.compile(r"(?:-?[0-9]+(?: -?[0-9]+)*)?")
_INTEGER = re.compile(r"-?[0-9]+")
_BLANK = " " + "".join(map(chr, range(1, 0x20))).replace("\n", "").replace("\r", "")
_BLANKS = re.compile(f"[{re.escape(_BLANK)}]+")
_CONTINUED = re.compile(r"(?:[^\n]*\\\n)+[^\n]*")
# The fast reader takes printable ASCII, tabs and newlines only (and no "_"); anything else goes
# to the slow reader, which applies the grammar above token by token.
_PLAIN = bytes(range(0x20, 0x7f)).replace(b"_", b"") + b"\t\n"


def _plain(text):
    return text.isascii() and not text.encode("ascii").translate(None, _PLAIN)


def _show(tok, limit=40):
    """A token as an error message shows it: quoted, cut when long."""
    return repr(tok if len(tok) <= limit else tok[:limit] + "...")


def _lines(text):
    """The file's lines, as both readers see them."""
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def _tokens(line):
    line = line.strip(_BLANK)
    return _BLANKS.split(line) if line else []


def _join_continued(text):
    """Lines ending in a backslash joined with the next (the backslash and the line end become
    a blank); as many empty lines follow a joined line as it absorbed, so later lines keep
    their numbers in error messages."""
    if "\\\n" not in text and "\\\r" not in text:
        return text
    text = text.replace("\r\n", "\n").replace("\r", "\n")
    return _CONTINUED.sub(lambda m: m[0].replace("\\\n", " ") + "\n" * m[0].count("\\\n"), text)


def _tokens_per_line_are(lines, n):
    """Whether every line holds exactly n blank-separated tokens (vectorized for the common
    single-spaced layout, line by line otherwise)."""
    joined = "\n".join(lines)
    if "\t" in joined or "  " in joined or " \n" in joined or "\n " in joined or \
            joined.startswith(" ") or joined.endswith(" "):
        return all(len(line.split()) == n for line in lines)
    b = np.frombuffer(joined.encode("ascii"), dtype=np.uint8)
    spaces = np.concatenate([[0], np.cumsum(b == 32)])
    ends = np.concatenate([np.flatnonzero(b == 10), [len(b)]])
    starts = np.concatenate([[0], ends[:-1] + 1])
    return bool((spaces[ends] - spaces[starts] == n - 1).all() and (ends > starts).all())


def _floats(tokens, lines, per_line, path, what):
    """Convert a flat list of numeric strings to float64 (n, per_line).

    The fast path lets numpy parse everything at once; only on failure do we walk the tokens
    one by one, so the error can name the offending line.
    """
    if not tokens:
        return np.zeros((0, per_line))
    if not _NUMBERS.fullmatch(" ".join(tokens)):
        i = next(i for i, tok in enumerate(tokens) if not _NUMBER.fullmatch(tok))
        tok = tokens[i]
        kind = "non-finite" if tok.lower().lstrip("+-") in ("inf", "infinity", "nan") else "non-numeric"
        msg = f"{kind} {what} value {_show(tok)}"
        if _MISPLACED_SIGN.fullmatch(tok):
            e = tok.lower().index("e")
            msg += f" (an exponent's sign follows the e: {tok[:e - 1]}{tok[e]}{tok[e - 1]}{tok[e + 1:]})"
        raise _error(path, lines[i // per_line], msg)
    arr = np.array(tokens, dtype=np.float64)
    bad = ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise _error(path, lines[i // per_line], f"non-finite {what} value {_show(tokens[i])}")
    return arr.reshape(-1, per_line)


def _parse_corners_fast(toks):
    """Parse corner tokens ``v``, ``v/t``, ``v//n``, ``v/t/n`` into an int64 (C, 3) array
    (0 = absent). Returns None if the tokens do not all have a shape this path understands.
    """
    C = len(toks)
    slashes = np.fromiter(map(str.count, toks, ["/"] * C), dtype=np.int64, count=C)
    if slashes.max(initial=0) > 2:
        return None
    # "v//n" -> "v/0/n": 0 is never a valid OBJ index, so it can stand for "absent".
    joined = " ".join(toks).replace("//", "/0/")
    fields = joined.replace("/", " ").split()
    if len(fields) != int(slashes.sum()) + C:  # e.g. a trailing "1/2/" or a "/" alone
        return None
    if not _INTEGERS.fullmatch(" ".join(fields)):  # "3-", "4-1", other scripts' digits
        return None
    try:
        vals = np.array(fields, dtype=np.int64)
    except (ValueError, OverflowError):
        return None
    out = np.zeros((C, 3), dtype=np.int64)
    nslot = slashes + 1
    starts = np.zeros(C, dtype=np.int64)
    np.cumsum(nslot[:-1], out=starts[1:])
    for s in range(3):
        m = nslot > s
        out[m, s] = vals[starts[m] + s]
    return out


def _parse_uniform_corners(joined, C):
    """Parse C space-separated corners that all share one layout (``v``, ``v/t``, ``v//n`` or
    ``v/t/n``, as every common exporter writes) with one C-level ``np.fromstring`` call.
    Returns (C, 3) int64 with 0 = absent, or None if the layout is not uniform.
    """
    first = joined.split(" ", 1)[0]
    k = first.count("/")
    layout = first.translate(_DIGITS)  # the corner's skeleton: "", "/" or "//" (v/t/n, v//n)
    if layout not in ("", "/", "//"):
        return None
    # Every corner must have exactly this skeleton: strip the digits and compare the rest.
    if joined.translate(_DIGITS) != " ".join([layout] * C):
        return None
    # ... and every field must be an integer ("3-" or "4-1" pass the skeleton test).
    if "-" in joined and not _INTEGERS.fullmatch(joined.replace("//", " ").replace("/", " ")):
        return None
    if layout == "//":
        joined = joined.replace("//", "/0/")  # 0 is never a valid index: it marks "absent"
    with warnings.catch_warnings():  # fromstring warns (and stops) on junk: we count instead
        warnings.simplefilter("ignore")
        vals = np.fromstring(joined.replace("/", " "), dtype=np.int64, sep=" ")
    if len(vals) != C * (k + 1):
        return None
    out = np.zeros((C, 3), dtype=np.int64)
    out[:, : k + 1] = vals.reshape(C, k + 1)
    return out


def _parse_corners_slow(toks, corner_line, path):
    """Token-by-token twin of :func:`_parse_corners_fast` that reports the line of an error."""
    out = np.zeros((len(toks), 3), dtype=np.int64)
    for c, tok in enumerate(toks):
        parts = tok.split("/")
        if len(parts) > 3 or parts[0] == "":
            raise _error(path, corner_line(c), f"malformed face corner {_show(tok)}")
        for s, p in enumerate(parts):
            if p == "":
                continue
            if not _INTEGER.fullmatch(p):
                msg = f"non-integer index in face corner {_show(tok)}"
                raise _error(path, corner_line(c), msg)
            try:
                out[c, s] = int(p)
            except OverflowError:  # beyond int64 (found by native/fuzz/fuzz_obj.py)
                msg = f"index out of range in face corner {_show(tok)}"
                raise _error(path, corner_line(c), msg) from None
    return out


def read_obj(path) -> ObjData:
    """Read an OBJ file into :class:`ObjData`.

    Raises ``ValueError("file:line: ...")`` for malformed input: non-numeric values, a vertex
    with fewer than 3 coordinates, a face with fewer than 3 corners, index 0, or an index that
    refers to a missing vertex/normal/uv.

    Mixed files: if only some corners have ``vn``, normals are dropped (``None``, so the core
    computes smooth ones) with a warning; if only some have ``vt``, the others get UV (0, 0).
    ``vt`` or ``vn`` indices in a file that defines no ``vt`` or no ``vn`` are ignored, with a
    warning (as Blender's importer ignores them).
    """
    path = os.fspath(path)
    try:
        with _open(path, "rb") as fh:
            raw = fh.read()
    except (EOFError, gzip.BadGzipFile, zlib.error) as e:
        raise ValueError(f"{path}: damaged or truncated gzip file ({e})") from None
    text = _join_continued(_decode(raw, path))
    # Two readers: a vectorized one for the common, clean case, and a line-by-line one that
    # handles every oddity and names the line of an error. The fast one gives up (None) on
    # anything unusual, so both always agree.
    data = _read_fast(text, path)
    if data is None:
        data = _read_slow(text, path)
    return data


# Byte order marks: the encoding they name, longest first (UTF-32 LE's starts like UTF-16 LE's).
_BOMS = ((codecs.BOM_UTF32_LE, "utf-32-le"), (codecs.BOM_UTF32_BE, "utf-32-be"),
         (codecs.BOM_UTF8, "utf-8"), (codecs.BOM_UTF16_LE, "utf-16-le"),
         (codecs.BOM_UTF16_BE, "utf-16-be"))


def _decode(raw, path):
    """The file's text: UTF-8, or what a byte order mark names (UTF-8, UTF-16 or UTF-32, as
    Windows tools write them); the mark is not part of the first line. Bytes that do not
    decode become U+FFFD (they can only matter in names and comments: numbers are ASCII). A
    NUL character is refused by name: it is what UTF-16 or UTF-32 text without a byte order
    mark, or a file that is not text at all, looks like when read as UTF-8."""
    encoding = "utf-8"
    for bom, name in _BOMS:
        if raw.startswith(bom):
            raw, encoding = raw[len(bom):], name
            break
    text = raw.decode(encoding, errors="replace")
    nul = text.find("\0")
    if nul >= 0:
        line = len(_lines(text[:nul]))
        raise _error(path, line, f"NUL character in {encoding.upper()} text: UTF-16 or UTF-32 "
                     "without a byte order mark, or not a text file (save it as UTF-8)")
    return text


# A number with its exponent's sign before the "e" ("3.1+e2" for 3.1e+2).
_MISPLACED_SIGN = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)[+-][eE][0-9]+")


# Lines the regexes of the fast path would skip silently: indented lines and bare keywords.
# (A keyword followed by blanks only is caught later by its token count.)
_FAST_BAIL = ("\n ", "\n\t", "\nv\n", "\nvt\n", "\nvn\n", "\nf\n")
_DIGITS = str.maketrans("", "", "0123456789-")


def _read_fast(text, path):
    """Regex + numpy reader; returns None whenever it is not sure (the slow path decides)."""
    if "#" in text:
        text = re.sub(r"#[^\n\r]*", "", text)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    if not _plain(text):
        return None
    text = "\n" + text + "\n"
    if any(b in text for b in _FAST_BAIL):
        return None

    def grab(kw, ncols, pad=None):
        lines = re.findall(r"\n%s[ \t]([^\n]*)" % kw, text)
        toks = " ".join(lines).split()
        # Exactly ncols tokens on every line (a matching total alone is not enough: "v 1 2 3 4 5"
        # followed by "v 6" would shift every coordinate after it).
        if lines and not _tokens_per_line_are(lines, ncols):
            counts = set(map(len, map(str.split, lines)))
            if len(counts) != 1 or min(counts) < (ncols if pad is None else 1):
                return None
            k = counts.pop()
            if k < ncols:  # "vt u" only: pad
                toks = [t for u in toks for t in (u, pad)]
                k = 2
            toks = np.array(toks, dtype=object).reshape(len(lines), k)[:, :ncols].ravel().tolist()
        try:
            arr = np.array(toks, dtype=np.float64).reshape(-1, ncols)
        except ValueError:
            return None
        return arr if np.isfinite(arr).all() else None

    positions = grab("v", 3)
    vt = grab("vt", 2, pad="0")
    vn = grab("vn", 3)
    if positions is None or vt is None or vn is None:
        return None
    faces = re.findall(r"\nf[ \t]([^\n]*)", text)
    joined = " ".join(faces)
    if "\t" in joined or "  " in joined or joined.startswith(" ") or joined.endswith(" "):
        faces = [" ".join(f.split()) for f in faces]  # odd spacing: normalize per face
        joined = " ".join(faces)
    nf = len(faces)
    sizes = np.fromiter(map(str.count, faces, [" "] * nf), dtype=np.int64, count=nf) + 1
    if nf and sizes.min() < 3:
        return None
    raw = _parse_uniform_corners(joined, int(sizes.sum())) if nf else np.zeros((0, 3), np.int64)
    if raw is None or (raw < 0).any():  # relative indices need the line order: slow path
        return None
    if len(raw) and (raw[:, 0] == 0).any():
        return None
    totals = (len(positions), len(vt), len(vn))
    for s in range(3):
        if len(raw) and raw[:, s].max() > totals[s]:
            return None
    face_offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=face_offsets[1:])
    return _finish(path, positions, vt, vn, raw - 1, raw != 0, face_offsets)


def _finish(path, positions, vt, vn, idx, present, face_offsets):
    """Assemble ObjData from resolved 0-based corner indices idx (C, 3) = (v, vt, vn)."""
    corner_vertices = np.ascontiguousarray(idx[:, 0])
    uvs = None
    t_has = present[:, 1]
    if t_has.any():
        if t_has.all():
            uvs = vt[idx[:, 1]]
        else:
            uvs = np.zeros((len(corner_vertices), 2))
            uvs[t_has] = vt[idx[t_has, 1]]
            warnings.warn(f"{path}: {int((~t_has).sum())} face corners have no texture "
                          "coordinate; using (0, 0)")
    normals = None
    n_has = present[:, 2]
    if len(n_has) and n_has.all():
        normals = vn[idx[:, 2]]
    elif n_has.any():
        warnings.warn(f"{path}: only some face corners have normals; ignoring all normals")
    return ObjData(positions, corner_vertices, face_offsets, normals, uvs)


def _read_slow(text, path):
    """Line-by-line reader: handles relative indices and odd layouts, reports line numbers."""
    v_tok, v_line = [], []
    vt_tok, vt_line = [], []
    vn_tok, vn_line = [], []
    toks = []  # all face corner tokens, in order
    f_size, f_line = [], []
    # Element counts at each face: negative indices are relative to these.
    f_nv, f_nvt, f_nvn = [], [], []

    for lineno, line in enumerate(_lines(text), 1):
        if "#" in line:
            line = line[: line.index("#")]
        parts = _tokens(line)
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            if len(parts) < 4:
                raise _error(path, lineno, f"vertex needs 3 coordinates, got {len(parts) - 1}")
            v_tok += parts[1:4]  # a 4th value (w) or vertex colours are ignored
            v_line.append(lineno)
        elif key == "f":
            n = len(parts) - 1
            if n < 3:
                raise _error(path, lineno, f"face needs at least 3 corners, got {n}")
            toks += parts[1:]
            f_size.append(n)
            f_line.append(lineno)
            f_nv.append(len(v_line))
            f_nvt.append(len(vt_line))
            f_nvn.append(len(vn_line))
        elif key == "vn":
            if len(parts) < 4:
                raise _error(path, lineno, f"normal needs 3 components, got {len(parts) - 1}")
            vn_tok += parts[1:4]
            vn_line.append(lineno)
        elif key == "vt":
            if len(parts) < 2:
                raise _error(path, lineno, "texture coordinate needs at least 1 value")
            uv = parts[1:3]
            vt_tok += uv if len(uv) == 2 else [uv[0], "0"]  # 1D textures: v = 0
            vt_line.append(lineno)
        # every other keyword (o, g, s, usemtl, mtllib, l, p, vendor extensions) is ignored

    positions = _floats(v_tok, v_line, 3, path, "vertex")
    vt = _floats(vt_tok, vt_line, 2, path, "texture coordinate")
    vn = _floats(vn_tok, vn_line, 3, path, "normal")

    sizes = np.asarray(f_size, dtype=np.int64)
    face_offsets = np.zeros(len(sizes) + 1, dtype=np.int64)
    np.cumsum(sizes, out=face_offsets[1:])
    corner_face = np.repeat(np.arange(len(sizes)), sizes)
    f_line_arr = np.asarray(f_line, dtype=np.int64)

    def corner_line(c):
        return int(f_line_arr[corner_face[c]])

    raw = _parse_corners_fast(toks) if toks else np.zeros((0, 3), np.int64)
    if raw is None:
        raw = _parse_corners_slow(toks, corner_line, path)

    counts = (np.asarray(f_nv, np.int64), np.asarray(f_nvt, np.int64), np.asarray(f_nvn, np.int64))
    totals = (len(positions), len(vt), len(vn))
    names = ("vertex", "texture coordinate", "normal")
    idx = np.zeros_like(raw)
    present = raw != 0
    if len(raw) and not present[:, 0].all():
        c = int(np.flatnonzero(~present[:, 0])[0])
        raise _error(path, corner_line(c),
                     f"vertex index 0 in corner {toks[c]!r} (OBJ indices start at 1)")
    for s in (1, 2):
        # Texture coordinate or normal indices in a file that defines none are ignored, as
        # Blender's importer ignores them (exporters that write "f 1//1" regardless exist).
        if totals[s] == 0 and present[:, s].any():
            warnings.warn(f"{path}: face corners refer to {names[s]}s, but the file defines "
                          f"none; ignoring those indices")
            present[:, s] = False
    for s in range(3):
        so_far = counts[s][corner_face]
        # Positive indices may refer forward (many writers rely on it); negative ones count
        # back from the elements defined before this face.
        res = np.where(raw[:, s] > 0, raw[:, s] - 1, so_far + raw[:, s])
        bad = present[:, s] & ((res < 0) | (res >= totals[s]))
        if bad.any():
            c = int(np.flatnonzero(bad)[0])
            raise _error(
                path, corner_line(c),
                f"{names[s]} index {int(raw[c, s])} in corner {toks[c]!r} is out of range "
                f"({totals[s]} defined in file, {int(so_far[c])} before this face)",
            )
        idx[:, s] = res
    return _finish(path, positions, vt, vn, idx, present, face_offsets)


def read_obj_mesh(path):
    """Read an OBJ file into a ``smoothffd.Mesh`` (polygons, split normals and UVs kept)."""
    return read_obj(path).to_mesh()


# ----------------------------------------------------------------------------------------
# writing


def _dedupe(rows):
    """Unique rows by exact bit pattern. rows (C, k) -> (unique (U, k), index (C,)).

    Each row becomes one uint64 key: the exact bits when they fit (two float32: UVs), else a
    hash that is verified afterwards (falling back to an exact row sort on a collision).
    Sorting one uint64 per row is ~10x faster than sorting rows as void records.
    """
    rows = np.ascontiguousarray(rows)
    C, k = rows.shape
    if C == 0:
        return rows, np.zeros(0, dtype=np.int64)
    ubits = np.dtype("u%d" % rows.dtype.itemsize)
    bits = rows.view(ubits)
    exact = rows.dtype.itemsize * k <= 8
    if exact:
        key = np.zeros(C, dtype=np.uint64)
        for j in range(k):
            key = (key << np.uint64(8 * rows.dtype.itemsize)) | bits[:, j].astype(np.uint64)
    else:
        key = np.zeros(C, dtype=np.uint64)
        for j in range(k):  # splitmix-style mixing; uint64 array arithmetic wraps silently
            key ^= bits[:, j].astype(np.uint64)
            key *= np.uint64(0x9E3779B97F4A7C15)
            key ^= key >> np.uint64(31)
    order = np.argsort(key)  # any representative of a group will do: no stable sort needed
    sk = key[order]
    start = np.empty(C, dtype=bool)
    start[0] = True
    np.not_equal(sk[1:], sk[:-1], out=start[1:])
    inv = np.empty(C, dtype=np.int64)
    inv[order] = np.cumsum(start) - 1
    uniq = rows[order[start]]
    if not exact and not np.array_equal(uniq[inv].view(ubits), bits):  # bits: NaN-safe
        void = rows.view(np.dtype((np.void, rows.dtype.itemsize * k))).ravel()
        _, first, inv = np.unique(void, return_index=True, return_inverse=True)
        uniq, inv = rows[first], inv.ravel()
    return uniq, inv


def _dedupe_corners(values, corner_vertices, n_vertices):
    """Exact dedupe of per-corner values (C, k) -> (unique (U, k), index (C,)).

    Most corners of a vertex carry the same normal/UV (splits are the exception), so each
    corner is first compared with one representative corner of its vertex; only the distinct
    candidates left over (about one per vertex) go through the sort in :func:`_dedupe`.
    """
    values = np.ascontiguousarray(values)
    C = len(values)
    if C == 0:
        return _dedupe(values)
    ubits = np.dtype("u%d" % values.dtype.itemsize)
    bits = values.view(ubits)
    rep = np.empty(n_vertices, dtype=np.int64)
    rep[corner_vertices] = np.arange(C)  # some corner of each vertex (which one is irrelevant)
    rc = rep[corner_vertices]
    same = (bits[rc] == bits).all(axis=1)
    cand = np.where(same, rc, np.arange(C))
    mark = np.zeros(C, dtype=bool)
    mark[cand] = True
    picked = np.flatnonzero(mark)
    uniq, sub_inv = _dedupe(values[picked])
    slot = np.cumsum(mark) - 1  # position of each picked corner within `picked`
    return uniq, sub_inv[slot[cand]]


def _float_fmt(dtype):
    # Enough significant digits that reading the file back gives the same bits.
    return "%.9g" if np.dtype(dtype).itemsize <= 4 else "%.17g"


def _write_rows(fh, template, values, chunk=200_000):
    """Write ``template % row`` for every row of ``values`` with one format call per chunk."""
    values = np.asarray(values)
    for r0 in range(0, len(values), chunk):
        block = values[r0 : r0 + chunk]
        fh.write((template * len(block)) % tuple(block.ravel().tolist()))


def write_obj(path, positions, triangles, corner_normals=None, uvs=None, *, header=None):
    """Write a mesh to an OBJ file.

    positions       (V, 3)
    triangles       (T, 3) int triangles, or a ``(corner_vertices, face_offsets)`` pair for
                    polygons of any size
    corner_normals  (T, 3, 3) or (C, 3) per face corner, or None
    uvs             (T, 3, 2) or (C, 2) per face corner, or None
    header          optional comment line(s) written at the top

    Normals and UVs are deduplicated by exact value, so a smooth result stores about one
    normal per vertex instead of one per corner. float32 values are written with 9
    significant digits (float64 with 17) so a round trip is exact.
    """
    path = os.fspath(path)
    pos = np.asarray(positions)
    if pos.ndim != 2 or pos.shape[1] != 3:
        raise ValueError(f"positions must have shape (V, 3), got {pos.shape}")
    if not np.isfinite(pos).all():  # "nan" in an OBJ file would not read back
        bad = int((~np.isfinite(pos)).any(axis=1).sum())
        raise ValueError(f"positions: {bad} vertices are not finite")
    if isinstance(triangles, (tuple, list)) and len(triangles) == 2 and np.ndim(triangles[0]) == 1:
        cv = np.asarray(triangles[0], dtype=np.int64)
        offsets = np.asarray(triangles[1], dtype=np.int64)
        if offsets.ndim != 1 or len(offsets) < 1 or offsets[0] != 0 or offsets[-1] != len(cv):
            raise ValueError("triangles: face_offsets must start at 0 and end at "
                             "len(corner_vertices)")
        if (np.diff(offsets) < 3).any():
            raise ValueError("triangles: every polygon needs at least 3 corners")
        all_triangles = bool((np.diff(offsets) == 3).all())
    else:
        tri = np.asarray(triangles)
        if tri.ndim != 2 or tri.shape[1] != 3 or not np.issubdtype(tri.dtype, np.integer):
            raise ValueError("triangles: expected (T, 3) integers or a (corner_vertices, "
                             f"face_offsets) pair, got shape {tri.shape}")
        cv = tri.astype(np.int64).ravel()
        offsets = np.arange(0, len(cv) + 1, 3, dtype=np.int64)
        all_triangles = True
    C = len(cv)
    if C and (cv.min() < 0 or cv.max() >= len(pos)):
        raise ValueError(f"triangles: vertex index out of range [0, {len(pos)})")

    cols = [cv + 1]
    parts = []  # (keyword, unique values) written before the faces
    for name, arr, k in (("uvs", uvs, 2), ("corner_normals", corner_normals, 3)):
        if arr is None:
            cols.append(None)
            continue
        a = np.asarray(arr)
        if a.size != C * k:
            raise ValueError(f"{name} must have {C} corners x {k} values, got shape {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"{name}: some values are not finite")
        uniq, inv = _dedupe_corners(a.reshape(C, k), cv, len(pos))
        cols.append(inv + 1)
        parts.append((name, uniq))

    with atomic_write(path) as fh:
        if header:
            for line in str(header).splitlines():
                fh.write(f"# {line}\n")
        _write_rows(fh, "v %s %s %s\n".replace("%s", _float_fmt(pos.dtype)), pos)
        for name, uniq in parts:
            f = _float_fmt(uniq.dtype)
            if name == "uvs":
                _write_rows(fh, f"vt {f} {f}\n", uniq)
            else:
                _write_rows(fh, f"vn {f} {f} {f}\n", uniq)
        v, t, n = cols
        # OBJ corner syntax: v, v/t, v//n, v/t/n.
        if t is None and n is None:
            stack, slot = v[:, None], "%d"
        elif n is None:
            stack, slot = np.stack([v, t], 1), "%d/%d"
        elif t is None:
            stack, slot = np.stack([v, n], 1), "%d//%d"
        else:
            stack, slot = np.stack([v, t, n], 1), "%d/%d/%d"
        if C == 0:
            return
        if all_triangles:  # one fixed template: the fastest path
            _write_rows(fh, f"f {slot} {slot} {slot}\n", stack.reshape(-1, 3 * stack.shape[1]))
        else:
            _write_polygon_rows(fh, stack, slot, offsets)


def _write_polygon_rows(fh, stack, slot, offsets, chunk=500_000):
    """Polygons of mixed sizes: each corner is formatted as "<lead> slot", where the lead is
    "f" at a face start and "" otherwise, so one format call still covers many faces."""
    C = len(stack)
    lead = np.full(C, "", dtype=object)
    lead[offsets[:-1]] = "\nf"
    lead[0] = "f"
    k = stack.shape[1]
    for c0 in range(0, C, chunk):
        c1 = min(C, c0 + chunk)
        # Interleave the lead strings with the index columns: row = (lead, i[, j[, k]]).
        rows = np.empty((c1 - c0, k + 1), dtype=object)
        rows[:, 0] = lead[c0:c1]
        rows[:, 1:] = stack[c0:c1]
        fh.write((("%s " + slot) * (c1 - c0)) % tuple(rows.ravel().tolist()))
    fh.write("\n")


def write_result(path, result, header=None):
    """Write a ``smoothffd.Result`` or ``CompactResult`` (positions, triangles, normals, UVs)
    as OBJ.

    A positions-only result (``deform(..., normals=False)``, normals None) is written without
    ``vn`` lines, like a result without UVs has no ``vt``. Either layout gives the same file."""
    normals = result.corner_normals
    if callable(normals):  # CompactResult: one normal per render vertex, gathered per corner
        normals = normals()
    write_obj(path, result.positions, result.triangles, normals, result.uvs, header=header)
