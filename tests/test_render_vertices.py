"""Render vertices of the plan (plan.hpp): an output vertex duplicated only where its normals
split, the topology of the CUDA evaluator's compact output. CPU only (no GPU needed)."""

import numpy as np
import pytest

import smoothffd
from smoothffd import _core
from meshes import grid_cube, sphere_mesh


def plan_of(mesh, lat, level):
    return smoothffd.Deformer(mesh, lat, level=level, device="cpu").plan


def check_consistent(plan):
    """render_triangles name the same positions as triangles; every render vertex is used and
    owned by a (patch, grid point) that maps to it; R >= N."""
    rpos, rtri = plan.render_vertices()
    R, N = plan.render_vertex_count, plan.output_vertices
    assert rpos.shape == (R,) and rtri.shape == (plan.output_triangles, 3)
    assert R >= N
    np.testing.assert_array_equal(rpos[rtri], plan.triangles())
    assert np.all(np.diff(rpos) >= 0), "render vertices are numbered by output vertex"
    assert np.array_equal(np.unique(rtri), np.arange(R)), "every render vertex is used"
    owner = plan.render_owner()
    assert owner.shape == (R, 2)
    assert (owner[:, 0] >= 0).all() and (owner[:, 0] < plan.patches).all()
    return rpos, rtri


def cpu_normals_agree_within_classes(plan, lat, tol):
    """The CPU corner normals of all corners of one render vertex agree (one normal class)."""
    vals = np.ascontiguousarray(lat.control_values().reshape(-1, 3), dtype=np.float32)
    _, nc, _ = _core.CpuEvaluator(plan).evaluate(vals)
    _, rtri = plan.render_vertices()
    r = rtri.reshape(-1)
    n = nc.reshape(-1, 3).astype(np.float64)
    ref = np.zeros((plan.render_vertex_count, 3))
    ref[r] = n  # any corner of the class
    ang = np.arctan2(np.linalg.norm(np.cross(n, ref[r]), axis=1), np.sum(n * ref[r], axis=1))
    assert ang.max() <= tol, f"normals inside one render vertex differ by {ang.max():.2e} rad"
    return n, r


@pytest.mark.parametrize("level", [1, 2, 4, 7])
@pytest.mark.parametrize("cuts", [1, 2, 3])
def test_cube_split_normals_count(cuts, level):
    """Unclipped cube of cuts x cuts quads a face with flat face normals: each point inside the
    12 cube edges' sub-edges has 2 render vertices, each vertex on a cube edge 2, each corner 3."""
    mesh = grid_cube(cuts, size=0.8)
    lat = smoothffd.BSplineLattice.identity([-1, -1, -1], [1, 1, 1], shape=(2, 2, 2), degree=(1, 1, 1))
    plan = plan_of(mesh, lat, level)
    assert plan.sub_vertices == plan.input_vertices, "no knot-box clipping expected"
    L, c = level, cuts
    assert plan.patches == 6 * c * c * 2
    extra = 12 * c * (L - 1) + 12 * (c - 1) + 8 * 2
    assert plan.render_vertex_count == plan.output_vertices + extra
    assert plan.splits_normals   # the cube's edges split every normal on them
    check_consistent(plan)
    n, r = cpu_normals_agree_within_classes(plan, lat, 1e-5)
    # Duplicates carry different (face) normals: 90 degrees apart on the identity lattice.
    rpos, _ = plan.render_vertices()
    dup = np.flatnonzero(np.diff(rpos) == 0)
    ref = np.zeros((plan.render_vertex_count, 3))
    ref[r] = n
    assert len(dup) == extra
    assert np.abs(np.sum(ref[dup] * ref[dup + 1], axis=1)).max() < 1e-5


def test_cube_split_normals_deformed_and_clipped():
    rng = np.random.default_rng(3)
    mesh = grid_cube(2, size=0.8)
    lat = smoothffd.BSplineLattice.identity([-1, -1.1, -0.9], [1.1, 1, 1], shape=(5, 5, 5), degree=(2, 2, 2))
    lat = lat.with_control_points(lat.rest_points + 0.05 * rng.standard_normal(lat.rest_points.shape))
    plan = plan_of(mesh, lat, 5)
    assert plan.sub_vertices > plan.input_vertices
    check_consistent(plan)
    assert plan.render_vertex_count > plan.output_vertices
    cpu_normals_agree_within_classes(plan, lat, 1e-4)


@pytest.mark.parametrize("level", [1, 3, 10])
def test_smooth_sphere_has_no_duplicates(level):
    rng = np.random.default_rng(level)
    lat = smoothffd.BSplineLattice.identity([-1.1, -1.2, -1.05], [1.15, 1.1, 1.2], shape=(5, 5, 5), degree=(2, 2, 2))
    lat = lat.with_control_points(lat.rest_points + 0.05 * rng.standard_normal(lat.rest_points.shape))
    plan = plan_of(sphere_mesh(2), lat, level)
    assert plan.sub_vertices > plan.input_vertices  # clipped by the knot planes
    assert plan.render_vertex_count == plan.output_vertices
    assert not plan.splits_normals
    rpos, rtri = check_consistent(plan)
    np.testing.assert_array_equal(rpos, np.arange(plan.output_vertices))
    np.testing.assert_array_equal(rtri, plan.triangles())
    cpu_normals_agree_within_classes(plan, lat, 1e-4)


def test_deformer_splits_normals_is_the_plans():
    """Deformer.splits_normals (what the Blender add-on asks to choose the layout and the
    normals write) is the plan's: a flat-shaded cube splits, a smooth sphere does not."""
    lat = smoothffd.BSplineLattice.identity([-1.1, -1.2, -1.05], [1.15, 1.1, 1.2], shape=(5, 5, 5),
                                            degree=(2, 2, 2))
    for mesh, splits in ((grid_cube(2, size=0.8), True), (sphere_mesh(2), False)):
        d = smoothffd.Deformer(mesh, lat, level=3, device="cpu")
        assert d.splits_normals is d.plan.splits_normals is splits
        assert splits == (d.plan.render_vertex_count > d.plan.output_vertices)
