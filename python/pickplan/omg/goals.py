"""Goal sets: grasps (hand poses in the object frame) -> IK -> standoff approach -> FCL filter
(approach clearance) -> diversity -> cap. Native; every rejected grasp records why."""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.core.settings import Option, to_native
from pickplan.omg.world import CheckerKind, World


class IkTask(Option):
    pose = "pose"
    position = "position"


class IkRotationError(Option):
    angle_axis = "angle_axis"
    sine_axis = "sine_axis"


class IkDamping(Option):
    adaptive = "adaptive"
    fixed = "fixed"


class IkStepNorm(Option):
    max_abs = "max_abs"
    euclidean = "euclidean"


@dataclass(frozen=True)
class IkSettings:
    """Mirror of the native ``IkSettings`` (one damped-least-squares descent's settings, then the
    spread of seeds); ``to_native`` sets the per-joint weights."""

    task: IkTask = IkTask.pose
    rotation_error: IkRotationError = IkRotationError.angle_axis
    max_iterations: int = 40
    position_tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3
    damping_schedule: IkDamping = IkDamping.adaptive
    damping: float = 1e-2
    damping_decrease: float = 0.3
    damping_increase: float = 10.0
    min_damping: float = 1e-8
    max_damping: float = 1e4
    min_relative_decrease: float = 1e-3
    max_stalled_iterations: int = 8
    max_step: float = 0.5
    step_norm: IkStepNorm = IkStepNorm.max_abs
    limit_margin: float = 0.0
    num_seeds: int = 24
    seed: int = 0
    duplicate_tolerance: float = 0.05

    def to_native(self, active) -> "_core.IkSettings":
        """The native settings; joints not ``active`` are frozen (weight 0)."""
        return to_native(self, _core.IkSettings, weights=[1.0 if a else 0.0 for a in active])


@dataclass(frozen=True)
class GoalSetSettings:
    """Mirror of the native ``GoalSetSettings`` (paper: 30 goals per scene, 8 cm standoff), plus
    ``approach_clearance``: every configuration of the standoff approach (pre-grasp to grasp) must
    keep this distance from the other objects, measured as the success test measures it (body
    points in the scene SDF, target and table left out): the clearance the test demands of a plan's
    approach (``MetricSettings.tail_clearance``). The approach is pinned: neither CHOMP nor the
    goal-cost estimate can move or charge it, so a goal failing this could never succeed.
    0 disables the check."""

    approach_clearance: float = 0.01
    standoff: float = 0.08
    standoff_steps: int = 4
    max_joint_jump: float = 0.5
    diversity: float = 0.1
    max_goals: int = 30
    max_solutions: int = 4
    seed: int = 0

    def to_native(self) -> "_core.GoalSetSettings":
        return to_native(self, _core.GoalSetSettings, skip=("approach_clearance",))


@dataclass
class GoalSet:
    goals: np.ndarray        # (G, dof) grasp configurations
    tails: np.ndarray        # (G, standoff_steps + 1, dof): pre-grasp first, grasp last
    grasp_index: np.ndarray  # (G,) index into ``grasps``
    grasps: np.ndarray       # (N, 4, 4) the input grasps (hand in the object frame)
    reasons: list            # per input grasp: "ok" or why it was rejected
    seconds: float

    def __len__(self) -> int:
        return int(self.goals.shape[0])

    def reason_counts(self) -> dict:
        return dict(Counter(self.reasons))


def check_grasps(grasps) -> np.ndarray:
    g = np.asarray(grasps, dtype=float)
    if g.ndim != 3 or g.shape[1:] != (4, 4):
        raise ValueError(f"grasps: expected shape (N, 4, 4), got {g.shape}")
    return g


def ik_solver(world: World, settings: IkSettings = IkSettings()) -> "_core.IkSolver":
    robot = world.robot
    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    return _core.IkSolver(robot.native, robot.hand_link, settings.to_native(active))


def build_goal_set(world: World, grasps, start: Optional[np.ndarray] = None,
                   settings: GoalSetSettings = GoalSetSettings(), ik: IkSettings = IkSettings(),
                   collision_check: bool = True) -> GoalSet:
    """Goal configurations for the world's target from grasps in its object frame.

    An object with no reachable grasp gives an empty goal set (with reasons), not an exception.
    """
    grasps = check_grasps(grasps)
    start = world.start if start is None else np.asarray(start, dtype=float)
    hand_poses = np.einsum("ij,njk->nik", world.target_pose, grasps) if len(grasps) else grasps
    checker = world.checker(CheckerKind.goal).native if collision_check else None
    hand_checker = world.checker(CheckerKind.hand).native if collision_check else None
    problem = world.clearance_problem if collision_check and settings.approach_clearance > 0 else None
    out = _core.build_goal_set(ik_solver(world, ik), checker, hand_checker, hand_poses, start, settings.to_native(),
                               problem, float(settings.approach_clearance))
    return GoalSet(np.asarray(out["goals"]), np.asarray(out["tails"]), np.asarray(out["grasp_index"], dtype=int),
                   grasps, list(out["reasons"]), float(out["seconds"]))
