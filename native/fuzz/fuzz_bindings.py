"""Fuzzer for the bindings' argument conversion (native/python/bindings.cpp, smoothffd._core).

The add-on and power users call the bindings directly, past the package's validation, so every
entry point must turn a wrong argument into a Python exception, never a crash. Each case calls
one of: LatticeSpec.bspline / blender / evaluate, build_plan, estimate_plan_bytes, CpuEvaluator(),
its evaluate / evaluate_compact / evaluate_positions, the Plan's accessors (interpolate_corners,
vertex_sources, ...), with arguments that are mostly right and one of them wrong: arrays of the
wrong shape, length, dtype (complex, object, text, bool, float16), order or endianness,
read-only or strided, values NaN, infinite, 1e300, negative or beyond int32, None or another
type where an array or an object is expected, counts and levels from -1 to 2^31 - 1.

Contract: every call returns or raises an Exception other than SystemError; none crashes the
process (segfault, abort), takes more than 10 s, or exhausts a 4 GiB address space in a way
that kills the process. The cases run in a child process (a crash must not take the fuzzer
with it); the child logs each case's id before running it, so a crash is reported with the
case that caused it, and `--repro SEED:INDEX` runs that case again in this process.

  PYTHONPATH=python python3 native/fuzz/fuzz_bindings.py --seconds 15
  PYTHONPATH=python python3 native/fuzz/fuzz_bindings.py --repro 1:123
"""
import argparse
import pathlib
import random
import resource
import subprocess
import sys
import time
import traceback

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
ROOT = HERE.parents[1]

DTYPES = [np.float64, np.float32, np.float16, np.int32, np.int64, np.uint8, np.bool_,
          np.complex128, object, "U3", ">f8", ">i4"]
NOT_ARRAYS = [None, 3, -1, 2.5, "abc", "", [1, 2, 3], [[1, 2, 3]], [], {}, object(), b"xyz"]
BIG_INTS = [-1, 0, 1, 2, 3, 4, 5, 6, 64, 65, 1023, 1024, 2**20, 2**31 - 1, 2**31, 2**63, -2**31]


# ------------------------------------------------------------------------- value makers


def describe(x):
    if isinstance(x, np.ndarray):
        flags = ("" if x.flags.c_contiguous else " strided") + ("" if x.flags.writeable else " read-only")
        head = np.array2string(x.ravel()[:4], threshold=4) if x.dtype != object else "objects"
        return f"array({x.dtype}, {x.shape}{flags}, {head})"
    if isinstance(x, (list, tuple)) and len(x) > 6:
        return f"{type(x).__name__} of {len(x)}"
    if isinstance(x, (list, tuple)):
        return f"{type(x).__name__}(" + ", ".join(describe(v) for v in x) + ")"
    r = repr(x)
    return r if len(r) < 80 else r[:77] + "..."


def layout(rng, a):
    """The same values in another memory layout now and then."""
    if not isinstance(a, np.ndarray) or a.dtype == object or a.ndim == 0:
        return a
    r = rng.random()
    if r < 0.1:
        a = np.asfortranarray(a)
    elif r < 0.2 and a.shape[0] > 0:
        a = np.repeat(a, 2, axis=0)[::2]  # strided
    elif r < 0.3:
        a = a.copy()
        a.setflags(write=False)
    return a


def numbers(rng, shape):
    kind = rng.random()
    if kind < 0.6:
        return np.random.default_rng(rng.getrandbits(32)).uniform(-1.5, 1.5, shape)
    return np.full(shape, rng.choice([0.0, np.nan, np.inf, -np.inf, 1e300, -1e300, 1e-320, 1e38,
                                       3e38, -1.0, 2.0**31]))


def wrong_array(rng, good):
    """An array or object like `good` but wrong in one way."""
    r = rng.random()
    if r < 0.15:
        return rng.choice(NOT_ARRAYS)
    good = np.asarray(good)
    if r < 0.35:  # another dtype
        dt = rng.choice(DTYPES)
        try:
            return layout(rng, good.astype(dt))
        except (ValueError, TypeError, OverflowError):
            return np.zeros(good.shape, dtype=dt)
    if r < 0.6:  # another shape or length
        n = good.shape[0] if good.ndim else 1
        shape = rng.choice([(), (0,), (n + 1,), (max(n - 1, 0),), (n, 2), (n, 4), (3, n), (n, 3, 1),
                            (1,) + good.shape, (2 * n,), (n * 3,)])
        return layout(rng, numbers(rng, shape).astype(good.dtype if good.dtype.kind in "fiub" else float))
    if r < 0.8:  # odd values
        a = good.astype(np.float64) if good.dtype.kind != "f" else good.copy()
        if a.size:
            flat = a.reshape(-1)
            flat[rng.randrange(a.size)] = rng.choice([np.nan, np.inf, -1e300, 1e300, -1.0, 2.0**40])
        return layout(rng, a.astype(good.dtype) if good.dtype.kind == "f" else a)
    a = good.copy()  # integers out of range
    if a.size and a.dtype.kind in "iu":
        a.reshape(-1)[rng.randrange(a.size)] = rng.choice([-1, -2**31, 2**31 - 1, 10**6, a.max() + 1])
    return layout(rng, a)


def maybe_wrong(rng, good, p=0.15):
    return wrong_array(rng, good) if rng.random() < p else layout(rng, good)


# ------------------------------------------------------------------------- fixtures


def cube():
    X = np.array([[x, y, z] for z in (0.2, 0.8) for y in (0.2, 0.8) for x in (0.2, 0.8)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    cv = np.array(quads, np.int32).ravel()
    fo = np.arange(0, 25, 4, dtype=np.int32)
    return X, cv, fo


class Fixtures:
    def __init__(self, core):
        self.core = core
        X, cv, fo = cube()
        self.mesh = (X, cv, fo)
        m = np.zeros((3, 4))
        for a in range(3):
            m[a, a] = 1.0
        self.map = m
        knots = [np.array([0, 0, 0, 0.5, 1, 1, 1.0])] * 3
        self.bspline = core.LatticeSpec.bspline([2, 2, 2], knots, [4, 4, 4], m)
        self.blender = core.LatticeSpec.blender(["BSPLINE", "LINEAR", "CARDINAL"], [3, 2, 4], m * 2)
        self.plans = [core.build_plan(X, cv, fo, None, None, None, self.bspline, 2),
                      core.build_plan(X, cv, fo, np.tile([0, 0, 1], (24, 1)).astype(np.float32),
                                      np.zeros((24, 2), np.float32), np.ones(8, np.float32),
                                      self.blender, 1)]
        self.evaluators = [core.CpuEvaluator(p, 1) for p in self.plans]


# ------------------------------------------------------------------------- cases


def case_bspline(rng, fx):
    core = fx.core
    p = [rng.randint(1, 5) for _ in range(3)]
    n = [pi + rng.randint(1, 3) for pi in p]
    knots = [np.sort(np.random.default_rng(rng.getrandbits(32)).uniform(-2, 2, n[a] + p[a] + 1))
             for a in range(3)]
    args = [p, knots, n, fx.map]
    i = rng.randrange(4)
    if i == 0:
        args[0] = rng.choice([[rng.choice(BIG_INTS) for _ in range(3)], p[:2], p + [1], None, [1.5, 2, 2],
                              "abc", [None, 1, 1]])
    elif i == 1:
        k = list(knots)
        j = rng.randrange(3)
        k[j] = wrong_array(rng, k[j])
        args[1] = rng.choice([k, k[:2], k + [k[0]], None, "knots", np.zeros((3, 7))])
    elif i == 2:
        args[2] = rng.choice([[rng.choice(BIG_INTS) for _ in range(3)], n[:2], None, [n[0], -n[1], n[2]]])
    else:
        args[3] = wrong_array(rng, fx.map)
    return "LatticeSpec.bspline", lambda: core.LatticeSpec.bspline(*args), args


def case_blender(rng, fx):
    core = fx.core
    names = ["LINEAR", "CARDINAL", "CATMULL_ROM", "BSPLINE", "KEY_BSPLINE", "", "linear", "X" * 200]
    types = [rng.choice(names[:4]) for _ in range(3)]
    counts = [rng.randint(1, 5) for _ in range(3)]
    args = [types, counts, fx.map]
    i = rng.randrange(3)
    if i == 0:
        args[0] = rng.choice([[rng.choice(names) for _ in range(3)], types[:2], None, "BSPLINE", [1, 2, 3]])
    elif i == 1:
        args[1] = rng.choice([[rng.choice(BIG_INTS) for _ in range(3)], counts[:1], None, [2.5, 2, 2]])
    else:
        args[2] = wrong_array(rng, fx.map)
    return "LatticeSpec.blender", lambda: core.LatticeSpec.blender(*args), args


def case_spec_evaluate(rng, fx):
    spec = rng.choice([fx.bspline, fx.blender])
    count = 3 * (4 * 4 * 4 if spec is fx.bspline else 3 * 2 * 4)
    pts = numbers(rng, (5, 3))
    D = np.zeros(count)
    w = np.ones(5)
    args = [maybe_wrong(rng, pts, 0.4), maybe_wrong(rng, D, 0.4), maybe_wrong(rng, w, 0.4)]
    return "LatticeSpec.evaluate", lambda: spec.evaluate(*args), args


def case_build_plan(rng, fx):
    core = fx.core
    X, cv, fo = fx.mesh
    C, V = len(cv), len(X)
    args = [X, cv, fo, None, None, None, rng.choice([fx.bspline, fx.blender]), rng.randint(1, 3)]
    kw = {}
    extras = [np.tile(np.float32([0, 0, 1]), (C, 1)), np.zeros((C, 2), np.float32),
              np.ones(V, np.float32)]
    for j in range(3):
        if rng.random() < 0.4:
            args[3 + j] = extras[j]
    i = rng.randrange(10)
    if i < 3:
        args[i] = wrong_array(rng, args[i])
    elif i < 6:
        args[i] = wrong_array(rng, extras[i - 3])
    elif i == 6:
        args[6] = rng.choice([None, 3, "lattice", fx.plans[0]])
    elif i == 7:
        args[7] = rng.choice(BIG_INTS + [2.5, None, "3", -2**31 - 1, 10**30])
    elif i == 8:
        kw["sharp_angle_degrees"] = rng.choice([np.nan, np.inf, -1.0, 1e300, 0.0, 180.0, "x", None])
    else:
        kw["memory_limit"] = rng.choice([np.nan, -1.0, 1.0, 1e300, np.inf, 0.0, "x"])
    return "build_plan", lambda: core.build_plan(*args, **kw), args + [kw]


def case_estimate(rng, fx):
    args = [rng.choice(BIG_INTS + [-2**31 - 1, 10**20]) for _ in range(4)] + [rng.choice([True, False, 2, None])]
    return "estimate_plan_bytes", lambda: fx.core.estimate_plan_bytes(*args), args


def case_evaluator_init(rng, fx):
    args = [rng.choice(fx.plans + [None, fx.bspline, 3]),
            rng.choice([0, 1, 2, -1, -2**31, 2**31 - 1, 2**31, 4096, 2.5, None]),
            rng.choice(["auto", "x86-64-v2", "x86-64-v3", "", "avx512", None, 3])]
    def run():
        ev = fx.core.CpuEvaluator(args[0], args[1], isa=args[2])
        if isinstance(args[0], type(fx.plans[0])):
            dims = args[0].dims
            ev.evaluate(np.zeros((dims[0] * dims[1] * dims[2], 3), np.float32))
    return "CpuEvaluator()", run, args


def case_evaluate(rng, fx):
    k = rng.randrange(len(fx.plans))
    plan, ev = fx.plans[k], fx.evaluators[k]
    nd = plan.dims[0] * plan.dims[1] * plan.dims[2]
    D = np.random.default_rng(rng.getrandbits(32)).uniform(-0.1, 0.1, (nd, 3)).astype(np.float32)
    pos = np.zeros((plan.output_vertices, 3), np.float32)
    nrm = np.zeros((plan.output_triangles, 3, 3), np.float32)
    rnrm = np.zeros((plan.render_vertex_count, 3), np.float32)
    which = rng.randrange(3)
    D = maybe_wrong(rng, D, 0.5)
    if which == 0:
        args = [D, maybe_wrong(rng, pos, 0.3) if rng.random() < 0.5 else None,
                maybe_wrong(rng, nrm, 0.3) if rng.random() < 0.5 else None]
        return "CpuEvaluator.evaluate", lambda: ev.evaluate(*args), args
    if which == 1:
        args = [D, maybe_wrong(rng, pos, 0.3) if rng.random() < 0.5 else None,
                maybe_wrong(rng, rnrm, 0.3) if rng.random() < 0.5 else None,
                rng.choice([True, False, None, 2])]
        if rng.random() < 0.1 and isinstance(args[1], np.ndarray):
            args[2] = args[1]  # the same array for both outputs
        return "CpuEvaluator.evaluate_compact", lambda: ev.evaluate_compact(*args), args
    args = [D, maybe_wrong(rng, pos, 0.3) if rng.random() < 0.5 else None]
    return "CpuEvaluator.evaluate_positions", lambda: ev.evaluate_positions(*args), args


def case_plan_methods(rng, fx):
    plan = rng.choice(fx.plans)
    C = 24
    values = np.random.default_rng(rng.getrandbits(32)).uniform(-1, 1, rng.choice([(C,), (C, 2), (C, 5)]))
    values = values.astype(np.float32)
    name = rng.choice(["interpolate_corners", "vertex_sources", "patch_sources", "input_triangles",
                       "render_vertices", "render_owner", "fit_matrix", "uvs", "triangles",
                       "rest_positions", "sharp_edges", "edge_flags"])
    if name == "interpolate_corners":
        arg = maybe_wrong(rng, values, 0.6)
        if rng.random() < 0.1:
            arg = np.zeros((C, 0), np.float32)
        return "Plan.interpolate_corners", lambda: plan.interpolate_corners(arg), [arg]
    return f"Plan.{name}", lambda: getattr(plan, name)(), []


CASES = [case_bspline, case_blender, case_spec_evaluate, case_build_plan, case_estimate,
         case_evaluator_init, case_evaluate, case_evaluate, case_plan_methods]


def make_case(seed, index, fx):
    rng = random.Random(f"{seed}:{index}")
    return rng.choice(CASES)(rng, fx)


# ------------------------------------------------------------------------- child and parent


def limit_memory():
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    limit = 4 << 30
    if soft == resource.RLIM_INFINITY or soft > limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))


def run_case(seed, index, fx, stats, log=None):
    name, call, args = make_case(seed, index, fx)
    if log is not None:
        log.write(f"{seed}:{index} {name} " + ", ".join(describe(a) for a in args) + "\n")
        log.flush()
    t0 = time.perf_counter()
    try:
        call()
        outcome = "ok"
    except SystemError:
        raise
    except Exception as e:  # a Python exception is the contract
        outcome = type(e).__name__
    dt = time.perf_counter() - t0
    # A slow refusal is a finding (level 2**31 - 1 once allocated for 11 s before failing); a
    # call that succeeds does work in proportion to what it returns (level 1023 on a cube:
    # 12.5 M triangles, 3.6 GB, 6-10.5 s on the 2-core machine), up to the parent's hang limit.
    if dt > (10 if outcome != "ok" else 25):
        raise AssertionError(f"{seed}:{index} {name} took {dt:.1f} s ({outcome})")
    stats[(name, outcome)] = stats.get((name, outcome), 0) + 1


def child(args):
    import warnings

    warnings.simplefilter("ignore")  # numpy's casting warnings while making odd arrays
    limit_memory()
    from smoothffd import _core

    fx = Fixtures(_core)
    stats = {}
    t_end = time.time() + args.seconds
    i = args.start
    with open(args.log, "a") as log:
        while time.time() < t_end:
            run_case(args.seed, i, fx, stats, log)
            i += 1
        log.write(f"DONE {i - args.start}\n")
        for (name, outcome), n in sorted(stats.items()):
            log.write(f"STAT {name} {outcome} {n}\n")


def parent(args):
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log = out / "fuzz_bindings.log"
    log.write_text("")
    cmd = [sys.executable, __file__, "--child", "--seed", str(args.seed), "--seconds",
           str(args.seconds), "--log", str(log)]
    t0 = time.time()
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    last_size, last_change = 0, time.time()
    while proc.poll() is None:
        time.sleep(0.5)
        size = log.stat().st_size
        if size != last_size:
            last_size, last_change = size, time.time()
        elif time.time() - last_change > 30:
            proc.kill()
            proc.wait()
            break
    output = proc.stdout.read()
    lines = log.read_text().splitlines()
    cases = [l for l in lines if l and l[0].isdigit()]
    done = [l for l in lines if l.startswith("DONE")]
    if proc.returncode != 0 or not done:
        last = cases[-1] if cases else "(no case started)"
        why = ("hung (no new case for 30 s)" if proc.returncode in (-9, None) and time.time() - last_change > 30
               else f"exit status {proc.returncode}")
        crash = out / f"crash-bindings-{last.split()[0].replace(':', '-')}.txt"
        crash.write_text(f"{why}\nlast case: {last}\n\n{output[-5000:]}")
        print(f"fuzz_bindings: CRASH ({why}) in case {last}\n{output[-3000:]}\n"
              f"written to {crash}; reproduce: PYTHONPATH=python python3 {__file__} --repro "
              f"{last.split()[0]}", flush=True)
        sys.exit(1)
    stats = {}
    for l in lines:
        if l.startswith("STAT "):
            _, name, outcome, n = l.split(" ")
            stats.setdefault(name, {})[outcome] = int(n)
    n = int(done[0].split()[1])
    summary = "; ".join(f"{name} " + ", ".join(f"{k} {v}" for k, v in sorted(o.items()))
                        for name, o in sorted(stats.items()))
    print(f"fuzz_bindings: {n} calls in {time.time() - t0:.0f}s, no crash ({summary})", flush=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=15)
    ap.add_argument("--out", default=str(ROOT / "build" / "fuzz"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--repro", help="SEED:INDEX of a case to run here, with its traceback")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--start", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--log", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(args)
    if args.repro:
        from smoothffd import _core

        limit_memory()
        seed, index = (int(x) for x in args.repro.split(":"))
        name, _, cargs = make_case(seed, index, Fixtures(_core))
        print(f"fuzz_bindings: case {args.repro}: {name} " + ", ".join(describe(a) for a in cargs), flush=True)
        stats = {}
        try:
            run_case(seed, index, Fixtures(_core), stats)
        except Exception:
            traceback.print_exc()
            sys.exit(1)
        print(f"fuzz_bindings: {stats}")
        return
    parent(args)


if __name__ == "__main__":
    main()
