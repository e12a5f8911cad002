"""Fuzzer for the command line's argument handling (python/smoothffd/cli.py), in process.

Contract checked on every argv: `cli.main(argv)` returns 0 or 2, or argparse exits with 0
(--help) or 2; no exception escapes (that would be a traceback); status 2 ends stderr with one
line "...: error: ..." and nothing on stderr looks like a traceback; no temporary file of an
atomic write is left behind; no run takes longer than 20 s; no unplanned allocation fails
(numpy's "Unable to allocate" or a bare MemoryError as the message; the address space is
limited to 4 GiB), while a refusal that says why (the Deformer's memory check) is fine.

Inputs: argv built from the parser itself (every subcommand, every option with values of its
type: valid, negative, zero, huge, nan, inf, empty, other scripts' digits, long strings) and
small files made once in a temporary folder (a cube OBJ with and without normals, its .gz, B-spline
and Blender lattice JSON, an empty and a binary file, a folder, a missing path), then mutated
(tokens dropped, duplicated, swapped, replaced or inserted). Runs in that folder, so relative
outputs land there; the files are restored when a run overwrote them.

  PYTHONPATH=python python3 native/fuzz/fuzz_cli.py --seconds 15
  PYTHONPATH=python python3 native/fuzz/fuzz_cli.py --repro FILE     # FILE: a JSON argv list
"""
import argparse
import contextlib
import io as stdio
import json
import os
import pathlib
import random
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
import warnings

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]

INTS = ["0", "1", "2", "3", "4", "5", "6", "-1", "-5", "8", "64", "65", "1000", "1024", "4097",
        "2147483648", "99999999999999999999", "1e3", "0x10", "", "nan", "+3", " 4", "\u0663", "3.0"]
FLOATS = ["0", "1", "-1", "0.5", "2.5", "45", "90", "-720", "1e-300", "1e300", "1e308", "1e309",
          "-1e309", "inf", "-inf", "nan", "-0", "1_0", "", "1e", "\u0663", "-1e-3", "1e-3", "10"]
STRINGS = ["", "-", "--", "x", "\u00e9", "a" * 300, "line\nbreak", "-o", "--level", "help"]


class Timeout(Exception):
    pass


def _on_alarm(signum, frame):
    raise Timeout("run took longer than 20 s")


CUBE = """v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
"""


def make_files(folder):
    """The fixture files -> {name: bytes} (restored after any run that changed them)."""
    from smoothffd import cli, lattice_json

    files = {"cube.obj": CUBE.encode()}
    normals = CUBE + "vn 0 0 -1\nvn 0 0 1\n"
    files["cube_n.obj"] = normals.replace("f 1 4 3 2", "f 1//1 4//1 3//1 2//1").replace(
        "f 5 6 7 8", "f 5//2 6//2 7//2 8//2").encode()
    doc = cli.make_lattice_doc([-0.1] * 3, [1.1] * 3, (4, 4, 4), (2, 2, 2), "bspline", "twist", 30.0)
    files["lat.json"] = lattice_json.dumps_lattice(doc).encode()
    doc = cli.make_lattice_doc([-0.1] * 3, [1.1] * 3, (3, 3, 2), kind="blender", mode="bend",
                               amount=20.0, interpolation="CARDINAL")
    files["blender.json"] = lattice_json.dumps_lattice(doc).encode()
    files["empty.obj"] = b""
    files["binary.json"] = bytes(range(256))
    import gzip

    files["cube.obj.gz"] = gzip.compress(CUBE.encode())
    for name, data in files.items():
        (folder / name).write_bytes(data)
    (folder / "adir").mkdir(exist_ok=True)
    return files


class Target:
    def __init__(self, folder):
        from smoothffd import cli

        self.cli, self.folder = cli, folder
        self.files = make_files(folder)
        self.paths = list(self.files) + ["adir", "missing.obj", "out.obj", "out.json",
                                         "sub/new/out.obj", "out.obj.gz", "cube.obj",
                                         str(folder / "abs_out.obj"), "adir/x.json"]
        parser = cli.build_parser()
        sub = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"][0]
        self.commands = {name: [a for a in sp._actions] for name, sp in sub.choices.items()}
        self.status = {}

    def restore(self):
        for name, data in self.files.items():
            p = self.folder / name
            try:
                if p.is_file() and p.read_bytes() == data:
                    continue
                if p.is_dir():
                    shutil.rmtree(p)
                p.write_bytes(data)
            except OSError:
                pass
        # Outputs of earlier runs go: a result read back as input would grow the inputs run by run.
        adir = self.folder / "adir"
        for p in list(self.folder.iterdir()) + (list(adir.iterdir()) if adir.is_dir() else []):
            if p.name not in self.files and p != adir:
                if p.is_dir():
                    shutil.rmtree(p, ignore_errors=True)
                else:
                    p.unlink()
        if not adir.is_dir():
            if adir.exists():
                adir.unlink()
            adir.mkdir()

    # ---------------------------------------------------------------- argv generation
    def value(self, rng, action):
        if action.choices:
            return rng.choice(list(action.choices) + ["", "CUDA", "bogus"])
        if action.type is int:
            return rng.choice(INTS)
        if action.type is float:
            return rng.choice(FLOATS)
        return rng.choice(self.paths) if rng.random() < 0.8 else rng.choice(STRINGS)

    def argv(self, rng):
        names = list(self.commands)
        cmd = rng.choice(names) if rng.random() < 0.95 else rng.choice(["", "bogus", "-h", "--version"])
        argv = [cmd]
        for action in self.commands.get(cmd, []):
            required = action.required or (not action.option_strings and action.nargs is None)
            if not required and rng.random() < 0.6:
                continue
            if action.option_strings:
                if "-h" in action.option_strings and rng.random() < 0.9:
                    continue
                argv.append(rng.choice(action.option_strings))
            if action.nargs == 0:
                continue
            n = action.nargs if isinstance(action.nargs, int) else 1
            if action.nargs == "+":
                n = rng.choice([1, 1, 2, 3, 6])
            if rng.random() < 0.05:
                n = max(0, n + rng.choice([-1, 1]))  # one value too few or too many
            argv.extend(self.value(rng, action) for _ in range(n))
        if cmd == "make-lattice" and rng.random() < 0.7:  # mostly valid sizes: get past argparse
            for i, tok in enumerate(argv):
                if tok in ("--shape", "--degree") and i + 3 < len(argv):
                    lo = 1 if tok == "--degree" else 2
                    for k in range(1, 4):
                        argv[i + k] = str(rng.randint(lo, 6) if rng.random() < 0.9 else rng.choice(INTS))
        return argv

    def mutate(self, rng, argv):
        argv = list(argv)
        for _ in range(rng.randint(0, 3)):
            op = rng.randrange(5)
            i = rng.randrange(len(argv) + 1)
            if op == 0 and argv:
                del argv[min(i, len(argv) - 1)]
            elif op == 1 and argv:
                argv.insert(i, argv[rng.randrange(len(argv))])
            elif op == 2 and len(argv) > 1:
                j = rng.randrange(len(argv))
                k = rng.randrange(len(argv))
                argv[j], argv[k] = argv[k], argv[j]
            elif op == 3:
                argv.insert(i, rng.choice(INTS + FLOATS + STRINGS + self.paths))
            else:
                opts = [o for acts in self.commands.values() for a in acts for o in a.option_strings]
                argv.insert(i, rng.choice(opts))
        return argv

    # ---------------------------------------------------------------- one run
    def __call__(self, argv):
        out, err = stdio.StringIO(), stdio.StringIO()
        code = None
        signal.setitimer(signal.ITIMER_REAL, 20.0)
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), \
                    warnings.catch_warnings():
                warnings.simplefilter("ignore")  # the core's RuntimeWarnings are not the CLI's
                try:
                    code = self.cli.main(list(argv))
                except SystemExit as e:  # argparse
                    code = e.code
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        err = err.getvalue()
        key = (argv[0] if argv else "", code)
        self.status[key] = self.status.get(key, 0) + 1
        assert code in (0, 2), f"exit status {code!r}; stderr: {err[-2000:]}"
        assert "Traceback" not in err, err[-2000:]
        if code == 2:
            shown = err  # an argument's own line breaks, echoed in the message, are not lines
            for tok in argv:
                if "\n" in tok:
                    shown = shown.replace(tok, tok.replace("\n", "\\n"))
            last = shown.rstrip("\n").split("\n")[-1]
            assert ": error: " in last, f"status 2 without an error line: {err[-2000:]!r}"
            assert len(last) < 2000, "an error line of 2000 characters"
            # A refused allocation nobody planned for (numpy's "Unable to allocate", a bare
            # MemoryError): a small argv must not ask for gigabytes.
            assert "Unable to allocate" not in last and not last.endswith("error: MemoryError"), last
        left = [p.name for p in self.folder.rglob(".*.tmp")]
        assert not left, f"temporary files left: {left}"


def run_one(target, argv, out):
    try:
        target(argv)
    except Exception:
        crash = pathlib.Path(out) / f"crash-cli-{abs(hash(tuple(argv))) & 0xffffffff:08x}.json"
        crash.write_text(json.dumps(argv))
        print(f"fuzz_cli: CRASH on argv {argv!r}, written to {crash}\n{traceback.format_exc()}",
              flush=True)
        sys.exit(1)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=15)
    ap.add_argument("--out", default=str(ROOT / "build" / "fuzz"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repro", help="a JSON list of arguments to run once, with its traceback")
    args = ap.parse_args()
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    signal.signal(signal.SIGALRM, _on_alarm)
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = 4 << 30
    if soft == resource.RLIM_INFINITY or soft > limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    here = os.getcwd()
    with tempfile.TemporaryDirectory(prefix="fuzz_cli_") as tmp:
        folder = pathlib.Path(tmp)
        os.chdir(folder)
        try:
            target = Target(folder)
            if args.repro:
                argv = json.loads(pathlib.Path(here, args.repro).read_text())
                target(argv)
                print(f"fuzz_cli: {argv!r}: ok")
                return
            rng = random.Random(args.seed)
            t_end = time.time() + args.seconds
            n = 0
            while time.time() < t_end:
                argv = target.argv(rng)
                if rng.random() < 0.5:
                    argv = target.mutate(rng, argv)
                run_one(target, argv, out)
                target.restore()
                n += 1
            ok = sum(v for (c, code), v in target.status.items() if code == 0)
            deep = ", ".join(f"{c} {v}" for (c, code), v in sorted(target.status.items()) if code == 0)
            counts = f"{ok} exit 0: {deep}; {n - ok} exit 2"
            print(f"fuzz_cli: {n} command lines in {args.seconds:.0f}s ({counts}), no crash")
        finally:
            os.chdir(here)


if __name__ == "__main__":
    main()
