"""The OBJ reader (smoothffd.io.read_obj) against Blender's own importer
(bpy.ops.wm.obj_import) on files nobody here wrote the way this package writes them.
docs/formats.md lists the outcome; each line of that list is a case here:

* read as Blender reads them: a backslash continuing a line, ASCII control characters as
  blanks, vt/vn indices in a file that defines no vt/vn (the same faces, corner by corner;
  Blender 3.4 drops the faces with vt indices);
* read here, lost there: a UTF-8 byte order mark (Blender drops the first line), UTF-16 with
  its byte order mark, CR-only line ends (read here as their LF twin; Blender's mesh differs);
* refused here with the line, a different mesh there without a word: '3.1+e2' (Blender:
  3.1, and the rest of the line 0), '1_000', '1,5', faces with index 0 or out of range.
"""
import codecs
import importlib
import os
import shutil
import sys
import tempfile
import warnings

import bpy
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # blender -b --python does not
import sffd_testlib as T  # noqa: E402

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
PLAIN = TRI + "v 1 1 0\nf 1 2 3\nf 2 4 3\n"

SAME = {
    "continued lines": b"v 0 0 0\nv 1 0 \\\n0\nv 0 1 0\nv 1 1 0\nf 1 2 \\\n3\nf 2 4 3\n",
    "form feed before v": b"v 0 0 0\nv 1 0 0\n\x0cv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n",
    "control characters between tokens": b"v 0 0 0\nv 1\x0b0\x1f0\nv\x010 1 0\nv 1 1 0\x0c\n"
                                         b"f\t1 2\x1e3\nf 2 4 3\n",
    "vn indices, no vn": (TRI + "v 1 1 0\nf 1//1 2//1 3//1\nf 2//1 4//1 3//1\n").encode(),
    "vt indices, no vt": (TRI + "v 1 1 0\nf 1/1 2/2 3/3\nf 2/1 4/1 3/1\n").encode(),
}
LOST_THERE = {
    "UTF-8 byte order mark": codecs.BOM_UTF8 + PLAIN.encode(),
    "UTF-16 with its byte order mark": codecs.BOM_UTF16_LE + PLAIN.encode("utf-16-le"),
    "CR-only line ends": PLAIN.replace("\n", "\r").encode(),
}
# name: (file, what read_obj's error says, Blender's first vertex or None (its face count))
REFUSED_HERE = {
    "3.1+e2": (b"v 3.1+e2 5 6\nv 0 0 0\nv 0 1 0\nf 1 2 3\n",
               "non-numeric vertex value '3.1+e2' (an exponent's sign follows the e: 3.1e+2)",
               (3.1, 0.0, 0.0)),
    "1_000": (b"v 1_000 5 6\nv 0 0 0\nv 0 1 0\nf 1 2 3\n", "non-numeric vertex value '1_000'",
              (1.0, 0.0, 0.0)),
    "1,5": (b"v 1,5 5 6\nv 0 0 0\nv 0 1 0\nf 1 2 3\n", "non-numeric vertex value '1,5'",
            (1.0, 0.0, 0.0)),
    "index 0": ((TRI + "f 0 1 2\nf 1 2 3\n").encode(), "vertex index 0", None),
    "index out of range": ((TRI + "f 1 2 4\nf 1 2 3\n").encode(), "vertex index 4", None),
}


def blender_faces(path):
    """Blender's import: each polygon as its corners' coordinates, in file order."""
    T.clear()
    r = bpy.ops.wm.obj_import(filepath=path)
    assert r == {'FINISHED'}, r
    faces = []
    for obj in bpy.data.objects:
        if obj.type == 'MESH':
            co = T.positions(obj.data)
            faces += [tuple(map(tuple, co[list(p.vertices)].round(6))) for p in obj.data.polygons]
    return faces


def our_faces(sfio, path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = sfio.read_obj(path)
    co = d.positions.round(6)
    fo = d.face_offsets
    return [tuple(map(tuple, co[d.corner_vertices[fo[i]:fo[i + 1]]])) for i in range(len(fo) - 1)]


def main():
    T.setup()
    sfio = importlib.import_module(T.core_module().__name__ + ".io")
    tmp = tempfile.mkdtemp(prefix="sffd_obj_")

    def write(name, data):
        path = os.path.join(tmp, name.replace(" ", "_").replace("/", "_") + ".obj")
        with open(path, "wb") as fh:
            fh.write(data)
        return path

    want = our_faces(sfio, write("plain", PLAIN.encode()))

    def plain():
        theirs = blender_faces(write("plain", PLAIN.encode()))
        T.check("plain file: Blender and read_obj agree", theirs == want, f"{theirs} vs {want}")

    def same(name, data):
        path = write(name, data)
        ours, theirs = our_faces(sfio, path), blender_faces(path)
        if name == "vt indices, no vt" and bpy.app.version < (4, 0):
            # Blender 3.4 drops those faces (later versions ignore the indices, as here).
            T.check(f"read here, not by Blender {bpy.app.version_string}: {name}",
                    ours == want and theirs == [], f"{ours} / {theirs}")
            return
        T.check(f"read as Blender reads it: {name}", ours == theirs == want, f"{ours} / {theirs}")

    def lost_there(name, data):
        path = write(name, data)
        ours, theirs = our_faces(sfio, path), blender_faces(path)
        T.check(f"read here, not by Blender: {name}", ours == want and theirs != want,
                f"{ours} / {theirs}")

    def refused_here(name, data, message, first):
        path = write(name, data)
        try:
            our_faces(sfio, path)
            refused = ""
        except ValueError as e:
            refused = str(e)
        theirs = blender_faces(path)
        if first is None:   # Blender drops the bad face and keeps the good one
            differs = len(theirs) == 1
        else:
            differs = bool(theirs) and theirs[0][0] == first
        T.check(f"refused here, read differently by Blender: {name}",
                message in refused and differs, f"{refused!r} / {theirs}")

    try:
        T.run("plain file", plain)
        for name, data in SAME.items():
            T.run(name, same, name, data)
        for name, data in LOST_THERE.items():
            T.run(name, lost_there, name, data)
        for name, case in REFUSED_HERE.items():
            T.run(name, refused_here, name, *case)
    finally:
        T.clear()
        shutil.rmtree(tmp)
    T.finish()


main()
