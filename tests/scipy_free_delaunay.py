"""A tiny Bowyer-Watson Delaunay triangulation (tests only; scipy is not a dependency)."""

import numpy as np


def delaunay(points):
    """(N, 2) points -> (F, 3) counter-clockwise triangles."""
    pts = np.asarray(points, float)
    lo, hi = pts.min(0), pts.max(0)
    d = (hi - lo).max() * 10
    c = (lo + hi) / 2
    allp = np.vstack([pts, [c + [-d, -d], c + [d, -d], c + [0, d]]])
    n = len(pts)
    tris = [(n, n + 1, n + 2)]

    def circum(t):
        a, b, cc = allp[list(t)]
        m = np.array([[b[0] - a[0], b[1] - a[1]], [cc[0] - a[0], cc[1] - a[1]]])
        r = 0.5 * np.array([b @ b - a @ a, cc @ cc - a @ a])
        center = np.linalg.solve(m, r)
        return center, np.sum((a - center) ** 2)

    for i in range(n):
        p = allp[i]
        bad = [t for t in tris if np.sum((p - circum(t)[0]) ** 2) < circum(t)[1]]
        edges = {}
        for t in bad:
            for e in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0])):
                k = tuple(sorted(e))
                edges[k] = edges.get(k, 0) + 1
        tris = [t for t in tris if t not in bad]
        for (a, b), cnt in edges.items():
            if cnt == 1:
                tris.append((a, b, i))
    out = []
    for t in tris:
        if max(t) >= n:
            continue
        a, b, cc = pts[list(t)]
        if (b[0] - a[0]) * (cc[1] - a[1]) - (b[1] - a[1]) * (cc[0] - a[0]) < 0:
            t = (t[0], t[2], t[1])
        out.append(t)
    return np.array(out)
