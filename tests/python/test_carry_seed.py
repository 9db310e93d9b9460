"""The transfer's upright start (``omg.carry_seed``), against forward kinematics: the hand moves on the
straight line between the lifted pose and the pre-place and turns only about the vertical (the yaw
between them), where the straight line in joint space tilts it; the seed ends on the goal's tail."""

from types import SimpleNamespace

import numpy as np

from pickplan.core import robots
from pickplan.core.ik import IkSettings
from pickplan.omg.carry_seed import MAX_STEP, upright_initialization
from pickplan.omg.goals import ik_solver


def _yaw(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _world_and_goal(turn_deg: float, shift):
    robot = robots.load_robot("panda")
    world = SimpleNamespace(robot=robot, cache=None)
    hand = robot.link_index(robot.hand_link)
    q0 = np.array(robot.ready_configuration, float)
    T0 = robot.fk(q0)[hand]
    T1 = np.array(T0)
    T1[:3, :3] = _yaw(np.radians(turn_deg)) @ T0[:3, :3]
    T1[:3, 3] += shift
    out = ik_solver(world, IkSettings()).solve_all(T1, q0)
    assert out, "the test's pre-place is out of reach"
    q1 = np.array(out[0].q, float)
    q1[robot.info.arm_dof :] = q0[robot.info.arm_dof :]
    tail = np.vstack([q1 + 0.01 * k * (np.arange(robot.dof) < robot.info.arm_dof) for k in range(4)])
    return world, robot, hand, q0, T0, T1, tail[None]


def _tilt_deg(T, T0) -> float:
    up = T[:3, :3] @ T0[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # a world-vertical axis carried by the hand
    return float(np.degrees(np.arccos(np.clip(up[2], -1.0, 1.0))))


def test_the_seed_keeps_the_held_object_upright_on_the_straight_line():
    world, robot, hand, q0, T0, T1, tails = _world_and_goal(75.0, [-0.15, 0.35, -0.1])
    n = 24
    seed, goal = upright_initialization(world, q0, tails, n)
    assert goal == 0 and seed.shape == (n, robot.dof)
    assert np.array_equal(seed[-tails.shape[1] :], tails[0])  # ends on the goal's tail
    transit = seed[: n - tails.shape[1]]
    poses = np.array([robot.fk(q)[hand] for q in transit])
    assert max(_tilt_deg(T, T0) for T in poses) < 0.5
    # on the segment between the two hand positions, in order
    d = T1[:3, 3] - T0[:3, 3]
    t = (poses[:, :3, 3] - T0[:3, 3]) @ d / (d @ d)
    assert np.all(np.diff(t) > 0) and 0 < t[0] and t[-1] < 1
    assert np.abs(poses[:, :3, 3] - (T0[:3, 3] + t[:, None] * d)).max() < 1e-3
    path = np.vstack([q0, transit, tails[0, 0]])
    assert np.abs(np.diff(path, axis=0)).max() <= MAX_STEP
    # the straight line in joint space between the same configurations tilts the hand
    line = q0 + np.linspace(0, 1, 20)[:, None] * (tails[0, 0] - q0)
    assert max(_tilt_deg(robot.fk(q)[hand], T0) for q in line) > 2.0


def test_no_seed_without_transit_waypoints():
    world, _, _, q0, _, _, tails = _world_and_goal(30.0, [0.0, 0.2, 0.0])
    assert upright_initialization(world, q0, tails, n=tails.shape[1]) is None
