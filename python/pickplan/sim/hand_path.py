"""The hand moved in a straight line by the native IK: the lift after a grasp (``execution``), the hand
keeping pace with a moving target (``eval.moving``)."""
from __future__ import annotations

import numpy as np

from pickplan import _core

#: Damped-least-squares steps per waypoint, each waypoint solved from the previous one.
IK_STEPS = 3


def hand_path(robot, q0: np.ndarray, offsets: np.ndarray, damping: float) -> np.ndarray:
    """Configurations (K + 1, dof) of a described ``robot`` moving its hand by each of the (K, 3) world
    ``offsets`` from where it is at ``q0``, orientation held: the native damped-least-squares IK
    (fixed damping ``damping**2``, the arm joints inside their limits, fingers frozen), IK_STEPS
    steps per waypoint."""
    hand = robot.link_index(robot.info.hand_link)
    ik = _core.IkSettings()
    ik.weights = [1.0] * robot.info.arm_dof + [0.0] * (robot.dof - robot.info.arm_dof)
    ik.rotation_error = _core.IkRotationError.sine_axis
    ik.damping_schedule = _core.IkDamping.fixed
    ik.damping = damping ** 2
    ik.max_iterations = IK_STEPS
    ik.max_stalled_iterations = 0      # every step is taken, as many as asked
    ik.position_tolerance = ik.rotation_tolerance = 0.0
    ik.max_step = float("inf")
    targets = np.repeat(robot.fk(q0)[hand][None], len(offsets), axis=0)
    targets[:, :3, 3] += np.asarray(offsets, dtype=float)
    path, _ = _core.IkSolver(robot.native, hand, ik).solve_path(targets, q0)
    return np.vstack([q0, path])
