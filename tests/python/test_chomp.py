"""CHOMP / CHOMP-Proj: gradients vs finite differences, exact goal projection, convergence, avoidance."""

import concurrent.futures

import numpy as np
import pytest
import trimesh

from pickplan.omg import chomp
from pickplan.core import sdf

Q_LEFT = np.array([1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])
Q_RIGHT = np.array([-1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])


def _table():
    pose = np.eye(4)
    pose[:3, 3] = [0.45, 0.0, -0.025]
    return (1.3, 1.6, 0.05), pose


@pytest.fixture(scope="module")
def body(panda):
    return panda.sample_body_points(per_link=20, seed=0)


@pytest.fixture(scope="module")
def wall_scene():
    height = 0.4
    grid = sdf.mesh_sdf(trimesh.creation.box(extents=(0.1, 0.3, height)), sdf.SdfSettings(cache_dir=""))
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.0, height / 2]
    return sdf.SceneSdf([("wall", grid, pose)], table=_table())


def _fd_gradient(f, xi, h, active):
    g = np.zeros_like(xi)
    for t in range(xi.shape[0]):
        for j in np.flatnonzero(active):
            e = np.zeros_like(xi)
            e[t, j] = h
            g[t, j] = (f(xi + e) - f(xi - e)) / (2 * h)
    return g


def test_prior_gradient_and_A_match_closed_forms(panda, body, wall_scene):
    c = chomp.Chomp(panda, wall_scene, body)
    rng = np.random.default_rng(0)
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT) + rng.normal(scale=0.05, size=(30, 9))
    f, g = c.problem.prior(xi, Q_LEFT)
    dt = c.dt
    full = np.vstack([Q_LEFT, xi])
    assert f == pytest.approx(0.5 * np.sum(np.diff(full, axis=0) ** 2) / dt**2, rel=1e-12)
    fd = _fd_gradient(lambda x: c.problem.prior(x, Q_LEFT)[0], xi, 1e-6, np.ones(9, bool))
    assert np.linalg.norm(g - fd) <= 1e-5 * np.linalg.norm(fd)
    # A = K^T K: the Hessian of f_prior, and solve_A inverts it.
    A = c.problem.A_matrix()
    K = (np.eye(30) - np.eye(30, k=-1)) / dt
    np.testing.assert_allclose(A, K.T @ K, rtol=1e-12)
    v = rng.normal(size=(30, 9))
    np.testing.assert_allclose(c.problem.solve_A(v), np.linalg.solve(A, v), rtol=1e-9, atol=1e-12)


def test_obstacle_gradient_matches_finite_differences(panda, body):
    # Table only: its SDF is analytic, so f_obstacle is C1 and smooth almost everywhere.
    scene = sdf.SceneSdf([], table=_table())
    settings = chomp.ChompSettings(top_k=0, clip_gradient=0.0)
    c = chomp.Chomp(panda, scene, body, settings)
    low = np.array([0.0, 0.9, 0.0, -1.4, 0.0, 2.3, 0.785, 0.04, 0.04])  # hand near the table top
    xi = c.initial_trajectory(Q_LEFT, low)
    terms, g = c.problem.obstacle(xi, Q_LEFT)
    assert terms.obstacle > 1.0  # the trajectory really is inside the padding
    fd = _fd_gradient(lambda x: c.problem.obstacle(x, Q_LEFT)[0].obstacle, xi, 1e-6, c.active)
    g[:, ~np.array(c.active)] = 0  # finger joints are not optimized (the step masks them)
    assert np.linalg.norm(g - fd) <= 1e-5 * np.linalg.norm(fd), np.linalg.norm(g - fd) / np.linalg.norm(fd)


def test_obstacle_gradient_with_object_grid_and_top_k(panda, body, wall_scene):
    settings = chomp.ChompSettings(top_k=200, clip_gradient=0.0)
    c = chomp.Chomp(panda, wall_scene, body, settings)
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    _, g = c.problem.obstacle(xi, Q_LEFT)
    fd = _fd_gradient(lambda x: c.problem.obstacle(x, Q_LEFT)[0].obstacle, xi, 1e-7, c.active)
    g[:, ~np.array(c.active)] = 0
    # Trilinear cells and the top-k set make a few components non-smooth; the rest agree.
    assert np.linalg.norm(g - fd) <= 1e-3 * np.linalg.norm(fd)


def test_projected_step_meets_the_goal_exactly(panda, body, wall_scene):
    c = chomp.Chomp(panda, wall_scene, body)
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    goals = [Q_RIGHT, Q_RIGHT + np.r_[0.3, -0.2, 0.1, 0.2, 0, -0.1, 0.2, 0, 0], np.r_[Q_LEFT[:7] * 0.5, 0.04, 0.04]]
    ws = c.workspace()
    for i in range(12):
        goal = goals[i % 3]
        xi, info = c.step(xi, Q_LEFT, goal, i, ws)
        assert np.abs(xi[-1] - goal).max() <= 1e-10
        assert info.goal_error <= 1e-10
        np.testing.assert_array_equal(xi[:-1, 7:], np.broadcast_to(Q_LEFT[7:], (29, 2)))  # fingers untouched
    # A standoff tail of 4 waypoints is pinned as a whole.
    tail = np.linspace(Q_RIGHT + 0.1, Q_RIGHT, 4)
    xi, _ = c.step(xi, Q_LEFT, tail, 12, ws)
    assert np.abs(xi[-4:] - tail).max() <= 1e-10


def test_free_space_converges_monotonically_to_the_straight_line(panda, body):
    scene = sdf.SceneSdf([])  # nothing to avoid
    settings = chomp.ChompSettings(lambda_growth=1.0, step_size=5.0)
    c = chomp.Chomp(panda, scene, body, settings)
    xi0 = c.initial_trajectory(Q_LEFT, Q_RIGHT)  # cubic: not the optimum
    res = c.optimize(Q_LEFT, Q_RIGHT, iterations=60, xi0=xi0)
    obj = np.array(res.objective)
    assert np.all(np.diff(obj) <= 1e-12)
    np.testing.assert_allclose(res.xi, chomp.linear_initialization(Q_LEFT, Q_RIGHT, 30), atol=1e-8)


def test_wall_between_start_and_goal_is_avoided(panda, body, wall_scene):
    c = chomp.Chomp(panda, wall_scene, body)
    xi0 = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    before = c.metrics(xi0, Q_LEFT)
    assert before.min_clearance < 0  # the straight path goes through the wall
    res = c.optimize(Q_LEFT, Q_RIGHT, iterations=100)
    m = res.metrics
    assert m.min_clearance >= 0.05 and m.min_table_clearance >= 0.0
    assert m.collision_free and m.success, m
    assert np.abs(res.xi[-1] - Q_RIGHT).max() <= 1e-10
    lo, hi = panda.lower_limits, panda.upper_limits
    assert np.all(res.xi >= lo - 1e-9) and np.all(res.xi <= hi + 1e-9)


def test_joint_limits_are_restored_smoothly(panda, body):
    scene = sdf.SceneSdf([])
    c = chomp.Chomp(panda, scene, body)
    goal = Q_RIGHT.copy()
    xi = c.initial_trajectory(Q_LEFT, goal)
    xi[10:20, 3] = -3.3  # joint 4's lower limit is -3.1416
    xi, info = c.step(xi, Q_LEFT, goal, 0)
    assert info.limit_projections >= 1
    assert xi[:, 3].min() >= panda.lower_limits[3] - 1e-2


def test_deterministic_across_runs_and_threads(panda, body, wall_scene):
    c = chomp.Chomp(panda, wall_scene, body)
    ref = c.optimize(Q_LEFT, Q_RIGHT, iterations=30, metric_settings=None).xi
    with concurrent.futures.ThreadPoolExecutor(max_workers=4) as pool:
        outs = list(pool.map(lambda _: c.optimize(Q_LEFT, Q_RIGHT, iterations=30, metric_settings=None).xi, range(4)))
    for out in outs:
        np.testing.assert_array_equal(out, ref)


def test_bad_inputs_raise(panda, body, wall_scene):
    c = chomp.Chomp(panda, wall_scene, body)
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    with pytest.raises(ValueError, match=r"trajectory: expected shape \(30, 9\), got \(29, 9\)"):
        c.step(xi[:-1], Q_LEFT, Q_RIGHT)
    bad = xi.copy()
    bad[3, 2] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        c.step(bad, Q_LEFT, Q_RIGHT)
    with pytest.raises(ValueError, match="expected 9 joint values, got 7"):
        c.step(xi, Q_LEFT, Q_RIGHT[:7])
    with pytest.raises(ValueError, match="unknown object 'mug'"):
        chomp.Chomp(panda, wall_scene, body, exclude=("mug",))
    with pytest.raises(ValueError, match="n must be >= 2"):
        chomp.Chomp(panda, wall_scene, body, chomp.ChompSettings(n=1))


def _clutter_sdf(merged: bool):
    rng = np.random.default_rng(3)
    grids = []
    for i in range(4):
        mesh = trimesh.creation.cylinder(radius=0.04, height=0.2) if i % 2 else trimesh.creation.box((0.08, 0.12, 0.2))
        pose = trimesh.transformations.rotation_matrix(rng.uniform(-np.pi, np.pi), (0, 0, 1))
        pose[:3, 3] = [rng.uniform(0.35, 0.7), rng.uniform(-0.35, 0.35), 0.1]
        grids.append((f"o{i}", sdf.mesh_sdf(mesh, sdf.SdfSettings(cache_dir="")), pose))
    scene = sdf.SceneSdf(grids, table=_table())
    if merged:
        scene.merge(exclude=("o1",))
    return scene


@pytest.mark.parametrize("merged", [False, True])
def test_link_culling_changes_no_cost_or_gradient(panda, body, merged):
    """Culling a link whose bounding sphere is beyond epsilon is exact: same objective, same gradient."""
    scene = _clutter_sdf(merged)
    rng = np.random.default_rng(1)
    full = chomp.Chomp(panda, scene, body, chomp.ChompSettings(link_culling=False), exclude=("o1",))
    culled = chomp.Chomp(panda, scene, body, chomp.ChompSettings(link_culling=True), exclude=("o1",))
    for _ in range(5):
        goal = Q_LEFT + np.r_[rng.uniform(-1, 1, 7), 0, 0]
        xi = culled.initial_trajectory(Q_LEFT, goal)
        (ref, g_ref), (got, g_got) = full.problem.obstacle(xi, Q_LEFT), culled.problem.obstacle(xi, Q_LEFT)
        assert ref.obstacle > 0
        assert got.obstacle == pytest.approx(ref.obstacle, rel=1e-12)
        np.testing.assert_allclose(g_got, g_ref, rtol=0, atol=1e-12 * np.abs(g_ref).max())


def test_merged_scene_grid_matches_per_object_grids(panda, body):
    """The merged grid resamples the per-object grids: the CHOMP objective barely moves; ``reference``
    distances are the per-object grids' bit for bit."""
    plain, merged = _clutter_sdf(False), _clutter_sdf(True)
    info = merged.merged_info
    assert info.bricks > 0 and info.cutoff == 0.2 and info.exclude_mask == 0b10
    rng = np.random.default_rng(2)
    pts = np.c_[rng.uniform(0.2, 0.8, 4000), rng.uniform(-0.5, 0.5, 4000), rng.uniform(0.0, 0.4, 4000)]
    d0, _ = plain.distance(pts, 0.2, exclude=("o1",))
    d1, _ = merged.distance(pts, 0.2, exclude=("o1",))
    # Trilinear resampling of a 1-Lipschitz field at spacing h is off by at most h sqrt(3) / 2.
    assert np.max(np.abs(d1 - d0)) <= info.resolution * np.sqrt(3) / 2
    assert np.all(np.minimum(merged.lower_bound(pts, exclude=("o1",)), 0.2) <= d1 + 1e-12)
    # Another exclusion falls back to the per-object grids exactly.
    np.testing.assert_array_equal(merged.distance(pts, 0.2)[0], plain.distance(pts, 0.2)[0])
    # reference=True reads the per-object grids whatever was merged, as the success test does (a lift stopped
    # at the test's clearance by the merged grid started a transfer the test failed by 0.05 mm).
    d2, g2 = merged.distance(pts, 0.2, exclude=("o1",), reference=True)
    g0 = plain.distance(pts, 0.2, exclude=("o1",))[1]
    assert np.any(d1 != d0)
    np.testing.assert_array_equal(d2, d0)
    np.testing.assert_allclose(g2[d0 < 0.2], g0[d0 < 0.2], rtol=0, atol=1e-12)
