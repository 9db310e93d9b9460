"""SDF grids against trimesh's exact signed distance, the interpolant's own derivatives, and closed forms."""

import os
import warnings

import numpy as np
import pytest
import trimesh

from pickplan import _core
from pickplan.core import sdf
from conftest import ycb_dir_or_skip


def _check_against_trimesh(mesh, grid, n, seed, margin=0.19):
    rng = np.random.default_rng(seed)
    lo, hi = mesh.bounds
    P = rng.uniform(lo - margin, hi + margin, size=(n, 3))
    # Half the points near the surface, where sign and accuracy matter most.
    surf, _ = trimesh.sample.sample_surface(mesh, n // 2, seed=seed)
    P[: n // 2] = surf + rng.normal(scale=0.01, size=surf.shape)
    ref = -trimesh.proximity.signed_distance(mesh, P)  # trimesh: positive inside
    d, _ = grid.distance(P)
    half_diag = grid.resolution * np.sqrt(3) / 2
    err = np.abs(d - ref)
    assert err.max() <= half_diag, (err.max(), half_diag)
    far_from_surface = np.abs(ref) > half_diag
    assert np.all(np.sign(d[far_from_surface]) == np.sign(ref[far_from_surface]))
    return err


@pytest.mark.parametrize(
    "make",
    [
        lambda: trimesh.creation.box(extents=(0.08, 0.15, 0.2)),
        lambda: trimesh.creation.cylinder(radius=0.035, height=0.1, sections=48),
        lambda: trimesh.creation.annulus(r_min=0.03, r_max=0.05, height=0.08, sections=48),  # a hollow tube
    ],
)
def test_grid_matches_trimesh_exact_signed_distance(make):
    mesh = make()
    grid = sdf.mesh_sdf(mesh, sdf.SdfSettings(cache_dir=""))
    _check_against_trimesh(mesh, grid, 600, seed=1)


def test_ycb_mesh_matches_trimesh_and_is_cached(tmp_path):
    folder = ycb_dir_or_skip()
    mesh = trimesh.load(os.path.join(folder, "006_mustard_bottle", "mesh.stl"))
    settings = sdf.SdfSettings(cache_dir=str(tmp_path))
    grid = sdf.mesh_sdf(mesh, settings)
    _check_against_trimesh(mesh, grid, 200, seed=2)
    cached = list((tmp_path / "sdf").iterdir())
    assert len(cached) == 1
    again = sdf.mesh_sdf(mesh, settings)  # from the cache: identical values
    np.testing.assert_array_equal(again.values, grid.values)


def test_sphere_grid_matches_closed_form_and_gradient_is_radial():
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=0.05)
    grid, report = _core.SdfGrid.build(mesh.vertices, mesh.faces, 0.004, 0.1)
    assert report.degenerate_faces == 0 and report.sign_disagreement == 0.0
    rng = np.random.default_rng(3)
    P = rng.uniform(-0.12, 0.12, size=(2000, 3))
    d, g = grid.distance(P)
    r = np.linalg.norm(P, axis=1)
    # The icosphere is inscribed in the sphere: its faces lie up to ~0.3 mm inside.
    assert np.abs(d - (r - 0.05)).max() < 0.004 * np.sqrt(3) / 2 + 3e-4
    away = (r > 0.02) & (np.abs(r - 0.05) > 0.008)
    cos = np.einsum("ij,ij->i", g[away], P[away]) / (np.linalg.norm(g[away], axis=1) * r[away])
    assert np.percentile(cos, 5) > 0.98


def test_gradient_is_the_derivative_of_the_interpolant():
    mesh = trimesh.creation.box(extents=(0.1, 0.06, 0.04))
    grid = sdf.mesh_sdf(mesh, sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir=""))
    rng = np.random.default_rng(4)
    P = rng.uniform(-0.09, 0.09, size=(300, 3))
    _, g = grid.distance(P)
    h = 1e-7
    for a in range(3):
        e = np.zeros(3)
        e[a] = h
        fd = (grid.distance(P + e)[0] - grid.distance(P - e)[0]) / (2 * h)
        # Skip points within h of a cell face, where the interpolant has a kink.
        f = (P[:, a] - grid.origin[a]) / grid.resolution
        ok = np.abs(f - np.round(f)) > 1e-4
        np.testing.assert_allclose(g[ok, a], fd[ok], atol=1e-6)


def test_values_continue_continuously_outside_the_grid():
    mesh = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    grid = sdf.mesh_sdf(mesh, sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir=""))
    xs = np.linspace(0.05, 0.5, 200)
    P = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
    d, g = grid.distance(P)
    np.testing.assert_allclose(d, xs - 0.05, atol=2e-3)  # exact distance to the face x = 0.05
    assert np.all(np.diff(d) > 0) and np.all(g[:, 0] > 0.99)


def test_mesh_with_a_hole_keeps_the_right_sign():
    mesh = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    holed = trimesh.Trimesh(mesh.vertices, mesh.faces[1:], process=False)  # one triangle missing
    assert not holed.is_watertight
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        grid = sdf.mesh_sdf(holed, sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir=""))
    assert any("not watertight" in str(w.message) for w in caught)
    d, _ = grid.distance(np.array([[0.0, 0.0, 0.0], [0.02, -0.01, 0.03], [0.1, 0.0, 0.0]]))
    assert d[0] < -0.04 and d[1] < 0 and d[2] > 0.04


def test_scene_sdf_takes_the_nearest_body_and_excludes_by_name():
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    grid = sdf.mesh_sdf(box, sdf.SdfSettings(resolution=0.01, margin=0.1, cache_dir=""))
    A, B = np.eye(4), np.eye(4)
    A[:3, 3] = [0.5, 0.0, 0.05]
    B[:3, 3] = [0.5, 0.6, 0.05]
    c, s = np.cos(0.5), np.sin(0.5)
    B[:2, :2] = [[c, -s], [s, c]]
    table_pose = np.eye(4)
    table_pose[:3, 3] = [0.5, 0.0, -0.025]
    scene = sdf.SceneSdf([("a", grid, A), ("b", grid, B)], table=((1.0, 1.0, 0.05), table_pose))
    p = np.array([[0.5, 0.15, 0.05], [0.5, 0.0, 0.3], [0.9, 0.0, 0.01]])
    d_objects, _ = scene.distance(p, exclude_table=True)
    np.testing.assert_allclose(d_objects[0], 0.1, atol=2e-3)  # a's face at y = 0.05
    np.testing.assert_allclose(d_objects[1], 0.2, atol=2e-3)  # a's top at z = 0.1
    d, g = scene.distance(p)
    np.testing.assert_allclose(d[0], 0.05, atol=1e-12)  # the table top is nearer
    np.testing.assert_allclose(d[2], 0.01, atol=1e-12)  # the table top, analytic
    np.testing.assert_allclose(g[2], [0, 0, 1], atol=1e-12)
    d_ex, _ = scene.distance(p, exclude=["a"], exclude_table=True)
    assert d_ex[0] > 0.1 and d_ex[2] > 0.2 and d_ex[1] > 0.2
    d_cut, g_cut = scene.distance(np.array([[3.0, 3.0, 3.0]]), cutoff=0.2)
    assert d_cut[0] == 0.2 and not g_cut.any()
    # The rotated copy gives the same distance in its own frame.
    local = np.array([0.0, 0.12, 0.0])
    d_b, _ = scene.distance((B[:3, :3] @ local + B[:3, 3])[None], exclude=["a"], exclude_table=True)
    np.testing.assert_allclose(d_b[0], 0.07, atol=2e-3)


def test_mesh_sdfs_builds_each_distinct_mesh_once_on_threads_in_order():
    """The grids of a scene built side by side equal the ones built one by one, in the meshes' order;
    a mesh given twice is built once."""
    settings = sdf.SdfSettings(resolution=0.01, margin=0.05, cache_dir="")
    box, ball = trimesh.creation.box(extents=(0.1, 0.06, 0.04)), trimesh.creation.icosphere(2, 0.04)
    cache = sdf.GridCache(8)
    grids = sdf.mesh_sdfs([box, ball, box], settings, cache, threads=2)
    assert cache.misses == 2 and grids[0] is grids[2]
    for mesh, grid in zip((box, ball), grids):
        alone = sdf.mesh_sdf(mesh, settings)
        np.testing.assert_array_equal(np.asarray(grid.values), np.asarray(alone.values))
        np.testing.assert_array_equal(np.asarray(grid.origin), np.asarray(alone.origin))


@pytest.mark.parametrize(
    "V, F, message",
    [
        (np.zeros((0, 3)), np.zeros((0, 3), int), "empty"),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), "degenerate"),
        (np.eye(3), np.array([[0, 1, 5]]), "refers to vertex 5"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 1, 0]]), np.array([[0, 1, 2]]), "NaN"),
    ],
)
def test_bad_meshes_raise(V, F, message):
    with pytest.raises(ValueError, match=message):
        _core.SdfGrid.build(V, F, 0.01, 0.05)


def test_bad_queries_raise():
    grid = sdf.mesh_sdf(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), sdf.SdfSettings(0.01, 0.05, cache_dir=""))
    with pytest.raises(ValueError, match=r"expected shape \(N, 3\), got \(4,\)"):
        grid.distance(np.zeros(4))
    with pytest.raises(ValueError, match="NaN"):
        grid.distance(np.array([[0.0, np.nan, 0.0]]))
    scene = sdf.SceneSdf([("a", grid, np.eye(4))])
    with pytest.raises(ValueError, match="unknown object 'zz'"):
        scene.distance(np.zeros((1, 3)), exclude=["zz"])
    with pytest.raises(ValueError, match="not a rigid transform"):
        scene.add_object("b", grid, np.diag([2.0, 1, 1, 1]))
