"""Rest-pose sphere reconstruction (the centre rule) and sharp-edge preservation."""

import numpy as np
import pytest

pytest.importorskip("smoothffd._core", reason="native module not built: run scripts/build.sh")

import smoothffd  # noqa: E402
from meshes import cube_mesh, random_bspline_lattice, sphere_mesh  # noqa: E402


# What the product measures on the rest icosphere, per (shape, degree): the largest radial
# error of the smooth result (the flat mesh's is 0.0175, 38-42x more) and the largest angle
# between an output normal and the sphere's at that point, degrees.
SPHERE_MEASURED = {((3, 3, 3), 2): (4.55e-4, 0.0062), ((6, 6, 6), 2): (4.17e-4, 0.0198),
                   ((5, 5, 5), 3): (4.55e-4, 0.0198)}


@pytest.mark.parametrize("shape,degree", sorted(SPHERE_MEASURED))
def test_rest_icosphere_is_close_to_the_sphere(shape, degree, capsys):
    """320-face icosphere with exact sphere normals under an identity lattice, level 8: the
    smooth result's largest radial error and normal angle within 2.5x of what the product
    measures (SPHERE_MEASURED; (6,6,6) also clips every face against knot planes)."""
    mesh = sphere_mesh(2)
    lat = smoothffd.BSplineLattice.identity([-1.2] * 3, [1.2] * 3, shape=shape, degree=degree)
    r = smoothffd.deform(mesh, lat, level=8)
    smooth = np.abs(np.linalg.norm(r.positions, axis=1) - 1).max()
    flat = np.abs(np.linalg.norm(r.rest_positions, axis=1) - 1).max()
    # In double: float32's arccos near 1 cannot resolve less than 0.02 degrees.
    P = r.positions.astype(np.float64)[r.triangles]
    N = r.corner_normals.astype(np.float64)
    normal_deg = np.degrees(np.arctan2(np.linalg.norm(np.cross(N, P), axis=2),
                                       np.einsum("tci,tci->tc", N, P))).max()
    with capsys.disabled():
        print(f"\n  icosphere {shape} deg {degree}: flat max radial error {flat:.5f}, "
              f"smooth {smooth:.6f}, factor {flat / smooth:.1f}x, normals {normal_deg:.4f} deg")
    radial_measured, normal_measured = SPHERE_MEASURED[shape, degree]
    assert smooth < 2.5 * radial_measured, smooth
    assert normal_deg < 2.5 * normal_measured, normal_deg


def _normals_at(result, vertex):
    """All corner normals of output triangles that use `vertex`."""
    t, c = np.nonzero(result.triangles == vertex)
    return result.corner_normals[t, c]


@pytest.mark.parametrize("deformed", [False, True])
def test_cube_edges_stay_sharp_faces_stay_smooth(deformed):
    rng = np.random.default_rng(7)
    mesh = cube_mesh(0.7)
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(5, 5, 5))
    if deformed:
        lat = random_bspline_lattice(rng, [-1] * 3, [1] * 3, (5, 5, 5), 2, 0.12)
    L = 6
    r = smoothffd.deform(mesh, lat, level=L)
    rest = r.rest_positions
    on_edge = np.sum(np.isclose(np.abs(rest), 0.7, atol=1e-6), axis=1) >= 2
    inside = np.sum(np.isclose(np.abs(rest), 0.7, atol=1e-6), axis=1) == 1
    assert on_edge.sum() > 12 and inside.sum() > 50
    # Along every cube edge the two faces' normals differ by about 90 degrees ...
    for v in np.nonzero(on_edge)[0][:200]:
        n = _normals_at(r, v)
        spread = np.degrees(np.arccos(np.clip(n @ n.T, -1, 1))).max()
        assert spread > 45, (v, spread)
    # ... and inside a face every corner at a vertex carries the same normal.
    for v in np.nonzero(inside)[0][:400]:
        n = _normals_at(r, v)
        assert np.abs(n - n[0]).max() < 1e-5
    # The sharp edges reported cover the 12 cube edges, L segments each (with clipping: more).
    assert len(r.sharp_edges) >= 12 * L
    if not deformed:
        # A sharp cube stays a cube: planar faces, straight edges.
        np.testing.assert_allclose(np.abs(r.positions).max(axis=1), 0.7, atol=1e-5)


def test_smooth_cube_without_normals_rounds_off():
    """Without split normals the cube is smooth (area-weighted vertex normals): no sharp edges,
    and the faces bulge like PN triangles do."""
    mesh = cube_mesh(0.7, sharp=False)
    lat = smoothffd.BSplineLattice.identity([-1] * 3, [1] * 3, shape=(3, 3, 3))
    r = smoothffd.deform(mesh, lat, level=4)
    assert len(r.sharp_edges) == 0
    assert np.abs(r.positions).max() > 0.7 + 1e-3
