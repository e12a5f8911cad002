"""Where the output lies on the input (Deformer.plan: input_triangles, patch_sources,
vertex_sources, interpolate_corners; docs/api.md), against computations of this file's own:
the rest positions from the input corners, the UVs from the input UVs."""
import numpy as np
import pytest

import smoothffd
from meshes import cube_mesh, uv_sphere


def quad_sphere():
    """A UV sphere whose rings are quads (poles: triangles), random per-corner UVs: polygons
    the core triangulates, and seams everywhere."""
    V, F = uv_sphere(12, 6)
    segments = 12
    faces = [list(F[j]) for j in range(segments)]                  # north fan
    body = F[segments:-segments].reshape(-1, 2, 3)
    faces += [[t[0][0], t[0][1], t[0][2], t[1][2]] for t in body]  # quads a, a+s, b+s, b
    faces += [list(f) for f in F[-segments:]]                      # south fan
    cv = np.concatenate(faces).astype(np.int64)
    fo = np.concatenate([[0], np.cumsum([len(f) for f in faces])])
    uvs = np.random.default_rng(1).uniform(-1, 2, (len(cv), 2)).astype(np.float32)
    return V, cv, fo, uvs


@pytest.fixture(scope="module")
def deformer():
    V, cv, fo, uvs = quad_sphere()
    mesh = smoothffd.Mesh(V, (cv, fo), uvs=uvs)
    lat = smoothffd.BSplineLattice.identity((-1.1,) * 3, (1.1,) * 3, shape=(4, 4, 4))
    return smoothffd.Deformer(mesh, lat, level=4, device="cpu"), V, cv, fo, uvs


def test_input_triangles_are_the_faces_corners(deformer):
    d, V, cv, fo, _ = deformer
    corners, face = d.plan.input_triangles()
    assert corners.dtype == np.int32 and face.dtype == np.int32 and corners.shape == (len(face), 3)
    assert np.all(corners >= fo[face][:, None]) and np.all(corners < fo[face + 1][:, None])
    assert np.array_equal(np.bincount(face, minlength=len(fo) - 1), np.diff(fo) - 2)
    tri, bary = d.plan.patch_sources()
    assert tri.shape == (d.plan.patches,) and bary.shape == (d.plan.patches, 3, 3)
    assert bary.dtype == np.float64
    res = d.deform()
    ll = d.level ** 2
    assert np.array_equal(face[tri][np.arange(len(res.triangles)) // ll], res.face_index)


def test_vertex_sources_reproduce_rest_positions(deformer):
    d, V, cv, fo, _ = deformer
    res = d.deform()
    corners, _ = d.plan.input_triangles()
    tri, bary = d.plan.vertex_sources()
    assert tri.shape == (len(res.positions),) and bary.shape == (len(res.positions), 3)
    assert np.all(tri >= 0) and np.all(bary >= 0)
    pts = V[cv[corners[tri]]]                                   # (N, 3 corners, 3)
    rest = np.einsum("nk,nki->ni", bary.astype(np.float64), pts)
    # measured 3.0e-8: the float32 rounding of Result.rest_positions (coordinates up to 1)
    assert np.abs(rest - res.rest_positions).max() < 1.2e-7
    nv = len(V)
    assert np.array_equal(np.sort(bary[:nv], axis=1), np.tile([0, 0, 1], (nv, 1)))


def test_interpolate_corners_equals_the_core_uvs(deformer):
    d, V, cv, fo, uvs = deformer
    res = d.deform()
    assert np.array_equal(d.plan.interpolate_corners(uvs), res.uvs)    # the same arithmetic
    # Independently: each output corner's UV is the barycentric mix, in its patch's input
    # triangle, of the input corners' UVs, at the corner's rest point.
    corners, _ = d.plan.input_triangles()
    ptri, _ = d.plan.patch_sources()
    t_in = np.repeat(ptri[np.arange(len(res.triangles)) // d.level ** 2], 3)
    tc = corners[t_in]                                          # (3T, 3) input corners
    a, b, c = (V[cv[tc[:, k]]] for k in range(3))
    x = res.rest_positions[res.triangles.reshape(-1)].astype(np.float64)
    m = np.stack([b - a, c - a], axis=2)
    # b as (n, k, 1): numpy 2 reads a batch of 1-d right-hand sides as one matrix.
    sol = np.linalg.solve(np.einsum("nij,nik->njk", m, m), np.einsum("nij,ni->nj", m, x - a)[..., None])[..., 0]
    w = np.concatenate([1 - sol.sum(axis=1, keepdims=True), sol], axis=1)
    want = np.einsum("nk,nki->ni", w, uvs[tc].astype(np.float64)).reshape(-1, 3, 2)
    # measured 2.3e-7, one float32 step of UVs up to 2 (the rest points are float32 too)
    assert np.abs(res.uvs - want).max() < 7e-7
    # Any number of columns; 1-D values give (T, 3).
    more = np.random.default_rng(2).normal(size=(len(cv), 3)).astype(np.float32)
    out = d.plan.interpolate_corners(more)
    assert out.shape == (len(res.triangles), 3, 3) and out.dtype == np.float32
    assert np.array_equal(d.plan.interpolate_corners(more[:, 1]), out[..., 1])


def test_interpolate_corners_refuses_wrong_sizes():
    d = smoothffd.Deformer(cube_mesh(), smoothffd.BSplineLattice.identity((-2,) * 3, (2,) * 3,
                                                                          shape=(3, 3, 3)), level=2)
    with pytest.raises(ValueError, match="one row per input corner"):
        d.plan.interpolate_corners(np.zeros((23, 2), np.float32))
    with pytest.raises(ValueError):
        d.plan.interpolate_corners(np.zeros((24, 0), np.float32))
