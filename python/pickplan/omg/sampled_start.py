"""A sampling-based initialization for Algorithm 2 where the straight line is none (a shelf, a cabinet):
RRT-Connect (native, to every goal's pre-grasp at once) from the start, shortened by shortcuts, resampled
to the transit's waypoints and joined to the reached goal's approach; the OMG loop then starts from it
(``run_loop``'s warm start) and CHOMP smooths it, the success test deciding as for any plan. Only goals
whose pre-grasp keeps the success test's transit clearance (``clear_pregrasps``) are offered to it: the
waypoint before a pre-grasp lies next to it, so a pre-grasp closer than that (the wrist under a shelf's
next board) fails the test whatever the path to it.

>>> warm = sampled_initialization(world, q0, goal_set.tails, n=30, settings=SampledStart())
>>> result = run_loop(settings, world, q0, goal_set, timings, warm=warm)
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Optional, Tuple

import numpy as np

from pickplan import _core
from pickplan.omg.furniture_check import pregrasps_clear_of_furniture
from pickplan.omg.motion import RrtSettings, resample
from pickplan.omg.world import CheckerKind


def clear_pregrasps(world, tails: np.ndarray, clearance: float, exact: Optional[float] = None) -> np.ndarray:
    """Rows of ``tails`` whose pre-grasp (first row) keeps ``clearance`` (m) between the robot's body
    points and everything but the target and the table, as the success test measures its transit;
    ``exact``: measured as the test among furniture does instead (``omg.furniture_check``: the links' hulls
    keep this much from the furniture and the objects but the target)."""
    if len(tails) == 0:
        return np.zeros(0, int)
    if exact is not None:
        return np.flatnonzero(pregrasps_clear_of_furniture(world, tails, exact))
    P = world.robot.transform_points(np.asarray(tails[:, 0], float), world.body)  # (G, points, 3)
    d, _ = world.sdf.distance(P.reshape(-1, 3), cutoff=clearance, exclude=[world.target], exclude_table=True)
    return np.flatnonzero(np.asarray(d).reshape(len(tails), -1).min(axis=1) >= clearance)


@dataclass(frozen=True)
class SampledStart:
    """Where the loop from the straight line fails the success test, it runs once more from an
    RRT-Connect path (``OMGSettings.sampled_start``; None: never). The path is checked by sampling
    (every ``rrt.resolution`` m of robot motion) against every object, the target included: it is only
    the optimizer's start, the success test judges the plan."""

    rrt: RrtSettings = field(default_factory=lambda: RrtSettings(time_limit=0.5, certified=False))
    shortcuts: int = 100
    attempts: int = 2  # RRT-Connect runs (new seeds) before giving up


def sampled_initialization(
    world, q0: np.ndarray, tails: np.ndarray, n: int, settings: SampledStart
) -> Optional[Tuple[np.ndarray, int]]:
    """(initial trajectory (n, dof) after ``q0``, the goal it ends on) or None when RRT-Connect found no
    path to any pre-grasp (``tails[:, 0]``) within its budget, or the world has no FCL checker to sample in."""
    robot = world.robot
    m = tails.shape[1]
    if n - m < 1 or len(tails) == 0:
        return None
    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    checker = getattr(world.checker(CheckerKind.strict), "native", None)
    if not isinstance(checker, _core.CollisionChecker):
        return None  # a world from depth (a field, no meshes) or carrying observed points: nothing to sample in
    for attempt in range(settings.attempts):
        rrt = replace(settings.rrt, seed=settings.rrt.seed + attempt)
        planner = _core.MotionPlanner(checker, rrt.to_native(active))
        out = planner.rrt_connect(np.asarray(q0, float), np.asarray(tails[:, 0], float))
        if out.status != _core.RrtStatus.solved:
            continue
        path = planner.shortcut(np.asarray(out.path), settings.shortcuts, rrt.seed)
        g = int(out.goal)
        transit = resample(np.asarray(path), n - m + 2)[1:-1]  # q0 and the pre-grasp excluded
        return np.vstack([transit, tails[g]]), g
    return None
