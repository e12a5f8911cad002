"""Fuzzer for the lattice JSON reader (python/smoothffd/lattice_json.py).

Contract checked on every input: `load_lattice(path)` returns a BSplineLattice or a
BlenderLattice, or raises ValueError or TypeError: nothing else (no KeyError, IndexError,
OverflowError, RecursionError, MemoryError, ...), no warning (warnings are errors here: a numpy
overflow means a value slipped through), no input slower than 5 s, no allocation beyond the
address-space limit (4 GiB). A lattice it returns has finite control values, evaluates to
finite positions at its rest points, and its JSON (lattice_to_dict + dumps_lattice) reads back
to the same structure and control values.

Two engines, as fuzz_obj.py: atheris when importable, else a seeded mutation loop over the seed
corpus: structural mutations of the decoded document (a node replaced by another type, a huge,
tiny, negative, NaN or integral number, a deep or long list, a key dropped, duplicated or
renamed, a list resized) and text mutations (JSON tokens inserted, bytes flipped, spans deleted
or duplicated, splices of other seeds).

  PYTHONPATH=python python3 native/fuzz/fuzz_lattice_json.py --seconds 15
  PYTHONPATH=python python3 native/fuzz/fuzz_lattice_json.py --repro FILE     # one input, traceback
"""
import json
import os
import pathlib
import random
import resource
import signal
import sys
import tempfile
import time
import warnings

import numpy as np

import fuzz_common


TOKENS = [b"null", b"true", b"false", b"[]", b"{}", b"[[", b"]]", b"0", b"-1", b"1e309", b"-0",
          b"NaN", b"Infinity", b"-Infinity", b"1e-320", b"99999999999999999999", b"0.5", b'""',
          b'"bspline"', b'"blender"', b'"shape"', b'"knots"', b'"degree"', b'"points"',
          b'"rest_points"', b'"control_points"', b'"strength"', b'"interpolation"',
          b'"lattice_to_object"', b'"point_weights"', b'"box_min"', b'"box_max"', b'"version"',
          b'"format"', b",",
          b":", b"\\u0000", b"\xff", b"\xef\xbb\xbf", b" ", b"\n", "é".encode()]
NUMBERS = [0, -1, 1, 2, 3, 5, 6, 64, 65, 1023, 1024, 100000, 2**31, 2**63, 10**400, -10**400,
           0.5, -0.0, 1e-300, 1e300, -1e300, 1e308, -1e308, 1.7e308, 1e37, 3.4e38, float("nan"),
           float("inf"), float("-inf"), True, False]


def _scaled(v, f, depth=0):
    """Every number in a nested list (down to depth 30) times f (points near the float64 limit)."""
    if isinstance(v, list):
        return [_scaled(x, f, depth + 1) for x in v] if depth < 30 else v
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        try:
            return v * f
        except OverflowError:
            return v
    return v


class Timeout(Exception):
    pass


def _on_alarm(signum, frame):
    raise Timeout("input ran longer than 5 s")


class Target:
    def __init__(self):
        from smoothffd import lattice_json

        self.lj = lattice_json
        import smoothffd

        self.kinds = (smoothffd.BSplineLattice, smoothffd.BlenderLattice)
        fd, self.path = tempfile.mkstemp(suffix=".json", prefix="fuzz_lattice_")
        os.close(fd)
        self.accepted = self.refused = 0

    def close(self):
        if os.path.exists(self.path):
            os.remove(self.path)

    def __call__(self, data: bytes):
        with open(self.path, "wb") as fh:
            fh.write(data)
        signal.setitimer(signal.ITIMER_REAL, 5.0)
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # numpy's overflow / invalid warnings included
                try:
                    lat = self.lj.load_lattice(self.path)
                except (ValueError, TypeError):
                    self.refused += 1
                    return
                self.accepted += 1
                self.check(lat)
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)

    def check(self, lat):
        assert isinstance(lat, self.kinds), type(lat)
        values = lat.control_values()
        assert np.isfinite(values).all(), "non-finite control values accepted"
        rest = lat.rest_points.reshape(-1, 3)
        if isinstance(lat, self.kinds[1]):  # lattice space -> object space
            m = lat.lattice_to_object
            with np.errstate(all="ignore"):  # rest points near 1e308 overflow: not evaluated below
                rest = rest @ m[:3, :3].T + m[:3, 3]
        weights = getattr(lat, "point_weights", None)
        weights = np.zeros(0) if weights is None else weights
        if (np.abs(rest).max(initial=0) < 1e150 and np.abs(values).max(initial=0) < 1e150
                and np.abs(weights).max(initial=0) < 1e150):
            with np.errstate(all="ignore"):
                F, _ = lat.evaluate(rest)
            assert np.isfinite(F).all(), "non-finite positions at the rest points"
        doc = json.loads(self.lj.dumps_lattice(self.lj.lattice_to_dict(lat)))
        again = self.lj.build_lattice(*self.lj.parse_lattice(doc, "round trip"))
        assert again.structure_key() == lat.structure_key(), "round trip changed the structure"
        assert np.array_equal(again.control_values(), values), "round trip changed the values"
        if weights.size:
            assert np.array_equal(again.point_weights, weights), "round trip changed the weights"


# ---------------------------------------------------------------------------- mutations


def _nodes(doc, path=()):
    """Every (path, value) of a decoded JSON document, down to depth 30."""
    yield path, doc
    if len(path) >= 30:
        return
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from _nodes(v, path + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc[:50]):
            yield from _nodes(v, path + (i,))


def _set(doc, path, value):
    if not path:
        return value
    node = doc
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return doc


def _random_value(rng, old):
    r = rng.random()
    if r < 0.35:
        return rng.choice(NUMBERS)
    if r < 0.45:
        return rng.choice([None, "", "BSPLINE", "x" * rng.randint(1, 300), [], {}, [1, 2, 3],
                           [[0, 0, 0]], "smoothffd-lattice"])
    if r < 0.55 and isinstance(old, (int, float)) and not isinstance(old, bool):
        try:
            return old * rng.choice([-1, 2, 10, 1e10, 1e-10, 1e200]) + rng.choice([0, 1, 0.5])
        except OverflowError:
            return old
    if r < 0.65 and isinstance(old, list):  # resize
        out = list(old)
        if out and rng.random() < 0.5:
            del out[rng.randrange(len(out))]
        elif out:
            out.insert(rng.randrange(len(out) + 1), rng.choice(out))
        else:
            out.append(0)
        return out
    if r < 0.7:  # deep or long lists
        v = rng.choice([0, 1.5])
        for _ in range(rng.choice([3, 50, 500])):
            v = [v]
        return v if rng.random() < 0.5 else [rng.choice(NUMBERS)] * rng.choice([4, 300, 5000])
    if r < 0.75 and isinstance(old, list) and old:
        return [old[0]] * 3  # a triple from a longer list or of lists
    if r < 0.8 and isinstance(old, list):
        return _scaled(old, rng.choice([1e300, -1e300, 1e-300, 1e10, -1]))
    return rng.choice([None, True, 1, 0.1, "BSPLINE", [0, 0, 0], [[1, 0, 0, 0]] * 4])


def mutate_doc(rng, doc):
    doc = json.loads(json.dumps(doc))  # a copy (deepcopy recurses in Python)
    for _ in range(rng.randint(1, 3)):
        nodes = list(_nodes(doc))
        path, old = rng.choice(nodes)
        op = rng.random()
        if op < 0.7 or not isinstance(doc, dict):
            doc = _set(doc, path, _random_value(rng, old))
        elif op < 0.8 and doc:
            del doc[rng.choice(list(doc))]
        elif op < 0.9:
            doc[rng.choice(["knot", "Shape", "name", "comment", "extra", "rest_points", "knots"])] = \
                _random_value(rng, None)
        else:
            k = rng.choice(list(doc)) if doc else "shape"
            doc[k] = doc.get(rng.choice(list(doc)), None) if doc else 1
    return doc


def mutate_text(rng, data, corpus):
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(5)
        pos = rng.randint(0, len(b))
        if op == 0:
            b[pos:pos] = rng.choice(TOKENS)
        elif op == 1 and b:
            b[min(pos, len(b) - 1)] ^= 1 << rng.randrange(8)
        elif op == 2 and b:
            del b[pos:pos + rng.randint(1, 16)]
        elif op == 3:
            other = rng.choice(corpus)
            cut = rng.randint(0, len(other))
            b = b[:pos] + other[cut:cut + rng.randint(1, 300)] + b[pos:]
        else:
            b[pos:pos] = b[pos:pos + rng.randint(1, 40)]
    return bytes(b[:65536])


def mutate(rng, data, corpus):
    if rng.random() < 0.7:
        try:
            doc = json.loads(data)
        except (ValueError, RecursionError):
            doc = None
        if doc is not None:
            out = mutate_doc(rng, doc)
            try:
                text = json.dumps(out, allow_nan=True)
            except (ValueError, RecursionError, OverflowError):
                return mutate_text(rng, data, corpus)
            return text.encode()[:1 << 20]
    if rng.random() < 0.02:
        return rng.choice([b"[" * 100000, b"{" * 50000, b"1" * 5000, b"", b"\xef\xbb\xbf{}",
                           b'{"format": "smoothffd-lattice", "version": 1, "kind": "bspline", "shape": '
                           + b"[" * 20000])
    return mutate_text(rng, data, corpus)


def run_one(target, data, out):
    fuzz_common.run_one("lattice", ".json", target, data, out)


def main():
    args = fuzz_common.parser(15, "lattice").parse_args()
    os.makedirs(args.out, exist_ok=True)
    signal.signal(signal.SIGALRM, _on_alarm)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = 4 << 30
    if soft == resource.RLIM_INFINITY or soft > limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    engine = fuzz_common.engine(args.engine)
    if engine == "atheris" and not args.repro:
        import atheris

        with atheris.instrument_imports(include=["smoothffd"]):
            target = Target()
        work = pathlib.Path(args.out) / "corpus-lattice"
        work.mkdir(parents=True, exist_ok=True)
        print(f"fuzz_lattice_json: atheris, {args.seconds:.0f}s", flush=True)
        atheris.Setup([sys.argv[0], f"-max_total_time={int(args.seconds)}", "-max_len=65536",
                       f"-artifact_prefix={args.out}/crash-lattice-", "-print_final_stats=1",
                       str(work), args.corpus], target)
        atheris.Fuzz()
    target = Target()
    try:
        if args.repro:
            target(pathlib.Path(args.repro).read_bytes())
            print(f"fuzz_lattice_json: {args.repro}: ok "
                  f"({'accepted' if target.accepted else 'refused'})")
            return
        corpus = fuzz_common.load_corpus(args.corpus, b"{}")
        rng = random.Random(args.seed)
        t_end = time.time() + args.seconds
        n = 0
        for s in corpus:
            run_one(target, s, args.out)
        while time.time() < t_end:
            data = mutate(rng, rng.choice(corpus), corpus)
            accepted = target.accepted
            run_one(target, data, args.out)
            n += 1
            if target.accepted > accepted and len(data) < 65536 and rng.random() < 0.2:
                corpus.append(data)  # accepted inputs become parents
        print(f"fuzz_lattice_json: mutation loop, {n} inputs in {args.seconds:.0f}s "
              f"({target.accepted} accepted, {target.refused} refused with ValueError/TypeError), "
              "no crash")
    finally:
        target.close()


if __name__ == "__main__":
    main()
