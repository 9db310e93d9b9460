"""An upright start for a transfer: the hand moved in a straight line from the lifted configuration to a
pre-place, turning only as the held object's start and end orientations differ (slerp), by IK along the
way. The straight line in joint space tilts a held object by up to 36 deg between two upright poses
(the bench's YCB transfers), and a grasp judged upright slips there; CHOMP then starts from a path
that keeps the object as it was held.

>>> warm = upright_initialization(carrying, q_lift, goal_set.tails, n=30)
>>> run_loop(settings, carrying, q_lift, goal_set, timings, warm=warm)   # None: the straight line
"""

from __future__ import annotations

from typing import Optional, Tuple

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from pickplan.core.ik import IkSettings
from pickplan.omg.attach import hand_pose_path

# rad: the most a joint may move between two waypoints of the seed (IK that jumped to another branch
# gives no seed: the straight line in joint space is kept)
MAX_STEP = 0.5


def upright_initialization(
    world, q0: np.ndarray, tails: np.ndarray, n: int, ik: IkSettings = IkSettings()
) -> Optional[Tuple[np.ndarray, int]]:
    """(initial trajectory (n, dof) after ``q0``, the goal in ``tails`` it ends on) or None when the
    hand's path has no IK solution near its neighbours all the way (``MAX_STEP``). The goal is the pre-place
    (``tails[:, 0]``) nearest ``q0`` in joint space."""
    robot = world.robot
    q0, tails = np.asarray(q0, float), np.asarray(tails, float)
    m = tails.shape[1]
    if n - m < 1 or len(tails) == 0:
        return None
    g = int(np.argmin(np.linalg.norm(tails[:, 0] - q0, axis=1)))
    hand = robot.link_index(robot.hand_link)
    T0, T1 = robot.fk(q0)[hand], robot.fk(tails[g, 0])[hand]
    t = np.arange(1, n - m + 1) / (n - m + 1)  # q0 and the pre-place excluded
    targets = np.tile(np.eye(4), (len(t), 1, 1))
    targets[:, :3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([T0[:3, :3], T1[:3, :3]]))(t).as_matrix()
    targets[:, :3, 3] = (1 - t)[:, None] * T0[:3, 3] + t[:, None] * T1[:3, 3]
    path, good = hand_pose_path(robot, q0, targets, ik, MAX_STEP)
    if not good.all() or np.abs(tails[g, 0] - path[-1]).max() > MAX_STEP:
        return None
    return np.vstack([path[1:], tails[g]]), g
