"""Baselines of the OMG paper's Table III on the same scenes, goal sets and collision model as OMG.

* ``CHOMP`` [33]: the goals are ranked by OMG's initial objective estimate (the native
  ``goal_costs`` at iteration 0), then plain CHOMP toward one fixed goal (with its standoff tail)
  runs through the ranked list until a plan meets the paper's success test (collision-free,
  smoothness < 30); at most ``max_goals_tried`` goals are tried (default 5).
* ``CHOMP-C`` [11]: OMG with ``selection="Proj", refine=False`` (see ``chomp_c_settings``).
* ``FMT`` [21] and ``RRT-C`` [25]: OMPL (PyPI wheel ``ompl``) in the 7-D space of the arm joints
  within their limits; state validity is the native FCL checker ``world.checker("obstacles")``
  (the target ignored: the plan ends at the pre-grasp, the first row of the goal's standoff tail,
  and the tail is appended), with the fingers allowed on the table as far as the success test
  allows them (``SupportValidity``); OMPL's standard simplification (shortcutting + smoothing); a time
  limit per goal; through the same ranked goal list; the path is resampled by arc length to the
  same n waypoints (tail included) so the paper's metrics apply unchanged.

Every baseline returns an ``omg.PlanResult``.

>>> result = plan_baseline("RRT-C", scene, BaselineSettings())
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Optional, Union

import numpy as np

from pickplan import _core
from pickplan.core import collision
from pickplan.core.settings import Option
from pickplan.omg import grasps as grasps_mod
from pickplan.omg.chomp import cubic_initialization
from pickplan.omg.goals import build_goal_set
from pickplan.omg.planner import OMGSettings, PlanResult, PlanStatus
from pickplan.sim.scenes import Scene
from pickplan.omg.world import CheckerKind, World
from pickplan.omg.planner import OMGPlanner
from pickplan.omg.selection import Selection


class Baseline(Option):
    """Table III's baseline planners."""

    CHOMP = "CHOMP"  # goal-set CHOMP towards the ranked goals, one at a time
    CHOMP_C = "CHOMP-C"  # OMG with the projection rule and no refinement [11]
    FMT = "FMT"  # OMPL's FMT* to the pre-grasp, then the standoff tail
    RRT_C = "RRT-C"  # OMPL's RRT-Connect likewise


OMPL_PLANNERS = (Baseline.FMT, Baseline.RRT_C)


@dataclass(frozen=True)
class BaselineSettings:
    """Shared with OMG through ``omg`` (CHOMP settings, goal set, IK, metrics, grasps, seed)."""

    omg: OMGSettings = field(default_factory=OMGSettings)
    max_goals_tried: int = 5  # goals of the ranked list tried before giving up
    chomp_iterations: int = 50  # plain CHOMP iterations per goal (OMG's N)
    time_limit: float = 1.0  # s of OMPL planning per goal
    simplify_time: float = 0.2  # s of OMPL path simplification per solution
    check_resolution: float = 0.005  # OMPL motion-validation step, fraction of the space's extent


def chomp_c_settings(settings: OMGSettings) -> OMGSettings:
    """CHOMP-C [11] is OMG's goal-set CHOMP with the projection rule and no refinement."""
    return replace(settings, selection=Selection.Proj, refine=False)


def _empty(q0, timings, gs) -> PlanResult:
    return PlanResult(
        PlanStatus.no_goals,
        np.vstack([q0]),
        q0,
        -1,
        np.eye(4),
        False,
        None,
        float("nan"),
        0,
        0,
        {"objective": [], "goal": [], "p": [], "switches": 0},
        timings,
        gs.reason_counts(),
    )


class SupportValidity:
    """Whether an arm configuration is valid for a sampling planner, by the success test's rule: nothing
    may touch an obstacle but the fingers, which may rest on the table up to the support tolerance
    (a pre-grasp of a thin object has its fingertips there). The exact finger depth is computed only
    when the strict check fails, so free states cost one FCL query."""

    def __init__(self, world: World, q0: np.ndarray, tolerance: Optional[float] = None):
        self.world, self.robot = world, world.robot
        self.strict = world.checker(CheckerKind.obstacles).native
        fingers = tuple(self.robot.finger_links)
        self.relaxed = world.checker(CheckerKind.transit).native if fingers else None
        # the fingers keep q0's opening along a path: their hulls in the hand frame are fixed
        self.fingers = world.cache.finger_geometry(self.robot, q0) if fingers else None
        self.tolerance = collision.SupportContact(tolerance).resolved(self.robot) if fingers else 0.0
        self.normal, self.offset = world.support_plane

    def __call__(self, q: np.ndarray) -> bool:
        if not self.strict.in_collision(q):
            return True
        if self.fingers is None or self.relaxed.in_collision(q):
            return False  # something other than a finger on the table
        H = self.robot.link_pose(q, self.robot.hand_link)
        if not self.world.over_support(H[None, :3, 3])[0]:
            return False
        return bool(self.fingers.penetration(H, self.normal, self.offset)[0] <= self.tolerance)


class _Problem:
    """Goal set, CHOMP problem and ranking shared by the baselines."""

    def __init__(self, scene: Scene, settings: BaselineSettings, world: Optional[World], grasps):
        s = settings.omg
        self.settings = settings
        self.world = world if world is not None and world.target == scene.target else World(scene, s.world)
        self.q0 = self.world.robot.check_within_limits(self.world.start, "start")
        if grasps is None or isinstance(grasps, str):
            kind = grasps or s.grasp_kind
            grasps = grasps_mod.grasp_set(self.world.target_model, kind, s.grasp_count, seed=s.seed).poses
        self.timings = dict.fromkeys(("goal_set", "ranking", "planning", "metrics"), 0.0)
        t = time.perf_counter()
        gs = build_goal_set(self.world, grasps, self.q0, s.goals, s.ik)
        self._rank(gs, time.perf_counter() - t)

    @classmethod
    def on_goal_set(cls, world, q0: np.ndarray, gs, settings: BaselineSettings) -> "_Problem":
        """The problem of a goal set already built in ``world`` (a place goal set in an ``attach.HeldWorld``)."""
        pb = cls.__new__(cls)
        pb.settings, pb.world, pb.q0 = settings, world, np.asarray(q0, dtype=float)
        pb.timings = dict.fromkeys(("goal_set", "ranking", "planning", "metrics"), 0.0)
        pb._rank(gs, gs.seconds)
        return pb

    def _rank(self, gs, seconds: float) -> None:
        s = self.settings.omg
        self.gs = gs
        self.timings["goal_set"] = seconds
        if len(self.gs) == 0:
            return
        self.m = self.gs.tails.shape[1]
        # the world's problem (built once per settings): the target left out of the obstacle cost and the metrics
        self.chomp = self.world.chomp(replace(s.chomp, obstacle_tail=self.m))
        self.metric_settings = replace(s.metrics, tail_waypoints=self.m)
        t = time.perf_counter()
        xi = cubic_initialization(self.q0, self.gs.goals[0], s.chomp.n)
        c = self.chomp.problem.goal_costs(
            xi,
            self.q0,
            0,
            s.iterations,
            np.asarray(self.gs.goals),
            s.cost_time_stride,
            s.cost_point_stride,
            self.chomp.workspace(),
        )
        self.ranking = [int(i) for i in np.argsort(np.asarray(c), kind="stable")]
        self.timings["ranking"] = time.perf_counter() - t

    def metrics(self, xi) -> "_core.TrajectoryMetrics":
        t = time.perf_counter()
        out = self.chomp.metrics(xi, self.q0, self.metric_settings)
        self.timings["metrics"] += time.perf_counter() - t
        return out

    def result(self, xi, g, metrics, attempts, t_total) -> PlanResult:
        self.timings["total"] = time.perf_counter() - t_total
        status = PlanStatus.of(metrics)
        robot = self.world.robot
        hand = robot.link_pose(xi[-1], robot.hand_link)
        history = {
            "objective": [],
            "goal": [g],
            "p": [],
            "switches": 0,
            "attempts": attempts,
            "ranking": self.ranking[: self.settings.max_goals_tried],
        }
        return PlanResult(
            status,
            np.vstack([self.q0, xi]),
            xi[-1].copy(),
            int(self.gs.grasp_index[g]),
            hand,
            False,
            metrics,
            float("nan"),
            len(self.gs),
            len(attempts),
            history,
            dict(self.timings),
            self.gs.reason_counts(),
        )


def plan_chomp(
    scene: Scene, settings: BaselineSettings = BaselineSettings(), world: Optional[World] = None, grasps=None
) -> PlanResult:
    """Plain CHOMP through the ranked goal list (first feasible plan; else the top goal's plan)."""
    t_total = time.perf_counter()
    return _chomp_over(_Problem(scene, settings, world, grasps), settings, t_total)


def _chomp_over(pb: _Problem, settings: BaselineSettings, t_total: float) -> PlanResult:
    if len(pb.gs) == 0:
        pb.timings["total"] = time.perf_counter() - t_total
        return _empty(pb.q0, pb.timings, pb.gs)
    first = None
    attempts = []
    for g in pb.ranking[: settings.max_goals_tried]:
        t = time.perf_counter()
        out = pb.chomp.optimize(pb.q0, pb.gs.tails[g], settings.chomp_iterations, metric_settings=None)
        pb.timings["planning"] += time.perf_counter() - t
        metrics = pb.metrics(out.xi)
        attempts.append({"goal": g, "success": bool(metrics.success)})
        if first is None:
            first = (out.xi, g, metrics)
        if metrics.success:
            return pb.result(out.xi, g, metrics, attempts, t_total)
    return pb.result(*first, attempts, t_total)


def resample_path(points: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal arc length along a piecewise-linear path, the first after its start
    (fractions 1/count .. 1): the last point is the path's end."""
    points = np.asarray(points, dtype=float)
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(points[-1:], count, axis=0)
    targets = s[-1] * np.arange(1, count + 1) / count
    return np.stack([np.interp(targets, s, points[:, j]) for j in range(points.shape[1])], axis=1)


def _ompl():
    try:
        from ompl import base as ob, geometric as og, util as ou
    except ImportError as exc:  # a clear message rather than a deep traceback
        raise ImportError("the FMT and RRT-C baselines need OMPL's Python wheel: pip install ompl") from exc
    ou.setLogLevel(ou.LogLevel.LOG_ERROR)
    return ob, og, ou


_OMPL_SEEDED = []  # OMPL's seed is process-wide and can be set once, before its first random number


def _seed_ompl(ou, seed: int) -> None:
    """Seed OMPL once per process (later seeds would be ignored with an error message): OMPL runs are
    reproducible for a fresh process, not across plans within one."""
    if not _OMPL_SEEDED:
        ou.RNG.setSeed(int(seed) + 1)
        _OMPL_SEEDED.append(int(seed) + 1)


def ompl_setup(ob, og, robot, joints: int):
    """OMPL's space of the robot's first ``joints`` joints within their limits, and a SimpleSetup on it."""
    space = ob.RealVectorStateSpace(joints)
    bounds = ob.RealVectorBounds(joints)
    for j in range(joints):
        bounds.setLow(j, float(robot.lower_limits[j]))
        bounds.setHigh(j, float(robot.upper_limits[j]))
    space.setBounds(bounds)
    return space, og.SimpleSetup(space)


def plan_ompl(
    scene: Scene,
    planner: Union[Baseline, str] = Baseline.RRT_C,
    settings: BaselineSettings = BaselineSettings(),
    world: Optional[World] = None,
    grasps=None,
) -> PlanResult:
    """FMT* or RRT-Connect to the pre-grasp of each ranked goal, then the goal's standoff tail."""
    _ompl()  # a clear ImportError before any work
    planner = Baseline.parse(planner, "baseline")
    if planner not in OMPL_PLANNERS:
        raise ValueError(f"unknown OMPL planner {planner.value!r}; use 'FMT' or 'RRT-C'")
    t_total = time.perf_counter()
    return _ompl_over(_Problem(scene, settings, world, grasps), planner, settings, t_total)


def _ompl_over(pb: _Problem, planner: Baseline, settings: BaselineSettings, t_total: float) -> PlanResult:
    ob, og, ou = _ompl()
    if len(pb.gs) == 0:
        pb.timings["total"] = time.perf_counter() - t_total
        return _empty(pb.q0, pb.timings, pb.gs)
    robot = pb.world.robot
    arm = robot.info.arm_dof
    q0 = pb.q0
    validity = SupportValidity(pb.world, q0, settings.omg.metrics.support_tolerance)
    _seed_ompl(ou, settings.omg.seed)
    space, ss = ompl_setup(ob, og, robot, arm)
    q = q0.copy()

    def valid(state) -> bool:
        q[:arm] = state[0:arm]
        return validity(q)  # a Python bool: OMPL's binding rejects numpy bools

    ss.setStateValidityChecker(valid)
    si = ss.getSpaceInformation()
    si.setStateValidityCheckingResolution(settings.check_resolution)
    n = settings.omg.chomp.n
    free = n - pb.m  # waypoints before the tail; the path ends at the tail's first row
    first = None
    attempts = []
    for g in pb.ranking[: settings.max_goals_tried]:
        tail = pb.gs.tails[g]
        start, goal = space.allocState(), space.allocState()
        for j in range(arm):
            start[j], goal[j] = float(q0[j]), float(tail[0][j])
        ss.clear()
        ss.setStartAndGoalStates(start, goal)
        ss.setPlanner(og.RRTConnect(si) if planner is Baseline.RRT_C else og.FMT(si))
        t = time.perf_counter()
        solved = ss.solve(settings.time_limit) if valid(goal) and valid(start) else None
        exact = solved is not None and bool(ss.haveExactSolutionPath())
        if exact:
            ss.simplifySolution(settings.simplify_time)
            path = ss.getSolutionPath()
            pts = np.array([path.getState(i)[0:arm] for i in range(path.getStateCount())])
        else:  # no path: the straight line (it fails the metrics, as a failed plan should)
            pts = np.stack([q0[:arm], tail[0][:arm]])
        pb.timings["planning"] += time.perf_counter() - t
        xi = np.repeat(q0[None, :], n, axis=0)
        xi[: free + 1, :arm] = resample_path(np.vstack([q0[:arm], pts[1:]]), free + 1)
        xi[free:] = tail
        metrics = pb.metrics(xi)
        attempts.append({"goal": g, "found": exact, "success": bool(metrics.success)})
        if first is None:
            first = (xi, g, metrics)
        if exact and metrics.success:
            return pb.result(xi, g, metrics, attempts, t_total)
    return pb.result(*first, attempts, t_total)


def plan_baseline_to_goal_set(
    name: Union[Baseline, str], world, q0: np.ndarray, goal_set, settings: BaselineSettings = BaselineSettings()
) -> PlanResult:
    """``CHOMP``, ``FMT`` or ``RRT-C`` from ``q0`` to a goal set already built in ``world`` (a place goal
    set in an ``attach.HeldWorld``): the same ranking, tries and success test as for grasps."""
    name = Baseline.parse(name, "baseline")
    t_total = time.perf_counter()
    if name is Baseline.CHOMP_C:
        raise ValueError("baseline CHOMP-C plans over grasps (OMG's loop), not to a goal set")
    pb = _Problem.on_goal_set(world, q0, goal_set, settings)
    if name is Baseline.CHOMP:
        return _chomp_over(pb, settings, t_total)
    return _ompl_over(pb, name, settings, t_total)


def plan_baseline(
    name: Union[Baseline, str],
    scene: Scene,
    settings: BaselineSettings = BaselineSettings(),
    world: Optional[World] = None,
    grasps=None,
) -> PlanResult:
    """A ``Baseline`` (or its name: ``CHOMP``, ``CHOMP-C``, ``FMT``, ``RRT-C``) on ``scene`` (its
    target, its start)."""
    name = Baseline.parse(name, "baseline")
    if name is Baseline.CHOMP:
        return plan_chomp(scene, settings, world, grasps)
    if name in OMPL_PLANNERS:
        return plan_ompl(scene, name, settings, world, grasps)
    return OMGPlanner(None, scene, chomp_c_settings(settings.omg), world=world).plan(grasps=grasps)
