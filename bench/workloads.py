"""Benchmark workloads (shared by the CPU and GPU benchmarks)."""

import numpy as np

import smoothffd


def torus(nu, nv, R=1.0, r=0.4):
    """Torus of 2*nu*nv triangles with exact smooth normals."""
    u = np.linspace(0, 2 * np.pi, nu, endpoint=False)
    v = np.linspace(0, 2 * np.pi, nv, endpoint=False)
    U, Vv = np.meshgrid(u, v, indexing="ij")
    P = np.stack([(R + r * np.cos(Vv)) * np.cos(U), (R + r * np.cos(Vv)) * np.sin(U), r * np.sin(Vv)], -1)
    N = np.stack([np.cos(Vv) * np.cos(U), np.cos(Vv) * np.sin(U), np.sin(Vv)], -1)
    idx = np.arange(nu * nv).reshape(nu, nv)
    a, b = idx, np.roll(idx, -1, axis=0)
    c, d = np.roll(idx, -1, axis=1), np.roll(b, -1, axis=1)
    F = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    P, N = P.reshape(-1, 3), N.reshape(-1, 3)
    return smoothffd.Mesh(P, F, corner_normals=N[F.reshape(-1)])


def w1_mesh():
    """About 46,742 triangles (the paper's Table 1 model size): 46,760."""
    return torus(167, 140)


def w1_lattice(seed=0):
    """5x5x5 control points, degree 2x2x2, a random deformation of 5% of the box."""
    rng = np.random.default_rng(seed)
    lat = smoothffd.BSplineLattice.identity([-1.5, -1.5, -0.5], [1.5, 1.5, 0.5], shape=(5, 5, 5))
    return lat.with_control_points(lat.control_points + rng.uniform(-0.05, 0.05, lat.control_points.shape))
