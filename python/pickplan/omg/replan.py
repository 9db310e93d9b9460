"""Replanning as the world moves: a warm start from the last plan.

``Replanner(planner)`` plans once from scratch (``plan``), then ``replan`` after the world changed
(the target or another object moved, the robot moved on):

1. the objects move in place in the planner's world (``World.move_object``: the SDF and the FCL
   models follow, nothing is rebuilt);
2. the goals follow the target: the grasps the last goal set kept, at the target's new pose, each
   IK seeded with its last goal; a target that did not move keeps its goal set as it was, with the
   goal C-Space ISF refined last time;
3. Algorithm 2 starts from the last trajectory moved to the new start, on the last goal, with the
   loop of ``ReplanSettings``; a start that still passes the success test is returned as it is, and
   a warm loop that fails it is followed by a plan from scratch (never worse than planning anew).

When fewer than ``min_goals`` goals follow (the target turned so far that they collide or leave the
arm's reach), the goal set is built from every grasp again and the loop starts on the best goal.

>>> replanner = Replanner(OMGPlanner(None, scene))
>>> first = replanner.plan()
>>> again = replanner.replan(start=q_now, moved={scene.target: T_new})
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Dict, Optional, Tuple

import numpy as np

from pickplan.core.timing import robot_limits
from pickplan.omg.chomp import cubic_blend
from pickplan.omg.goals import GoalSet, build_goal_set
from pickplan.omg.planner import OMGPlanner, PlanResult, PlanStatus, _clock, run_loop


@dataclass(frozen=True)
class ReplanSettings:
    iterations: int = 20  # the warm loop's cap (a fresh plan's: OMGSettings.iterations)
    min_iterations: int = 2  # the success test from this iteration on, every check_every
    check_every: int = 2
    min_goals: int = 3  # fewer goals follow the target: the goal set is built from every grasp again
    # The goals that follow a moved target: the last plan's and those its last cost estimates ranked best
    # (each goal's IK chain and cost estimates are most of a replan's time, and far goals rarely win after
    # a small move; 10 -> 5 took a replan after a 2 cm move from 11.4 to 9.0 ms with the same plans lifted,
    # 39 of 40 generated scenes; a followed set that fails is followed by a plan from scratch)
    max_goals: int = 5
    fresh_on_failure: bool = True  # a warm loop that fails the success test is followed by a plan from scratch

    def __post_init__(self):
        if min(self.iterations, self.min_iterations, self.check_every, self.min_goals, self.max_goals) < 1:
            raise ValueError(
                f"replan settings: iterations, min_iterations, check_every, min_goals and max_goals must "
                f"be >= 1, got {self}"
            )


def warm_trajectory(last: np.ndarray, start: np.ndarray) -> np.ndarray:
    """The n waypoints after ``start`` from ``last`` (n + 1 rows, its start first): the rest of the last
    path from its waypoint nearest ``start``, resampled to n + 1 points, its first point moved onto
    ``start`` and the offset blended out along the path (the initialization's cubic) so the end stays."""
    last = np.asarray(last, dtype=float)
    n = len(last) - 1
    k = int(np.argmin(np.linalg.norm(last - start, axis=1)))
    rest = last[k:]
    if len(rest) != n + 1:  # resampled by index: exact (the same rows) when nothing was cut
        at = np.linspace(0.0, len(rest) - 1, n + 1)
        rest = np.column_stack([np.interp(at, np.arange(len(rest)), rest[:, j]) for j in range(rest.shape[1])])
    return rest[1:] + (1.0 - cubic_blend(n))[:, None] * (np.asarray(start, dtype=float) - rest[0])[None, :]


class Replanner:
    """Plans, then replans from its last plan as the world moves (see the module doc). One per planner
    and thread: it moves objects in the planner's world."""

    def __init__(self, planner: OMGPlanner, settings: ReplanSettings = ReplanSettings(), grasps=None):
        self.planner, self.settings, self.grasps = planner, settings, grasps
        self.last: Optional[PlanResult] = None
        self._goals: Optional[GoalSet] = None
        self._start: Optional[np.ndarray] = None
        self._target_pose: Optional[np.ndarray] = None
        self._grasp_ids = np.zeros(0, int)  # the input grasp of each row of the goal set's grasps

    @property
    def world(self):
        return self.planner.world()

    def plan(self, start: Optional[np.ndarray] = None) -> PlanResult:
        """Algorithm 2 from scratch (``OMGPlanner.plan``), remembered for the next ``replan``. The target
        is expected to move (``World.expect_motion``) before the plan fills the SDF grids it reads: a first
        replan after a 2 cm move then took 7.6 ms instead of 9.8 (median of 40 generated scenes)."""
        world = self.world
        if hasattr(world, "expect_motion"):  # a perceived world moves no object (replans from a new start only)
            world.expect_motion(world.target)
        result, goals = self.planner.plan_with_goals(start, grasps=self.grasps, dense=False)  # in real time
        self._grasp_ids = np.arange(0 if goals is None else len(goals.grasps))
        self._remember(result, goals)
        return result

    def replan(self, start: Optional[np.ndarray] = None, moved: Optional[Dict[str, np.ndarray]] = None) -> PlanResult:
        """A plan from ``start`` (default: the last plan's) after the objects in ``moved`` (name -> 4x4
        pose in the world) moved; from scratch when there is no last plan with goals."""
        world = self.world
        for name, pose in (moved or {}).items():
            world.move_object(name, pose)
        if self.last is None or self._goals is None or len(self._goals) == 0 or not self.last.planned:
            return self.plan(start)
        s = self.planner.settings
        clock = _clock(s)
        t_total = clock()
        q0 = world.robot.check_within_limits(self._start if start is None else start, "start")
        timings = dict.fromkeys(("goal_set", "chomp", "costs", "selection", "isf", "metrics"), 0.0)
        t = clock()
        goals, goal, costs = self._follow(world, q0)
        if len(goals) < self.settings.min_goals:
            q0, grasps = self.planner._prepare(world, q0, self.grasps)
            goals, goal, costs = build_goal_set(world, grasps, q0, s.goals, s.ik), -1, None
            self._grasp_ids = np.arange(len(grasps))
        timings["goal_set"] = clock() - t
        if len(goals) == 0:
            timings["total"] = clock() - t_total
            result = PlanResult.unplanned(PlanStatus.no_goals, q0, timings, goals.reason_counts())
            self._remember(result, goals)
            return result
        r = self.settings
        loop = replace(
            s, iterations=r.iterations, min_iterations=min(r.min_iterations, r.iterations), check_every=r.check_every
        )
        result = run_loop(
            loop,
            world,
            q0,
            goals,
            timings,
            warm=(warm_trajectory(self.last.trajectory, q0), goal, costs if goal >= 0 else None),
        )
        if not result.success and self.settings.fresh_on_failure:
            warm_seconds = clock() - t_total
            fresh = self.plan(q0)
            fresh.timings["total"] += warm_seconds
            fresh.timings["warm"] = warm_seconds
            return fresh
        timings["total"] = clock() - t_total
        result.goal_reasons = goals.reason_counts()
        result.limits = robot_limits(world.robot)
        self._remember(result, goals)
        return replace(result, grasp_index=int(self._grasp_ids[result.grasp_index]) if result.grasp_index >= 0 else -1)

    def _remember(self, result: PlanResult, goals: Optional[GoalSet]) -> None:
        """Keeps the plan as planned (its grasp_index: a row of ``goals.grasps``, which ``_grasp_ids``
        maps to the input grasps)."""
        self.last, self._goals = result, goals
        self._start = np.asarray(result.trajectory[0], dtype=float)
        self._target_pose = self.world.target_pose.copy()

    def _follow(self, world, q0: np.ndarray) -> Tuple[GoalSet, int, Optional[np.ndarray]]:
        """The last goal set at the target's pose now, the row of the last plan's goal in it (-1: lost) and
        the last plan's latest cost estimate of each of its goals (the selection starts from them: the
        goals moved as little as the target did; None: the last plan has none)."""
        last, goals = self.last, self._goals
        m = goals.tails.shape[1]
        if np.array_equal(world.target_pose, self._target_pose):
            # Nothing to follow: the goals stand, and the goal planned last with them (ISF's refined copy added).
            if not last.refined:
                return goals, last.goal_source, self._last_costs(np.arange(len(goals)))
            rows = np.append(np.arange(len(goals)), -1)  # -1: the last plan's final goal, the refined copy
            return (
                replace(
                    goals,
                    goals=np.vstack([goals.goals, last.goal]),
                    tails=np.concatenate([goals.tails, last.trajectory[None, -m:]]),
                    grasp_index=np.append(goals.grasp_index, goals.grasp_index[last.goal_source]),
                ),
                len(goals),
                self._last_costs(rows),
            )
        rows = self._best_rows(len(goals))
        # Goal row rows[k] of the last set becomes grasp k here: the followed set's grasp_index index rows.
        followed = build_goal_set(
            world,
            goals.grasps[goals.grasp_index[rows]],
            q0,
            self.planner.settings.goals,
            self.planner.settings.ik,
            seeds=goals.goals[rows],
        )
        self._grasp_ids = self._grasp_ids[goals.grasp_index[rows]]
        new = np.flatnonzero(rows[followed.grasp_index] == last.goal_source) if len(followed) else []
        return followed, int(new[0]) if len(new) else -1, self._last_costs(rows[followed.grasp_index])

    def _last_costs(self, rows: np.ndarray) -> Optional[np.ndarray]:
        """The last plan's latest goal-cost estimates of its goal-set ``rows`` (-1: its final goal),
        normalized as the loop's estimates are; None when it kept none."""
        history = self.last.history
        if not history.get("costs") or not history.get("goal") or not len(rows):
            return None
        last = np.asarray(history["costs"][-1], dtype=float)
        c = last[np.where(rows < 0, int(history["goal"][-1]), rows)]
        norm = np.linalg.norm(c)
        return c / norm if norm > 0 and np.all(np.isfinite(c)) else None

    def _best_rows(self, count: int) -> np.ndarray:
        """Rows of the last goal set to follow: the last plan's goal first, then the lowest last estimates."""
        last = self.last
        costs = (
            np.asarray(last.history["costs"][-1], dtype=float)[:count] if last.history.get("costs") else np.zeros(count)
        )
        order = [r for r in np.argsort(costs, kind="stable") if r != last.goal_source]
        first = [last.goal_source] if last.goal_source >= 0 else []
        return np.sort(np.array(first + order, dtype=int)[: self.settings.max_goals])
