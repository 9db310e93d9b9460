"""Motion planning among obstacles (omg.motion) and the independent trajectory checker
(eval.trajectory_check): a board between two free waypoints is caught; RRT-Connect + CHOMP reaches
into a shelf where the straight line cannot, and the checker accepts what it returns."""

import numpy as np
import pytest

from pickplan.core import robots
from pickplan.core.shapes import Obstacle, Shape
from pickplan.eval.trajectory_check import TrajectoryChecker
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.motion import MotionSettings, MotionStatus, MotionWorld, Smoothing, plan_chomp, plan_motion
from pickplan.omg.pose_goal import Axis, PoseGoal


def at(x, y, z):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


@pytest.fixture(scope="module")
def arm():
    """The Panda with its fingers held open (only the 7 arm joints move)."""
    return robots.panda()


@pytest.fixture(scope="module")
def cache():
    """The robot's meshes and shapes, loaded once for the module's worlds and checkers."""
    return ModelCache()


def swing(arm, j1):
    q = arm.ready_configuration.copy()
    q[:7] = [j1, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785]  # the hand forward and low, about 0.55 m out
    return q


def test_checker_catches_a_thin_board_between_free_waypoints(arm, cache):
    board = Obstacle("board", Shape.box(0.5, 0.001, 0.6), at(0.55, 0.0, 0.3))  # 1 mm thick, across the swing
    path = np.stack([swing(arm, -0.45), swing(arm, 0.45)])
    checker = TrajectoryChecker(arm, [board], arm.description.skip_collision, cache=cache)
    assert not checker._collide.in_collision(path[0]) and not checker._collide.in_collision(path[1])
    report = checker.check(path)
    assert not report.valid and "board" in report.reason and report.states > 2
    # the dense states step no hull vertex by more than the resolution
    Q = checker.dense(path, checker.resolution)
    assert np.linalg.norm(np.diff(checker._points(Q), axis=0), axis=2).max() <= checker.resolution
    # without the board the same path passes, and reports its clearance to what is there
    far = Obstacle("far", Shape.sphere(0.05), at(-0.8, 0.0, 0.5))
    ok = TrajectoryChecker(arm, [far], arm.description.skip_collision, cache=cache).check(path)
    assert ok.valid and 0.3 < ok.min_clearance < 1.5
    # the planner's own motion check sees the board too
    world = MotionWorld(arm, [board], allowed_pairs=arm.description.skip_collision, cache=cache)
    assert not world.valid(path, 0.01)


def shelf():
    """A shelf 0.6 m in front of the robot, open towards it: boards at z 0.2 and 0.7, two sides, a back."""
    return [
        Obstacle("bottom", Shape.box(0.4, 0.8, 0.02), at(0.75, 0.0, 0.2), support=True),
        Obstacle("top", Shape.box(0.4, 0.8, 0.02), at(0.75, 0.0, 0.7)),
        Obstacle("left", Shape.box(0.4, 0.02, 0.52), at(0.75, 0.41, 0.45)),
        Obstacle("right", Shape.box(0.4, 0.02, 0.52), at(0.75, -0.41, 0.45)),
        Obstacle("back", Shape.box(0.02, 0.8, 0.52), at(0.96, 0.0, 0.45)),
    ]


@pytest.fixture(scope="module")
def shelf_world(arm, cache):
    return MotionWorld(arm, shelf(), allowed_pairs=arm.description.skip_collision, cache=cache)


def test_rrt_connect_then_chomp_reaches_into_a_shelf(arm, cache, shelf_world):
    world = shelf_world
    start = arm.ready_configuration.copy()
    start[:7] = [0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.785]  # the hand above the shelf, in front of its top
    goal = arm.ready_configuration.copy()
    goal[:7] = [0.0, 0.55, 0.0, -1.45, 0.0, 2.0, 0.785]  # the hand inside, between the boards
    checker = TrajectoryChecker(arm, shelf(), arm.description.skip_collision, cache=cache)
    assert not world.checker.in_collision(goal) and not world.checker.in_collision(start)
    assert not world.valid(np.stack([start, goal]), 0.01)  # the straight line hits the shelf
    result = plan_motion(world, start, goal, MotionSettings())
    assert result.status is MotionStatus.solved and result.source in ("chomp", "rrt")
    np.testing.assert_array_equal(result.path[0], start)
    np.testing.assert_allclose(result.path[-1], goal, atol=1e-9)
    assert checker.check(result.path).valid
    # deterministic for the seed
    np.testing.assert_array_equal(plan_motion(world, start, goal, MotionSettings()).path, result.path)
    rough = plan_motion(world, start, goal, MotionSettings(smoothing=Smoothing.none))
    assert rough.source == "rrt" and checker.check(rough.path).valid
    # CHOMP from the straight line alone: whatever it returns passes the motion check
    alone = plan_chomp(world, start, goal, MotionSettings())
    assert alone.status in (MotionStatus.solved, MotionStatus.not_found)
    if alone.solved:
        assert world.valid(alone.path, 0.01)


def test_bad_ends_are_statuses(arm, shelf_world):
    world = shelf_world
    inside = arm.ready_configuration.copy()
    inside[:7] = [0.0, 0.1, 0.0, -1.2, 0.0, 1.3, 0.785]  # the hand in the top board
    assert any(c.other == "top" for c in world.checker.contacts(inside))
    free = arm.ready_configuration
    assert plan_motion(world, inside, free).status is MotionStatus.invalid_start
    assert plan_motion(world, free, inside).status is MotionStatus.invalid_goals
    assert plan_motion(world, free, np.stack([inside, free])).status is MotionStatus.solved  # a goal set
    with pytest.raises(ValueError, match="expected 9 joint values"):
        plan_motion(world, free[:5], free)


def test_pose_goals_reach_the_pose_by_forward_kinematics(arm, cache, shelf_world):
    """A hand pose inside the shelf, as a pose goal: the path ends where forward kinematics puts the
    hand at the pose; with a free z axis the goal set holds turns of it, and the end keeps the axis."""
    world = shelf_world
    start = arm.ready_configuration.copy()
    start[:7] = [0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.785]
    inside = arm.ready_configuration.copy()
    inside[:7] = [0.0, 0.55, 0.0, -1.45, 0.0, 2.0, 0.785]
    hand = arm.hand_link
    T = arm.link_pose(inside, hand)
    checker = TrajectoryChecker(arm, shelf(), arm.description.skip_collision, cache=cache)
    fixed = plan_motion(world, start, PoseGoal(T, position_tolerance=1e-4, rotation_tolerance=1e-3))
    assert fixed.status is MotionStatus.solved and checker.check(fixed.path).valid
    np.testing.assert_array_equal(fixed.path[0], start)
    E = arm.link_pose(fixed.path[-1], hand)
    assert np.linalg.norm(E[:3, 3] - T[:3, 3]) < 2e-4
    assert np.arccos(np.clip((np.trace(E[:3, :3].T @ T[:3, :3]) - 1) / 2, -1, 1)) < 2e-3
    np.testing.assert_array_equal(fixed.path[-1, 7:], start[7:])  # the fingers keep their opening
    # a free axis: the turned poses are goals too (distinct hand rotations), the reached one keeps z
    turned = T.copy()
    c, s = np.cos(0.8), np.sin(0.8)
    turned[:3, :3] = T[:3, :3] @ np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    free = plan_motion(world, start, PoseGoal(turned, free_axis=Axis.z, turns=8))
    assert free.status is MotionStatus.solved and checker.check(free.path).valid
    assert len(free.goals) > 1
    ends = [arm.link_pose(q, hand) for q in free.goals]
    assert all(np.linalg.norm(e[:3, 3] - T[:3, 3]) < 2e-4 and e[:3, 2] @ T[:3, 2] > 1 - 1e-5 for e in ends)
    assert max(abs(np.arctan2(e[:3, 0] @ T[:3, 1], e[:3, 0] @ T[:3, 0])) for e in ends) > 0.5
    E = arm.link_pose(free.path[-1], hand)
    assert np.linalg.norm(E[:3, 3] - T[:3, 3]) < 2e-4 and E[:3, 2] @ T[:3, 2] > 1 - 1e-5
    # a pose out of reach is a status, not an exception
    far = T.copy()
    far[:3, 3] = [3.0, 0.0, 0.5]
    assert plan_motion(world, start, PoseGoal(far)).status is MotionStatus.unreachable
    with pytest.raises(ValueError, match="free axis"):
        PoseGoal(T, free_axis="w")
