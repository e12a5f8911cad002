"""How many sample evaluations the inline kernel would save by sharing the samples of a group's
patches (an idea not taken up), on W1 at L = 10, host only (no GPU needed).

Today every patch evaluates its 28 columns: 10 interior samples, 5 on each edge, 3 corners. A
sample on an edge belongs to both patches of the edge, a corner to every patch around the
vertex; a group (32 patches a block) could evaluate each of its samples once. This counts the
evaluations a frame for groups of 32 in the plan's patch order and in greedy compact regions
(each grown from the first unassigned patch over shared edges), sharing the edge samples only
or the corners too.

    PYTHONPATH=python python3 bench/share_probe.py
"""

import collections
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu  # noqa: E402
import smoothffd  # noqa: E402

GROUP = 32
P, F, N = bench_gpu.torus(167, 140)
lat = bench_gpu.lattice_for(P, np.random.default_rng(2015))
mesh = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
plan = smoothffd.Deformer(mesh, lat, level=10, device="cpu").plan
pv = np.asarray(plan.patch_vertex())
n = len(pv)
ends = np.sort(np.stack([pv[:, [0, 1]], pv[:, [1, 2]], pv[:, [2, 0]]], 1), axis=2)
_, eid = np.unique((ends[..., 0].astype(np.int64) << 32) + ends[..., 1], return_inverse=True)
eid = eid.reshape(-1, 3)

neighbours = collections.defaultdict(list)
by_edge = collections.defaultdict(list)
for p in range(n):
    for e in eid[p]:
        by_edge[e].append(p)
for ps in by_edge.values():
    for a in ps:
        neighbours[a] += [b for b in ps if b != a]


def regions():
    taken = np.zeros(n, bool)
    order = []
    for s in range(n):
        if taken[s]:
            continue
        grp, i = [s], 0
        taken[s] = True
        while i < len(grp) and len(grp) < GROUP:
            for q in neighbours[grp[i]]:
                if not taken[q] and len(grp) < GROUP:
                    taken[q] = True
                    grp.append(q)
            i += 1
        order += grp
    return np.array(order)


def evaluations(order, corners):
    total = 0
    for g in range(0, len(order), GROUP):
        ps = order[g:g + GROUP]
        total += 10 * len(ps) + 5 * len(np.unique(eid[ps]))
        total += len(np.unique(pv[ps])) if corners else 3 * len(ps)
    return total


print(f"W1 L=10: {n} patches, {plan.samples} samples ({plan.samples / n:.1f} a patch), "
      f"today {28 * n} evaluations (28 a patch)")
for name, order in (("plan order", np.arange(n)), ("compact regions", regions())):
    for corners in (False, True):
        t = evaluations(order, corners)
        what = "edge samples and corners" if corners else "edge samples"
        print(f"  groups of {GROUP} in {name}, sharing {what}: {t} ({t / n:.1f} a patch, "
              f"{100 * (1 - t / (28 * n)):.0f}% fewer)")
