"""The tessellation's true error by dense sampling, independent of the core's bounds: the
distance between output triangles (or a uniform level's triangles) and the cubic patches they
approximate, at 28 points a triangle, the patches evaluated here from their Bernstein
coefficients in numpy. Used by tests/test_adaptive.py, bench/bench_adaptive.py,
scripts/report.py and blender_scenes/bench_addon.py (numpy only: Blender's Python has no pytest).
"""

import numpy as np


def cubic_basis(b):
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([b0**3, b1**3, b2**3, 3*b0*b0*b1, 3*b0*b1*b1, 3*b1*b1*b2, 3*b1*b2*b2,
                     3*b0*b2*b2, 3*b0*b0*b2, 6*b0*b1*b2], axis=-1)


K = 6
W = np.array([(i / K, j / K, (K - i - j) / K) for j in range(K + 1) for i in range(K + 1 - j)])


def adaptive_error(r):
    """Per output triangle, the largest distance between it and its patch at the W points."""
    cp = r["patch_control"].astype(np.float64)
    tri, pos = r["triangles"], r["positions"].astype(np.float64)
    cb, tp = r["corner_bary"].astype(np.float64), r["triangle_patch"]
    worst = np.zeros(len(tri))
    for s in range(0, len(tri), 100000):
        sl = slice(s, s + 100000)
        bary = np.einsum("wc,tcr->twr", W, cb[sl])
        exact = np.einsum("twk,tkr->twr", cubic_basis(bary), cp[tp[sl]])
        lin = np.einsum("wc,tcr->twr", W, pos[tri[sl]])
        worst[sl] = np.linalg.norm(exact - lin, axis=2).max(axis=1)
    return worst


def uniform_error(cp, L):
    """The largest distance between the patches cp and their uniform level-L triangles."""
    cp = cp.astype(np.float64)
    g = lambda i, j: ((L - i - j) / L, i / L, j / L)
    tris = []
    for j in range(L):
        for i in range(L - j):
            tris.append([g(i, j), g(i + 1, j), g(i, j + 1)])
            if i + j < L - 1:
                tris.append([g(i + 1, j), g(i + 1, j + 1), g(i, j + 1)])
    tb = np.array(tris)
    M = cubic_basis(np.einsum("wc,tcr->twr", W, tb)) - np.einsum("wc,tck->twk", W, cubic_basis(tb))
    worst = 0.0
    for s in range(0, len(cp), 128):
        e = np.einsum("twk,pkr->ptwr", M, cp[s:s + 128])
        worst = max(worst, float(np.linalg.norm(e, axis=3).max()))
    return worst


def smallest_uniform_level(cp, tol, start):
    L = max(1, start)
    while L < 64 and uniform_error(cp, L) > tol:
        L += 1
    while L > 1 and uniform_error(cp, L - 1) <= tol:
        L -= 1
    return L
