"""CPU frames with Blender's lattices (cubic per axis, fit degree 9: the add-on's case), positions
only and with normals (compact layout), 2 threads: Suzanne with Subsurf 1 (tests/data/real, 3,936
triangles) and a 15,664-triangle torus, 4x4x4 and 8x8x8 lattices, random points each frame.
Prints the median ms, the stage medians and the plan's memory; asserts nothing.

    PYTHONPATH=python python3 bench/bench_cpu_blender.py [LABEL] [FRAMES]

Run it alternately with another tree's python/ (PYTHONPATH=$OLD/python) for an A/B.
"""
import sys, time, statistics, os
import numpy as np
import smoothffd, smoothffd.io
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_gpu
label = sys.argv[1] if len(sys.argv) > 1 else ""
reps = int(sys.argv[2]) if len(sys.argv) > 2 else 15
def blender_lat(P, shape, rng, amp=0.15):
    lo, hi = P.min(0) - 1e-3, P.max(0) + 1e-3
    c, s = (lo + hi) / 2, (hi - lo)
    g = [np.linspace(-0.5, 0.5, n) for n in shape]
    rest = np.stack(np.meshgrid(*g, indexing="ij"), -1)
    m = np.eye(4); m[:3, :3] = np.diag(s); m[:3, 3] = c
    pts = rest + rng.normal(scale=amp / max(shape), size=rest.shape)
    return smoothffd.BlenderLattice(rest, pts, lattice_to_object=m)
mesh_s = smoothffd.io.read_obj_mesh(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests/data/real/suzanne_subsurf.obj"))
P, F, N = bench_gpu.torus(89, 88)
mesh_t = smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])
for name, mesh, shape, L in [("suzanne3.9k", mesh_s, (4, 4, 4), 2), ("torus15.7k", mesh_t, (4, 4, 4), 2),
                              ("torus15.7k", mesh_t, (4, 4, 4), 3), ("torus15.7k 8^3", mesh_t, (8, 8, 8), 2)]:
    rng = np.random.default_rng(1)
    pos = np.asarray(mesh.positions)
    lat = blender_lat(pos, shape, rng)
    d = smoothffd.Deformer(mesh, lat, level=L, device="cpu", threads=2)
    for normals in (False, True):
        ts, st = [], []
        r = None
        for i in range(reps):
            l2 = blender_lat(pos, shape, np.random.default_rng(i + 2))
            t0 = time.perf_counter()
            r = d.deform(l2.points, normals=normals, out=r, layout="compact")
            ts.append((time.perf_counter() - t0) * 1e3)
            st.append(r.stats["stage_ms"])
        stm = {k: round(statistics.median(s[k] for s in st), 2) for k in st[0]}
        print(f"{label:4} {name:16} L{L} {'full' if normals else 'pos ':4} {statistics.median(ts):7.2f} ms  {stm}  plan {d.plan.bytes/1e6:.1f} MB", flush=True)
