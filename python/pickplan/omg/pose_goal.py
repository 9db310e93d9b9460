"""End-effector pose goals for ``omg.motion``: a link at a pose, within IK's tolerances, optionally
free to turn about one axis of the target frame (a symmetric object's axis, a tool's roll). The free
axis becomes a goal set: the pose turned about it at evenly spaced angles, every distinct IK solution
of each; the motion planner then reaches whichever of them it can.

>>> goal = PoseGoal(T_target, free_axis=Axis.z)
>>> result = plan_motion(world, q_start, goal)      # as for joint goals
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.core.ik import IkSettings
from pickplan.core.poses import clean_pose
from pickplan.core.settings import Option


class Axis(Option):
    x = "x"
    y = "y"
    z = "z"


@dataclass(frozen=True)
class PoseGoal:
    """``link`` (default: the robot's hand link) at ``pose`` (4x4, world frame), its origin within
    ``position_tolerance`` m and its orientation within ``rotation_tolerance`` rad of it; with a
    ``free_axis``, any turn of the pose about that axis of its own frame will do (``turns`` samples
    of the full turn)."""

    pose: np.ndarray
    link: Optional[str] = None
    free_axis: Optional[Axis] = None
    turns: int = 12
    position_tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3
    max_goals: int = 32  # nearest to the start first

    def __post_init__(self):
        object.__setattr__(self, "pose", clean_pose(self.pose, "pose goal"))
        if self.free_axis is not None:
            object.__setattr__(self, "free_axis", Axis.parse(self.free_axis, "free axis"))
        if int(self.turns) < 1 or int(self.max_goals) < 1:
            raise ValueError("pose goal: turns and max_goals must be >= 1")
        if not (self.position_tolerance > 0 and self.rotation_tolerance > 0):
            raise ValueError("pose goal: tolerances must be > 0")

    def targets(self) -> np.ndarray:
        """(T, 4, 4) the poses that satisfy the goal: the pose itself, or its turns about the free axis."""
        if self.free_axis is None:
            return self.pose[None]
        a = "xyz".index(self.free_axis.value)
        b, c = (a + 1) % 3, (a + 2) % 3
        out = []
        for t in np.arange(int(self.turns)) * (2.0 * np.pi / int(self.turns)):
            R = np.eye(4)  # a turn by t about the frame's own axis a
            R[b, b], R[b, c], R[c, b], R[c, c] = np.cos(t), -np.sin(t), np.sin(t), np.cos(t)
            out.append(self.pose @ R)
        return np.stack(out)


def pose_goal_configurations(
    robot, active, start: np.ndarray, goal: PoseGoal, ik: IkSettings = IkSettings()
) -> np.ndarray:
    """(G, dof) configurations putting ``goal.link`` at one of ``goal.targets()``, distinct, nearest
    to ``start`` first, at most ``goal.max_goals``; joints not ``active`` keep the start's values."""
    link = goal.link or getattr(robot, "hand_link", None)
    if link is None:
        raise ValueError("pose goal: give its link (this robot names no hand link)")
    settings = replace(ik, position_tolerance=goal.position_tolerance, rotation_tolerance=goal.rotation_tolerance)
    solver = _core.IkSolver(robot.native, robot.link_index(link), settings.to_native(active))
    found = []
    for T in goal.targets():
        for s in solver.solve_all(T, start):
            q = np.asarray(s.q, dtype=float)
            if all(np.linalg.norm(q - p) > ik.duplicate_tolerance for p in found):
                found.append(q)
    if not found:
        return np.zeros((0, robot.dof))
    Q = np.stack(found)
    return Q[np.argsort(np.linalg.norm(Q - start, axis=1), kind="stable")][: int(goal.max_goals)]
