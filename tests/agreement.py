"""How closely the CUDA evaluator agrees with the CPU evaluator on the same plan (both in float
arithmetic, in different orders): the bounds the GPU suites assert, and the worst difference a
run has seen, which tests/conftest.py prints at the end of the run so that the bounds can be
read next to what the product measures.
"""

import numpy as np

# Bounds: positions as a fraction of the lattice's size, normals in radians. Measured over the
# GPU suites (an H200, CUDA 13.0, the shipped cp312 wheel): positions 6.3e-7, normals 4.4e-5
# (float rounding in different orders). The bounds are about 3x and 2.3x that.
POSITIONS = 2e-6
NORMALS = 1e-4

WORST = {}


def _record(what, value):
    WORST[what] = max(WORST.get(what, 0.0), value)
    return value


def angles(a, b):
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, axis=-1))


def positions(gpu, cpu, size):
    """Largest position difference, as a fraction of `size`."""
    d = float(np.abs(np.asarray(gpu, np.float64) - np.asarray(cpu, np.float64)).max()) / size
    return _record("positions (of the lattice size)", d)


def normals(gpu, cpu):
    """Largest angle between corresponding normals (radians)."""
    return _record("normals (rad)", float(angles(gpu, cpu).max()))


def summary():
    return [f"CUDA vs CPU, worst in this run: {k} {v:.3g} (bound "
            f"{POSITIONS if k.startswith('positions') else NORMALS:g})" for k, v in sorted(WORST.items())]
