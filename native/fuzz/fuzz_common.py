"""What the byte-input fuzzers (fuzz_obj.py, fuzz_lattice_json.py) share: their command line,
the engine choice, the seed corpus and what a crash leaves behind."""
import argparse
import pathlib
import sys
import traceback

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def parser(seconds, corpus):
    """--seconds, --corpus (default native/fuzz/corpus/<corpus>), --out, --seed, --engine, --repro."""
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=seconds)
    ap.add_argument("--corpus", default=str(HERE / "corpus" / corpus))
    ap.add_argument("--out", default=str(ROOT / "build" / "fuzz"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--engine", choices=("auto", "atheris", "mutation"), default="auto")
    ap.add_argument("--repro", help="run one input and show the traceback")
    return ap


def engine(requested):
    """"atheris" when asked for, or on "auto" when it imports; else "mutation"."""
    if requested != "auto":
        return requested
    import importlib.util
    return "atheris" if importlib.util.find_spec("atheris") else "mutation"


def load_corpus(path, fallback):
    files = sorted(pathlib.Path(path).glob("*")) if path else []
    return [f.read_bytes() for f in files if f.is_file()] or [fallback]


def run_one(name, suffix, target, data, out):
    """target(data); on any exception the input is written to out/crash-<name>-<hash><suffix>
    and the process exits 1 with the traceback."""
    try:
        target(data)
    except Exception:
        crash = pathlib.Path(out) / f"crash-{name}-{abs(hash(data)) & 0xffffffff:08x}{suffix}"
        crash.write_bytes(data)
        print(f"fuzz_{name}: CRASH, input written to {crash}\n{traceback.format_exc()}", flush=True)
        sys.exit(1)
