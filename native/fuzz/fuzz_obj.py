"""Fuzzer for the OBJ reader (python/smoothffd/io.py), which is pure Python.

Contract checked on every input: `read_obj` either returns consistent data or raises
ValueError (nothing else: no IndexError, TypeError, MemoryError, ...). Consistent means: finite
float64 positions (V, 3); int corner indices in [0, V); face offsets from 0 to C, every face
with at least 3 corners; normals (C, 3) / uvs (C, 2) finite or None. The data must then be
accepted by `smoothffd.Mesh` (when the native core is built), and `write_obj` followed by
`read_obj` must give back the same face structure. Differential: wherever the vectorized
reader accepts a file, the line-by-line reader must give the same arrays.

Two engines:
- atheris (coverage-guided libFuzzer for Python) when importable, e.g. from build/venv-fuzz
  (`python3 -m venv --system-site-packages build/venv-fuzz && build/venv-fuzz/bin/pip install atheris`);
- otherwise a seeded random-mutation loop over the seed corpus (token insertions from an OBJ
  dictionary, byte flips, deletions, line duplication, splicing).

  PYTHONPATH=python python3 native/fuzz/fuzz_obj.py --seconds 30 --corpus native/fuzz/corpus/obj
  PYTHONPATH=python python3 native/fuzz/fuzz_obj.py --repro FILE     # one input, traceback
"""
import os
import pathlib
import random
import sys
import tempfile
import time
import warnings

import numpy as np

import fuzz_common

HERE = fuzz_common.HERE
ROOT = fuzz_common.ROOT

TOKENS = [b"v ", b"vt ", b"vn ", b"f ", b"o x", b"g ", b"s off", b"l 1 2", b"usemtl m", b"#",
          b"/", b"//", b"-", b"-1", b"0", b"1", b"2", b"3", b"-2", b"99999999999", b"1e309",
          b"nan", b"inf", b"-inf", b"0.5", b"1e-320", b"\n", b"\r\n", b"\r", b" ", b"\t", b"\\\n",
          b"\x00", b"\xff", b"1/1/1", b"1//1", b"2/2", b"f 1 2 3\n", b"v 0 0 0\n", b"+1", b"1.5",
          b"0x10", b"1_0", "é".encode()]


def _import_io():
    """smoothffd.io (and Mesh when the native core is built), without requiring the core."""
    import importlib
    import types

    sys.path.insert(0, str(ROOT / "python"))
    try:
        import smoothffd

        return importlib.import_module("smoothffd.io"), smoothffd.Mesh
    except ImportError:
        pkg = types.ModuleType("smoothffd")
        pkg.__path__ = [str(ROOT / "python" / "smoothffd")]
        sys.modules["smoothffd"] = pkg
        return importlib.import_module("smoothffd.io"), None


class Target:
    def __init__(self, io, Mesh):
        self.io, self.Mesh = io, Mesh
        fd, self.path = tempfile.mkstemp(suffix=".obj", prefix="fuzz_obj_")
        os.close(fd)
        self.out = self.path[:-4] + "_w.obj"
        self.accepted = self.refused = 0

    def close(self):
        for p in (self.path, self.out):
            if os.path.exists(p):
                os.remove(p)

    def __call__(self, data: bytes):
        with open(self.path, "wb") as fh:
            fh.write(data)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.compare_readers(data)
            try:
                d = self.io.read_obj(self.path)
            except ValueError:
                self.refused += 1
                return
            self.accepted += 1
            self.check(d)

    def compare_readers(self, data):
        """Differential: where the fast reader takes a file, the slow one reads the same."""
        try:
            text = self.io._decode(data, "x")
        except ValueError:  # NUL characters: refused before either reader runs
            return
        fast = self.io._read_fast(text, "x")
        if fast is None:
            return
        slow = self.io._read_slow(text, "x")  # must not raise where the fast one accepted
        for name in ("positions", "corner_vertices", "face_offsets", "corner_normals", "uvs"):
            a, b = getattr(fast, name), getattr(slow, name)
            assert (a is None) == (b is None) and (a is None or np.array_equal(a, b)), \
                f"the two OBJ readers disagree on {name}"

    def check(self, d):
        V = len(d.positions)
        assert d.positions.dtype == np.float64 and d.positions.shape == (V, 3), d.positions.shape
        assert np.isfinite(d.positions).all(), "non-finite position accepted"
        cv, fo = np.asarray(d.corner_vertices), np.asarray(d.face_offsets)
        C = len(cv)
        assert np.issubdtype(cv.dtype, np.integer) and np.issubdtype(fo.dtype, np.integer)
        assert fo.ndim == 1 and len(fo) >= 1 and fo[0] == 0 and fo[-1] == C, (fo[:3], C)
        assert (np.diff(fo) >= 3).all(), "face with fewer than 3 corners accepted"
        assert C == 0 or (cv.min() >= 0 and cv.max() < V), "corner index out of range accepted"
        if d.corner_normals is not None:
            assert d.corner_normals.shape == (C, 3) and np.isfinite(d.corner_normals).all()
        if d.uvs is not None:
            assert d.uvs.shape == (C, 2) and np.isfinite(d.uvs).all()
        if C == 0:
            return
        if self.Mesh is not None:
            # Must not raise, except for normals/uvs beyond float32 (the Mesh stores float32),
            # which must be refused with a message saying so.
            f32 = np.finfo(np.float32).max
            big = any(a is not None and np.abs(a).max(initial=0) > f32 for a in (d.corner_normals, d.uvs))
            try:
                self.Mesh(d.positions, (cv, fo), d.corner_normals, d.uvs)
            except ValueError as exc:
                if not (big and "out of the float32 range" in str(exc)):
                    raise
        # Round trip: the writer's output reads back with the same faces.
        self.io.write_obj(self.out, d.positions, (cv, fo), d.corner_normals, d.uvs)
        e = self.io.read_obj(self.out)
        assert np.array_equal(np.asarray(e.face_offsets), fo), "round trip changed faces"
        assert np.allclose(e.positions[np.asarray(e.corner_vertices)], d.positions[cv],
                           rtol=1e-6, atol=1e-30 + 1e-6 * np.abs(d.positions).max()), "round trip moved vertices"


def mutate(rng, data: bytes, corpus):
    b = bytearray(data)
    for _ in range(rng.randint(1, 6)):
        op = rng.randrange(7)
        pos = rng.randint(0, len(b))
        if op == 0:
            b[pos:pos] = rng.choice(TOKENS)
        elif op == 1 and b:
            b[min(pos, len(b) - 1)] ^= 1 << rng.randrange(8)
        elif op == 2 and b:
            del b[pos:pos + rng.randint(1, 8)]
        elif op == 3:  # duplicate a line
            lines = bytes(b).split(b"\n")
            i = rng.randrange(len(lines))
            lines.insert(rng.randrange(len(lines) + 1), lines[i])
            b = bytearray(b"\n".join(lines))
        elif op == 4:  # splice with another seed
            other = rng.choice(corpus)
            cut = rng.randint(0, len(other))
            b = b[:pos] + other[cut:cut + rng.randint(1, 200)]
        elif op == 5:  # replace a number-like token
            b[pos:pos + rng.randint(0, 3)] = str(rng.choice([0, -1, 1, 2, -5, 10 ** rng.randint(1, 30),
                                                           rng.uniform(-1e6, 1e6)])).encode()
        else:
            b[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 4)))
    return bytes(b[:8192])


def run_mutation(target, seconds, corpus, out, seed):
    rng = random.Random(seed)
    t_end = time.time() + seconds
    n = 0
    for s in corpus:
        run_one(target, s, out)
    while time.time() < t_end:
        data = mutate(rng, rng.choice(corpus), corpus)
        run_one(target, data, out)
        n += 1
        if rng.random() < 0.02 and target.accepted:
            corpus.append(data)  # keep some accepted inputs as new parents
    return n


def run_one(target, data, out):
    fuzz_common.run_one("obj", ".obj", target, data, out)


def main():
    args = fuzz_common.parser(30, "obj").parse_args()
    os.makedirs(args.out, exist_ok=True)
    engine = fuzz_common.engine(args.engine)
    if engine == "atheris" and not args.repro:
        import atheris

        with atheris.instrument_imports(include=["smoothffd"]):
            io, Mesh = _import_io()
        target = Target(io, Mesh)
        import atexit

        atexit.register(target.close)
        work = pathlib.Path(args.out) / "corpus-obj"
        work.mkdir(parents=True, exist_ok=True)
        print(f"fuzz_obj: atheris, {args.seconds:.0f}s", flush=True)
        atheris.Setup([sys.argv[0], f"-max_total_time={int(args.seconds)}", "-max_len=4096",
                       f"-artifact_prefix={args.out}/crash-obj-", f"-dict={HERE / 'obj.dict'}",
                       "-print_final_stats=1", str(work), args.corpus], target)
        atheris.Fuzz()  # exits the process
    io, Mesh = _import_io()
    target = Target(io, Mesh)
    try:
        if args.repro:
            target(pathlib.Path(args.repro).read_bytes())
            print(f"fuzz_obj: {args.repro}: ok ({'accepted' if target.accepted else 'ValueError'})")
            return
        corpus = fuzz_common.load_corpus(args.corpus, b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        n = run_mutation(target, args.seconds, corpus, args.out, args.seed)
        print(f"fuzz_obj: mutation loop, {n} inputs in {args.seconds:.0f}s "
              f"({target.accepted} accepted, {target.refused} refused with ValueError), no crash")
    finally:
        target.close()


if __name__ == "__main__":
    main()
