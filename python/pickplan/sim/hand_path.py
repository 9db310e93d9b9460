"""The hand moved in a straight line by the native IK: the lift after a grasp (``execution``), the hand
keeping pace with a moving target (``eval.moving``)."""

from __future__ import annotations

import numpy as np

from pickplan import _core
from pickplan.core.ik import IkDamping, IkRotationError, IkSettings

#: Damped-least-squares steps per waypoint, each waypoint solved from the previous one.
IK_STEPS = 3


def hand_path(robot, q0: np.ndarray, offsets: np.ndarray, damping: float) -> np.ndarray:
    """Configurations (K + 1, dof) of a described ``robot`` moving its hand by each of the (K, 3) world
    ``offsets`` from where it is at ``q0``, orientation held: the native damped-least-squares IK
    (fixed damping ``damping**2``, the arm joints inside their limits, fingers frozen), IK_STEPS
    steps per waypoint."""
    hand = robot.link_index(robot.info.hand_link)
    ik = IkSettings(
        rotation_error=IkRotationError.sine_axis,
        damping_schedule=IkDamping.fixed,
        damping=damping**2,
        max_iterations=IK_STEPS,
        max_stalled_iterations=0,  # every step is taken, as many as asked
        position_tolerance=0.0,
        rotation_tolerance=0.0,
        max_step=float("inf"),
    )
    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    targets = np.repeat(robot.fk(q0)[hand][None], len(offsets), axis=0)
    targets[:, :3, 3] += np.asarray(offsets, dtype=float)
    path, _ = _core.IkSolver(robot.native, hand, ik.to_native(active)).solve_path(targets, q0)
    return np.vstack([q0, path])
