"""Replanning as the world moves (omg.replan): objects moved in place give the same SDF and FCL answers
as a world built at the new poses (a moved object queried on its own grid beside the merged rest); a replan after no change returns the same trajectory without an
iteration; after the target moves the goal follows it and the plan lifts it in PyBullet; a robot that
moved on starts there; bad moves are clear errors."""

from dataclasses import replace

import numpy as np
import pytest

from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.replan import Replanner, warm_trajectory
from pickplan.omg.world import CheckerKind, World
from pickplan.sim import scenes
from pickplan.sim.execution import execute_plan

SETTINGS = OMGSettings(grasp_kind="antipodal")


def _moved(scene, name, shift, yaw=0.0):
    """The scene with object ``name`` shifted (world x, y) and turned about its vertical axis."""
    o = scene.object(name)
    T = np.array(o.pose, float)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:3, :3] = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ T[:3, :3]
    T[:2, 3] += shift
    return replace(scene, objects=[replace(x, pose=T) if x.name == name else x for x in scene.objects]), T


@pytest.fixture(scope="module")
def scene():
    return scenes.generate_scene(3)


def test_a_moved_object_reads_as_a_world_built_there(scene):
    world = World(scene)
    for kind in CheckerKind:
        world.checker(kind)
    other = next(o.name for o in scene.objects if o.name != scene.target)
    moved_scene, T = _moved(scene, other, (0.03, -0.02), yaw=0.4)
    world.move_object(other, T)
    world.move_object(other, T)  # a second move of a live object changes nothing
    fresh = World(moved_scene, cache=world.cache)
    # The moved object left every merged grid (the grids without it took their places): it is queried on
    # its own grid beside them. Truth: a world built at the new poses, its rest merged the same way (the
    # same bricks) and the moved object's distance alone (its own grid: no merged grid has that mask).
    excludes = [(scene.target,), ()]
    assert sorted(world.sdf.merged_excludes) == sorted(tuple(sorted(e + (other,))) for e in excludes)
    res = world.settings.sdf
    for e in excludes:
        fresh.sdf.merge(exclude=e + (other,), resolution=res.merged_resolution, cutoff=res.merged_cutoff)
    alone = [n for n in fresh.sdf.names if n != other]
    rng = np.random.default_rng(0)
    lo, hi = (
        np.min([o.pose[:3, 3] for o in scene.objects], axis=0),
        np.max([o.pose[:3, 3] for o in scene.objects], axis=0),
    )
    X = rng.uniform(lo - [0.15, 0.15, 0.0], hi + [0.15, 0.15, 0.25], size=(4000, 3))
    for exclude in excludes:
        for cutoff in (0.05, np.inf):
            d, g = world.sdf.distance(X, cutoff=cutoff, exclude=exclude)
            if np.isinf(cutoff):  # beyond the merged grids' cutoff: every object on its own grid
                d2, g2 = fresh.sdf.distance(X, cutoff=cutoff, exclude=exclude)
            else:
                d_rest, g_rest = fresh.sdf.distance(X, cutoff=cutoff, exclude=exclude + (other,))
                d_other, g_other = fresh.sdf.distance(X, cutoff=cutoff, exclude=alone, exclude_table=True)
                nearer = d_other < d_rest
                d2, g2 = np.where(nearer, d_other, d_rest), np.where(nearer[:, None], g_other, g_rest)
                assert nearer.sum() > 50  # the moved object is the nearest at many points
            np.testing.assert_array_equal(d, d2)
            np.testing.assert_array_equal(g, g2)
            lb = world.sdf.lower_bound(X, exclude=exclude)
            near = d < cutoff
            assert np.all(lb[near] <= d[near] + 1e-12)  # still a lower bound with the live object beside the grid
    robot = world.robot
    Q = rng.uniform(robot.lower_limits, robot.upper_limits, size=(300, robot.dof))
    for kind in CheckerKind:
        a, b = world.checker(kind), fresh.checker(kind)
        np.testing.assert_array_equal(a.in_collision_batch(Q), b.in_collision_batch(Q), err_msg=str(kind))
        np.testing.assert_array_equal([a.min_distance(q) for q in Q[:40]], [b.min_distance(q) for q in Q[:40]])
    assert world.scene.object(other).pose.tolist() == T.tolist()


def test_a_moved_targets_grasp_refiner_is_the_one_a_world_built_there_has(scene):
    world = World(scene)
    before = world.grasp_refiner()
    moved_scene, T = _moved(scene, scene.target, (0.02, 0.01), yaw=0.3)
    world.move_object(scene.target, T)
    placed, fresh = world.grasp_refiner(), World(moved_scene, cache=world.cache).grasp_refiner()
    assert placed is not before
    rng = np.random.default_rng(2)
    robot = world.robot
    for q in rng.uniform(robot.lower_limits, robot.upper_limits, size=(20, robot.dof)):
        (terms, grad), (terms2, grad2) = placed.cost(q), fresh.cost(q)
        assert terms == terms2
        np.testing.assert_array_equal(grad, grad2)
        assert placed.support_depth(q) == fresh.support_depth(q)
    assert before.cost(q)[0] != placed.cost(q)[0]  # the old one still sees the target where it was


def test_bad_moves_are_clear_errors(scene):
    world = World(scene)
    with pytest.raises(KeyError, match="no object 'nothing'"):
        world.move_object("nothing", np.eye(4))
    skew = np.eye(4)
    skew[0, 1] = 0.5
    with pytest.raises(ValueError, match="rigid"):
        world.move_object(scene.target, skew)
    with pytest.raises(ValueError, match="4x4"):
        world.move_object(scene.target, np.full((4, 4), np.nan))
    np.testing.assert_array_equal(world.target_pose, scene.object(scene.target).pose)  # nothing moved


def test_warm_trajectory_keeps_the_path_and_moves_its_start():
    rng = np.random.default_rng(1)
    last = np.cumsum(rng.normal(0, 0.05, size=(31, 9)), axis=0)
    np.testing.assert_array_equal(warm_trajectory(last, last[0]), last[1:])  # nothing changed: the same rows
    moved = warm_trajectory(last, last[0] + 0.02)
    assert moved.shape == (30, 9)
    np.testing.assert_allclose(moved[-1], last[-1], atol=1e-12)  # the end stays
    np.testing.assert_allclose(moved[0] - last[1], 0.02 * (1 - (3 / 30**2 - 2 / 30**3)), atol=1e-12)
    on = warm_trajectory(last, last[10])  # moved on along the path
    assert on.shape == (30, 9)
    np.testing.assert_allclose(on[-1], last[-1], atol=1e-12)


@pytest.fixture(scope="module")
def replanned(scene):
    replanner = Replanner(OMGPlanner(None, scene, SETTINGS))
    first = replanner.plan()
    assert first.success
    return replanner, first


def test_a_replan_after_no_change_returns_the_same_trajectory(replanned):
    replanner, first = replanned
    again = replanner.replan()
    assert again.success and again.iterations == 0
    np.testing.assert_array_equal(again.trajectory, first.trajectory)
    assert again.grasp_index == first.grasp_index


def test_after_the_target_moves_the_goal_follows_and_the_plan_lifts_it(scene, replanned):
    replanner, first = replanned
    world = replanner.world
    before = np.linalg.inv(world.target_pose) @ first.hand_pose  # the hand in the object frame
    # The replanner's plan left the target out of every merged grid before it filled them: its move merges nothing.
    assert all(scene.target in e for e in world.sdf.merged_excludes)
    grids = world.sdf.merged_excludes
    moved_scene, T = _moved(scene, scene.target, (0.02, 0.0))
    result = replanner.replan(moved={scene.target: T})
    assert world.sdf.merged_excludes == grids
    assert result.success, result.status
    assert 1 <= result.iterations <= replanner.settings.iterations  # the moved approach is optimized, not jumped onto
    after = np.linalg.inv(T) @ result.hand_pose
    assert np.linalg.norm(after[:3, 3] - before[:3, 3]) < 0.02  # the same grasp, moved with the object
    np.testing.assert_array_equal(result.trajectory[0], first.trajectory[0])
    executed = execute_plan(moved_scene, result.trajectory)
    assert executed.success, (executed.status, executed.message)


def test_a_robot_that_moved_on_replans_from_where_it_is(scene):
    replanner = Replanner(OMGPlanner(None, scene, SETTINGS))
    first = replanner.plan()
    assert first.success
    q_now = first.trajectory[8]
    result = replanner.replan(start=q_now)
    assert result.success
    np.testing.assert_array_equal(result.trajectory[0], q_now)
    _, T = _moved(scene, scene.target, (-0.01, 0.015), yaw=0.3)
    result = replanner.replan(start=result.trajectory[4], moved={scene.target: T})
    assert result.success
