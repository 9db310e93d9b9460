"""The OMG planner (Algorithm 2): CHOMP-Proj steps, online goal selection over the goal set and
C-Space ISF refinement of the selected goal, for N iterations with pre-termination.

>>> planner = OMGPlanner(None, scene, OMGSettings())
>>> result = planner.plan()                # start and target from the scene, its default grasps
>>> result.status, result.metrics.smoothness
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Optional, Tuple, Union

import numpy as np

from pickplan import _core
from pickplan.core import robots
from pickplan.core.caches import mesh_content_key
from pickplan.core.timing import Interpolation, KinematicLimits, TimedTrajectory, robot_limits, time_parameterize
from pickplan.core.settings import Option
from pickplan.omg import grasps as grasps_mod
from pickplan.omg.chomp import ChompSettings, MetricSettings
from pickplan.omg.furniture_check import LoopCheck, exact_furniture, judged_among_furniture, transit_target_distance
from pickplan.omg.goals import GoalSet, GoalSetSettings, build_goal_set
from pickplan.core.ik import IkSettings
from pickplan.omg.grasps import GraspKind
from pickplan.omg.isf import IsfSettings
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.native_loop import StageClock, run_native
from pickplan.omg.sampled_start import SampledStart, clear_pregrasps, sampled_initialization
from pickplan.sim.scenes import Scene
from pickplan.omg.selection import Selection, make_policy
from pickplan.omg.world import CheckerKind, World, WorldSettings


class PlanStatus(Option):
    """How a plan ended (the paper's success test, Sec. IV-A)."""

    success = "success"  # collision-free and smooth
    in_collision = "in_collision"
    not_smooth = "not_smooth"
    no_goals = "no_goals"  # no grasp gave a goal configuration (see PlanResult.goal_reasons)
    ungraspable = "ungraspable"  # no grasp of this gripper can exist for the target as it lies (PlanResult.reason)
    # no grasp set of the kind asked for exists for the target (a sweep's unit with a stored set the object lacks; not
    # a planning failure)
    no_grasps = "no_grasps"

    @classmethod
    def of(cls, metrics) -> "PlanStatus":
        """The status of a trajectory with these metrics (``Chomp.metrics``, a ``TrajectoryMetrics``)."""
        if metrics.success:
            return cls.success
        return cls.in_collision if not metrics.collision_free else cls.not_smooth


@dataclass(frozen=True)
class OMGSettings:
    """The planner's settings; defaults are the paper's (Sec. IV-B)."""

    chomp: ChompSettings = field(default_factory=ChompSettings)
    goals: GoalSetSettings = field(default_factory=GoalSetSettings)
    ik: IkSettings = field(default_factory=IkSettings)
    isf: IsfSettings = field(default_factory=IsfSettings)
    metrics: MetricSettings = field(default_factory=MetricSettings)
    world: WorldSettings = field(default_factory=WorldSettings)
    selection: Selection = Selection.MD  # Fixed | Proj | FTC | FTL | EXP | MD (a spelling converts)
    iterations: int = 50  # N, the optimization horizon
    refine: bool = True  # C-Space ISF on the selected goal every iteration
    isf_steps: int = 1  # ISF steps per planner iteration
    # m: ISF may move the hand at most this far from the input grasp (a local refinement; verified grasps moved
    # farther were dropped in execution)
    isf_max_shift: float = 0.01
    cost_time_stride: int = 2  # goal-cost estimates on every k-th tail waypoint ...
    cost_point_stride: int = 2  # ... and every k-th body point (rescaled)
    transit_avoids_target: bool = True  # the target is an obstacle to the transit (before the approach)
    pre_terminate: bool = True  # stop once the plan succeeds (checked every check_every iterations)
    min_iterations: int = 10
    check_every: int = 5
    grasp_kind: GraspKind = GraspKind.simulated  # default grasps when plan() gets none: stored, else generated
    grasp_count: int = 100
    # Where the default grasp set of a generated kind (antipodal, approach) gives no goal (a target near a
    # shelf's wall, under a low board), a denser one of this many is tried once: the few grasps that fit
    # are often missing from 100. 0: never. Stored sets and grasps given to plan() are used as they are.
    dense_grasp_count: int = 1000
    seed: int = 0
    # Where the loop from the straight line fails in a scene with furniture (a shelf, a cabinet): once more
    # from an RRT-Connect path (``omg.sampled_start``); None: never. A tabletop plans as in the paper.
    sampled_start: Optional[SampledStart] = field(default_factory=SampledStart)
    # Among furniture the success test measures the links' hulls against the furniture exactly (FCL) in place of
    # the body points' 5 cm padding (``omg.furniture_check``); False: the paper's test everywhere.
    exact_furniture: bool = True
    # what PlanResult.timings read (thread_cpu: a loaded machine's other processes do not count)
    clock: StageClock = StageClock.wall

    def __post_init__(self):
        for name, low in (
            ("iterations", 1),
            ("check_every", 1),
            ("min_iterations", 0),
            ("isf_steps", 0),
            ("cost_time_stride", 1),
            ("cost_point_stride", 1),
            ("grasp_count", 1),
            ("dense_grasp_count", 0),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"OMGSettings.{name}: expected an integer >= {low}, got {value!r}")
        object.__setattr__(self, "selection", Selection.parse(self.selection, "selection policy"))
        object.__setattr__(self, "grasp_kind", GraspKind.parse(self.grasp_kind, "grasp set kind"))
        object.__setattr__(self, "clock", StageClock.parse(self.clock, "stage clock"))

    def denser_grasp_count(self) -> Optional[int]:
        """How many grasps to try where the default set gave no goal (``dense_grasp_count``), or None."""
        generated = self.grasp_kind in (GraspKind.antipodal, GraspKind.approach)
        return self.dense_grasp_count if generated and self.dense_grasp_count > self.grasp_count else None


@dataclass
class PlanResult:
    status: PlanStatus
    trajectory: np.ndarray  # (n + 1, dof): the start, then the n waypoints
    goal: np.ndarray  # final configuration (the grasp)
    grasp_index: int  # input grasp the final goal came from (-1 when none)
    hand_pose: np.ndarray  # world pose of the hand at the goal
    refined: bool  # the final goal was refined by C-Space ISF
    # smoothness, collision, min_clearance, success, ... (Sec. IV-A); None when nothing was planned
    metrics: Optional["_core.TrajectoryMetrics"]
    grasp_cost: float  # f_grasp at the final goal (eq. 10)
    goal_set_size: int
    iterations: int
    # objective, goal, p, costs (normalized estimates; per iteration), switches, initial_grasp
    history: dict
    # seconds: prepare (world, grasps; not planning), goal_set, chomp, costs, selection, isf, metrics, total (goal set
    # + planning)
    timings: dict
    goal_reasons: dict = field(default_factory=dict)
    goal_set: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (G, dof) the IK goal set
    goal_source: int = -1  # row of goal_set the final goal came from (refined or not; -1: none)
    limits: Optional[KinematicLimits] = None  # the planned robot's limits (``timed``'s default)
    reason: str = ""  # why, for ungraspable ("ungraspable: wider than the 8 cm opening ...")

    @classmethod
    def unplanned(
        cls, status: "PlanStatus", q0: np.ndarray, timings: dict, goal_reasons: dict, reason: str = ""
    ) -> "PlanResult":
        """A result with no plan (no goal, an ungraspable target): the start alone, empty history."""
        history = {"objective": [], "goal": [], "p": [], "costs": [], "switches": 0, "initial_grasp": -1}
        return cls(
            status,
            np.vstack([q0]),
            q0,
            -1,
            np.eye(4),
            False,
            None,
            float("nan"),
            0,
            0,
            history,
            timings,
            goal_reasons,
            reason=reason,
        )

    @property
    def success(self) -> bool:
        return self.status == PlanStatus.success

    @property
    def planned(self) -> bool:
        """A trajectory was optimized (there were goals to plan to)."""
        return self.status not in (PlanStatus.no_goals, PlanStatus.ungraspable)

    def timed(
        self,
        rate: float = 1000.0,
        limits: Optional[KinematicLimits] = None,
        interpolation: Interpolation = Interpolation.PCHIP,
    ) -> TimedTrajectory:
        """The trajectory timed within ``limits`` (default: the planned robot's), sampled at ``rate`` Hz, from
        rest to rest along the same path (``pickplan.core.timing.time_parameterize``)."""
        return time_parameterize(self.trajectory, rate, limits or self.limits, interpolation)


class OMGPlanner:
    """Joint motion and grasp planning for one robot: ``robot`` is the robot planned for, a
    ``robots.DescribedRobot`` (``robots.load_robot("ur5_2f85")``) or a description's name or file;
    None: ``settings.world.robot`` (the Panda by default). Placed at the scene's robot base.

    Made once and asked again and again: ``plan(scene=...)`` plans in another scene, and what depends
    only on the objects or the robot (SDFs, FCL shapes, the robot's data: ``cache``, a ``ModelCache``
    the planner owns unless one is given) is built once for all of them."""

    def __init__(
        self,
        robot=None,
        scene: Optional[Scene] = None,
        settings: OMGSettings = OMGSettings(),
        world: Optional[World] = None,
        cache: Optional[ModelCache] = None,
    ):
        self.settings = settings
        self.scene = world.scene if scene is None and world is not None else scene
        self._world = world
        self.cache = cache if cache is not None else world.cache if world is not None else ModelCache()
        if robot is not None and not isinstance(robot, (str, robots.DescribedRobot)):
            raise ValueError(
                f"robot: expected a robots.DescribedRobot, a description name or file, or None; got "
                f"{type(robot).__name__} (a bare URDF Robot has no gripper: write a description)"
            )
        if robot is not None and world is not None and robots.load_robot(robot).info.name != world.robot.info.name:
            raise ValueError(
                f"robot: {robots.load_robot(robot).info.name!r} but the world was built for {world.robot.info.name!r}"
            )
        self.robot = robot

    def use_scene(self, scene: Scene) -> None:
        """Plan in ``scene`` from now on (its world is built on the next plan, from the planner's cache)."""
        if scene is not self.scene:
            self.scene, self._world = scene, None

    def world(self, target: Optional[str] = None) -> World:
        if self.scene is None:
            raise ValueError("no scene: give one (OMGPlanner(robot, scene) or plan(scene=...))")
        target = target or self.scene.target
        if self._world is None or self._world.target != target:
            scene = self.scene if target == self.scene.target else replace(self.scene, target=target)
            robot = self.robot if self.robot is not None else (self._world.robot if self._world else None)
            self._world = World(scene, self.settings.world, robot=robot, cache=self.cache)
        return self._world

    def default_grasps(self, world: World, count: Optional[int] = None) -> np.ndarray:
        """The settings' grasp set of the target for this robot's gripper (``count`` grasps, default the
        settings'): it depends on the object and the gripper only, so it is built once per planner cache
        (a copy is returned)."""
        s, model, gripper = self.settings, world.target_model, world.robot.info
        count = s.grasp_count if count is None else int(count)
        key = ("grasp_set", mesh_content_key(model.mesh), model.name, str(s.grasp_kind), count, s.seed, gripper.key)
        poses = self.cache.derived(
            key, lambda: grasps_mod.grasp_set(model, s.grasp_kind, count, seed=s.seed, gripper=gripper).poses
        )
        return np.array(poses)

    def _denser_goal_set(self, world: World, q0: np.ndarray) -> Optional[GoalSet]:
        """The goal set of ``dense_grasp_count`` default grasps, where the settings allow one."""
        s, count = self.settings, self.settings.denser_grasp_count()
        return None if count is None else build_goal_set(world, self.default_grasps(world, count), q0, s.goals, s.ik)

    def _prepare(self, world: World, start, grasps) -> Tuple[np.ndarray, np.ndarray]:
        """The checked start and the grasps; builds what the scene caches (FCL models, ISF data)."""
        s = self.settings
        q0 = world.robot.check_within_limits(world.start if start is None else start, "start")
        if grasps is None:
            grasps = self.default_grasps(world)
        elif isinstance(grasps, str):
            grasps = grasps_mod.grasp_set(
                world.target_model, grasps, s.grasp_count, seed=s.seed, gripper=world.robot.info
            ).poses
        world.checker(CheckerKind.goal), world.checker(CheckerKind.hand)  # FCL models: built once per scene, cached
        if s.refine:
            world.grasp_refiner(s.isf, s.seed)  # hand SDF, object samples: cached likewise
        return q0, grasps

    def plan(
        self,
        start: Optional[np.ndarray] = None,
        target: Optional[str] = None,
        grasps: Optional[Union[np.ndarray, str]] = None,
        scene: Optional[Scene] = None,
    ) -> PlanResult:
        """Algorithm 2 from ``start`` (default: the scene's) to one of ``grasps`` of ``target``
        (default: the scene's; grasps: poses, a grasp set kind, or None for ``default_grasps``);
        ``scene``: plan in this scene from now on (``use_scene``)."""
        if scene is not None:
            self.use_scene(scene)
        return self.plan_with_goals(start, target, grasps)[0]

    def plan_with_goals(
        self,
        start: Optional[np.ndarray] = None,
        target: Optional[str] = None,
        grasps: Optional[Union[np.ndarray, str]] = None,
        dense: bool = True,
    ) -> Tuple[PlanResult, Optional[GoalSet]]:
        """``plan`` and the goal set it planned over (None when the target cannot be grasped at all):
        what a replan starts from (``omg.replan``). ``dense``: where the default grasps give no goal, try
        the denser set (``OMGSettings.dense_grasp_count``; seconds, not what a real-time loop can wait for)."""
        s = self.settings
        clock = _clock(s)
        t = clock()
        world = self.world(target)
        densify = grasps is None and dense
        q0, grasps = self._prepare(world, start, grasps)
        # Scene preparation (SDFs, FCL models, grasp generation) is not planning: timed apart.
        timings = dict.fromkeys(("goal_set", "chomp", "costs", "selection", "isf", "metrics"), 0.0)
        verdict = target_graspability(world)  # geometry, scene preparation: no goal set for what cannot be grasped
        timings["prepare"] = clock() - t
        t_total = clock()

        t = clock()
        gs = build_goal_set(world, grasps, q0, s.goals, s.ik) if verdict.graspable else None
        if gs is not None and len(gs) == 0 and densify:
            gs = self._denser_goal_set(world, q0) or gs
        timings["goal_set"] = clock() - t
        if gs is None or len(gs) == 0:
            timings["total"] = clock() - t_total
            status = PlanStatus.no_goals if verdict.graspable else PlanStatus.ungraspable
            return PlanResult.unplanned(
                status,
                q0,
                timings,
                gs.reason_counts() if gs is not None else {},
                "" if verdict.graspable else f"ungraspable: {verdict.reason}",
            ), gs
        result = self._optimize(world, q0, gs, timings)
        timings["total"] = clock() - t_total
        result.goal_reasons = gs.reason_counts()
        result.limits = robot_limits(world.robot)
        return result, gs

    def _optimize(self, world: World, q0: np.ndarray, gs: GoalSet, timings: dict) -> PlanResult:
        """Algorithm 2's loop over a non-empty goal set (the test oracle overrides it); where it fails, once
        more from a sampling-based initialization (``OMGSettings.sampled_start``)."""
        result = run_loop(self.settings, world, q0, gs, timings)
        if not retries_sampled(world):
            return result
        return sampled_retry(self.settings, world, q0, gs, timings, result)


def retries_sampled(world) -> bool:
    """Whether ``OMGPlanner`` runs a failed loop once more from a sampled start in ``world``: among furniture
    (a shelf), where the straight line is often no start; a tabletop plans from it alone, as in the paper."""
    return bool(getattr(getattr(world, "scene", None), "obstacles", None))


def sampled_retry(s: OMGSettings, world, q0: np.ndarray, gs: GoalSet, timings: dict, result: PlanResult) -> PlanResult:
    """``result`` (the loop's from the straight line) unless it failed and the loop once more from a
    sampling-based initialization (``OMGSettings.sampled_start``; None: never) passes the success test."""
    if result.success or s.sampled_start is None:
        return result
    clock = _clock(s)
    t = clock()
    exact = s.exact_furniture and exact_furniture(world)
    keep = clear_pregrasps(world, gs.tails, s.metrics.clearance, s.metrics.tail_clearance if exact else None)
    clear = replace(gs, goals=gs.goals[keep], tails=gs.tails[keep], grasp_index=gs.grasp_index[keep])
    warm = sampled_initialization(world, q0, clear.tails, s.chomp.n, s.sampled_start) if len(keep) else None
    timings["sampled_start"] = clock() - t
    if warm is None:
        return result
    retry = run_loop(s, world, q0, clear, timings, warm=warm)
    if not retry.success:
        return result
    retry.history["sampled_start"] = True
    retry.goal_set = np.array(gs.goals)  # rows of the whole goal set, as plan_with_goals returns it
    retry.goal_source = int(keep[retry.goal_source]) if 0 <= retry.goal_source < len(keep) else -1
    return retry


def plan_to_goal_set(settings: OMGSettings, world, q0: np.ndarray, goal_set: GoalSet, warm=None) -> PlanResult:
    """Algorithm 2 from ``q0`` to a built, non-empty ``goal_set`` in any world with ``chomp`` (and
    ``grasp_refiner`` when ``settings.refine``): how a place goal set is planned (``omg.place``), with
    the same CHOMP-Proj steps, online selection and success test as a grasp; from ``warm`` (``run_loop``'s)
    first when given, then from the straight line."""
    if len(goal_set) == 0:
        raise ValueError("plan_to_goal_set: the goal set is empty")
    clock = _clock(settings)
    t = clock()
    timings = dict.fromkeys(("chomp", "costs", "selection", "isf", "metrics"), 0.0)
    timings["goal_set"] = goal_set.seconds
    q0 = np.asarray(q0, dtype=float)
    # a transfer carries the held object among the others, where the straight line often is no start
    result = run_loop(settings, world, q0, goal_set, timings, warm=warm) if warm is not None else None
    if result is None or not result.success:
        result = run_loop(settings, world, q0, goal_set, timings)
    result = sampled_retry(settings, world, q0, goal_set, timings, result)
    timings["total"] = clock() - t + goal_set.seconds
    result.goal_reasons = goal_set.reason_counts()
    result.limits = robot_limits(world.robot)
    return result


def _clock(settings: OMGSettings):
    """The timer ``settings.clock`` names."""
    return settings.clock.timer()


def target_graspability(world: World):
    """Whether the world's gripper can grasp its target as it lies at all (``core.graspability``;
    computed once per world)."""
    return world.graspability


@dataclass(frozen=True)
class LoopInputs:
    """What Algorithm 2's loop runs with, built from the settings and the world: the CHOMP problem
    (the approach tail free of obstacle cost), the success test's settings, C-Space ISF (None without
    refinement) and a fresh selection policy."""

    chomp: object
    metric_settings: MetricSettings
    refiner: object
    policy: object

    @classmethod
    def of(cls, settings: OMGSettings, world: World, tail_length: int) -> "LoopInputs":
        # The standoff approach (the last m waypoints) carries no obstacle cost, so the transit before it
        # may keep away from the target too: the arm does not sweep through the object it will grasp.
        avoid = tail_length > 0 and settings.transit_avoids_target
        metrics = replace(settings.metrics, tail_waypoints=tail_length)
        if avoid and getattr(world.scene, "obstacles", None):
            # Among furniture the transit reaches in level beside the target, and the test holds it to that:
            # the target kept the approach's clearance (on a tabletop, the paper's test).
            metrics = replace(metrics, transit_target_clearance=metrics.tail_clearance)
        return cls(
            world.chomp(replace(settings.chomp, obstacle_tail=tail_length), avoid_target=avoid),
            metrics,
            world.grasp_refiner(settings.isf, settings.seed) if settings.refine else None,
            make_policy(settings.selection),
        )


def run_loop(settings: OMGSettings, world: World, q0: np.ndarray, gs: GoalSet, timings: dict, warm=None) -> PlanResult:
    """Algorithm 2's loop over the non-empty goal set ``gs`` in C++ (``native_loop``, the GIL
    released); ``timings`` gains the seconds of each stage. (tests/python/omg_reference_loop.py
    keeps the loop in Python, the oracle the native loop is tested against.) ``warm``: (the initial
    trajectory after ``q0``, its goal in ``gs`` or -1[, the goals' costs to start the selection from or None]),
    a replan's start (``omg.replan``)."""
    parts = LoopInputs.of(settings, world, gs.tails.shape[1])
    m = gs.tails.shape[1]
    check = (
        LoopCheck(world, q0, m, parts.metric_settings) if settings.exact_furniture and exact_furniture(world) else None
    )
    out = run_native(
        parts.chomp,
        parts.refiner,
        world.robot,
        q0,
        gs.goals,
        gs.tails,
        gs.grasp_index,
        settings,
        parts.policy,
        parts.metric_settings,
        warm,
        None if check is None else (check.mask, check),
    )
    for phase, seconds in out.seconds.to_dict().items():
        timings[phase] += seconds
    history = {
        "objective": list(out.objective),
        "goal": list(out.goals_chosen),
        "p": out.p,
        "costs": out.costs,
        "switches": out.switches,
        "initial_grasp": out.initial_grasp,
    }
    xi, robot = out.xi, world.robot
    metrics = out.metrics
    known = check.measured(xi) if check is not None else None  # the plan the loop's check accepted
    if check is not None:
        metrics, history["furniture_distance"] = judged_among_furniture(
            parts.chomp, world, q0, xi, m, parts.metric_settings, None if known is None else known[0]
        )
    if metrics.success and parts.metric_settings.transit_target_clearance > -np.inf and isinstance(world, World):
        # The success test measures body points (a few per link: a finger's 20 leave 1.7 cm of its surface
        # unsampled); the transit's clearance from the target is what pushes it in execution: measured exactly.
        distance = (
            known[1]
            if known is not None and known[1] is not None
            else transit_target_distance(world, np.vstack([q0, xi]), m, parts.metric_settings.steps)
        )
        history["transit_target_distance"] = distance
        if distance < parts.metric_settings.transit_target_clearance:
            metrics = _core.marked_in_collision(metrics)
    return PlanResult(
        PlanStatus.of(metrics),
        np.vstack([q0, xi]),
        xi[-1].copy(),
        out.grasp_index,
        robot.link_pose(xi[-1], robot.hand_link),
        out.refined,
        metrics,
        out.grasp_cost,
        out.goal_set_size,
        out.iterations,
        history,
        timings,
        goal_set=np.array(gs.goals),
        goal_source=out.goal_source,
    )
