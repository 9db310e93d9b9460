"""The OMG planner (Algorithm 2): CHOMP-Proj steps, online goal selection over the goal set and
C-Space ISF refinement of the selected goal, for N iterations with pre-termination.

>>> planner = OMGPlanner(None, scene, OMGSettings())
>>> result = planner.plan()                # start and target from the scene, its default grasps
>>> result.status, result.metrics["smoothness"]
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Optional, Tuple, Union

import numpy as np

from pickplan.core import robots
from pickplan.core.timing import Interpolation, KinematicLimits, TimedTrajectory, robot_limits, time_parameterize
from pickplan.core.settings import Option
from pickplan.omg import grasps as grasps_mod
from pickplan.omg.chomp import ChompSettings, MetricSettings, cubic_initialization
from pickplan.omg.goals import GoalSet, GoalSetSettings, IkSettings, build_goal_set
from pickplan.omg.grasps import GraspKind
from pickplan.omg.isf import IsfSettings
from pickplan.omg.native_loop import PlanLoop, StageClock, run_native
from pickplan.sim.scenes import Scene
from pickplan.omg.selection import CostKind, Selection, make_policy
from pickplan.omg.world import CheckerKind, World, WorldSettings


class PlanStatus(Option):
    """How a plan ended (the paper's success test, Sec. IV-A)."""

    success = "success"            # collision-free and smooth
    in_collision = "in_collision"
    not_smooth = "not_smooth"
    no_goals = "no_goals"          # no grasp gave a goal configuration (see PlanResult.goal_reasons)
    ungraspable = "ungraspable"    # no grasp of this gripper can exist for the target as it lies (PlanResult.reason)

    @classmethod
    def of(cls, metrics: dict) -> "PlanStatus":
        """The status of a trajectory with these metrics (``Chomp.metrics``)."""
        if metrics["success"]:
            return cls.success
        return cls.in_collision if not metrics["collision_free"] else cls.not_smooth


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
    iterations: int = 50           # N, the optimization horizon
    refine: bool = True            # C-Space ISF on the selected goal every iteration
    isf_steps: int = 1             # ISF steps per planner iteration
    isf_max_shift: float = 0.01    # m: ISF may move the hand at most this far from the input grasp (a
                                   # local refinement; verified grasps moved farther were dropped in execution)
    cost_time_stride: int = 2      # goal-cost estimates on every k-th tail waypoint ...
    cost_point_stride: int = 2     # ... and every k-th body point (rescaled)
    transit_avoids_target: bool = True  # the target is an obstacle to the transit (before the approach)
    pre_terminate: bool = True     # stop once the plan succeeds (checked every check_every iterations)
    min_iterations: int = 10
    check_every: int = 5
    grasp_kind: GraspKind = GraspKind.simulated  # default grasps when plan() gets none: stored, else generated
    grasp_count: int = 100
    seed: int = 0
    loop: PlanLoop = PlanLoop.native  # Algorithm 2's loop in C++, or in Python (the reference; same plans)
    clock: StageClock = StageClock.wall  # what PlanResult.timings read (thread_cpu: a loaded machine's
                                         # other processes do not count)

    def __post_init__(self):
        for name, low in (("iterations", 1), ("check_every", 1), ("min_iterations", 0), ("isf_steps", 0),
                          ("cost_time_stride", 1), ("cost_point_stride", 1), ("grasp_count", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"OMGSettings.{name}: expected an integer >= {low}, got {value!r}")
        object.__setattr__(self, "selection", Selection.parse(self.selection, "selection policy"))
        object.__setattr__(self, "grasp_kind", GraspKind.parse(self.grasp_kind, "grasp set kind"))
        object.__setattr__(self, "loop", PlanLoop.parse(self.loop, "planner loop"))
        object.__setattr__(self, "clock", StageClock.parse(self.clock, "stage clock"))


@dataclass
class PlanResult:
    status: PlanStatus
    trajectory: np.ndarray         # (n + 1, dof): the start, then the n waypoints
    goal: np.ndarray               # final configuration (the grasp)
    grasp_index: int               # input grasp the final goal came from (-1 when none)
    hand_pose: np.ndarray          # world pose of the hand at the goal
    refined: bool                  # the final goal was refined by C-Space ISF
    metrics: dict                  # smoothness, collision, min_clearance, success, ... (Sec. IV-A)
    grasp_cost: float              # f_grasp at the final goal (eq. 10)
    goal_set_size: int
    iterations: int
    history: dict                  # objective, goal, p, costs (normalized estimates; per iteration),
                                   # switches, initial_grasp
    timings: dict                  # seconds: prepare (world, grasps; not planning), goal_set, chomp, costs,
                                   # selection, isf, metrics, total (goal set + planning)
    goal_reasons: dict = field(default_factory=dict)
    goal_set: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (G, dof) the IK goal set
    goal_source: int = -1          # row of goal_set the final goal came from (refined or not; -1: none)
    limits: Optional[KinematicLimits] = None  # the planned robot's limits (``timed``'s default)
    reason: str = ""               # why, for ungraspable ("ungraspable: wider than the 8 cm opening ...")

    @property
    def success(self) -> bool:
        return self.status == PlanStatus.success

    @property
    def planned(self) -> bool:
        """A trajectory was optimized (there were goals to plan to)."""
        return self.status not in (PlanStatus.no_goals, PlanStatus.ungraspable)

    def timed(self, rate: float = 1000.0, limits: Optional[KinematicLimits] = None,
              interpolation: Interpolation = Interpolation.PCHIP) -> TimedTrajectory:
        """The trajectory timed within ``limits`` (default: the planned robot's), sampled at ``rate`` Hz, from
        rest to rest along the same path (``pickplan.core.timing.time_parameterize``)."""
        return time_parameterize(self.trajectory, rate, limits or self.limits, interpolation)


class OMGPlanner:
    """Joint motion and grasp planning for one scene and one robot: ``robot`` is the robot planned for,
    a ``robots.DescribedRobot`` (``robots.load_robot("ur5_2f85")``) or a description's name or file;
    None: ``settings.world.robot`` (the Panda by default). Placed at the scene's robot base."""

    def __init__(self, robot, scene: Scene, settings: OMGSettings = OMGSettings(),
                 world: Optional[World] = None):
        self.settings = settings
        self.scene = scene
        self._world = world
        if robot is not None and not isinstance(robot, (str, robots.DescribedRobot)):
            raise ValueError(f"robot: expected a robots.DescribedRobot, a description name or file, or None; got "
                             f"{type(robot).__name__} (a bare URDF Robot has no gripper: write a description)")
        if robot is not None and world is not None and \
                robots.load_robot(robot).info.name != world.robot.info.name:
            raise ValueError(f"robot: {robots.load_robot(robot).info.name!r} but the world was built for "
                             f"{world.robot.info.name!r}")
        self.robot = robot

    def world(self, target: Optional[str] = None) -> World:
        target = target or self.scene.target
        if self._world is None or self._world.target != target:
            scene = self.scene if target == self.scene.target else replace(self.scene, target=target)
            robot = self.robot if self.robot is not None else (self._world.robot if self._world else None)
            self._world = World(scene, self.settings.world, robot=robot)
        return self._world

    def default_grasps(self, world: World) -> np.ndarray:
        s = self.settings
        return grasps_mod.grasp_set(world.target_model, s.grasp_kind, s.grasp_count, seed=s.seed,
                                    gripper=world.robot.info).poses

    def _prepare(self, world: World, start, grasps) -> Tuple[np.ndarray, np.ndarray]:
        """The checked start and the grasps; builds what the scene caches (FCL models, ISF data)."""
        s = self.settings
        q0 = world.robot.check_within_limits(world.start if start is None else start, "start")
        if grasps is None:
            grasps = self.default_grasps(world)
        elif isinstance(grasps, str):
            grasps = grasps_mod.grasp_set(world.target_model, grasps, s.grasp_count, seed=s.seed,
                                          gripper=world.robot.info).poses
        world.checker(CheckerKind.goal), world.checker(CheckerKind.hand)  # FCL models: built once per scene, cached
        if s.refine:
            world.grasp_refiner(s.isf, s.seed)  # hand SDF, object samples: cached likewise
        return q0, grasps

    def plan(self, start: Optional[np.ndarray] = None, target: Optional[str] = None,
             grasps: Optional[Union[np.ndarray, str]] = None) -> PlanResult:
        """Algorithm 2 from ``start`` (default: the scene's) to one of ``grasps`` of ``target``
        (default: the scene's; grasps: poses, a grasp set kind, or None for ``default_grasps``)."""
        s = self.settings
        clock = _clock(s)
        t = clock()
        world = self.world(target)
        q0, grasps = self._prepare(world, start, grasps)
        # Scene preparation (SDFs, FCL models, grasp generation) is not planning: timed apart.
        timings = dict.fromkeys(("goal_set", "chomp", "costs", "selection", "isf", "metrics"), 0.0)
        verdict = target_graspability(world)  # geometry, scene preparation: no goal set for what cannot be grasped
        timings["prepare"] = clock() - t
        t_total = clock()

        t = clock()
        gs = build_goal_set(world, grasps, q0, s.goals, s.ik) if verdict.graspable else None
        timings["goal_set"] = clock() - t
        if gs is None or len(gs) == 0:
            timings["total"] = clock() - t_total
            history = {"objective": [], "goal": [], "p": [], "costs": [], "switches": 0, "initial_grasp": -1}
            status = PlanStatus.no_goals if verdict.graspable else PlanStatus.ungraspable
            return PlanResult(status, np.vstack([q0]), q0, -1, np.eye(4), False, {}, float("nan"), 0, 0, history,
                              timings, gs.reason_counts() if gs is not None else {},
                              reason="" if verdict.graspable else f"ungraspable: {verdict.reason}")
        optimization = _Optimization(s, world, q0, GoalBook(gs, world.robot), timings)
        result = optimization.run() if s.loop is PlanLoop.python else optimization.run_native()
        timings["total"] = clock() - t_total
        result.goal_reasons = gs.reason_counts()
        result.limits = robot_limits(world.robot)
        return result


def plan_to_goal_set(settings: OMGSettings, world, q0: np.ndarray, goal_set: GoalSet) -> PlanResult:
    """Algorithm 2 from ``q0`` to a built, non-empty ``goal_set`` in any world with ``chomp`` (and
    ``grasp_refiner`` when ``settings.refine``): how a place goal set is planned (``omg.place``), with
    the same CHOMP-Proj steps, online selection and success test as a grasp."""
    if len(goal_set) == 0:
        raise ValueError("plan_to_goal_set: the goal set is empty")
    clock = _clock(settings)
    t = clock()
    timings = dict.fromkeys(("chomp", "costs", "selection", "isf", "metrics"), 0.0)
    timings["goal_set"] = goal_set.seconds
    optimization = _Optimization(settings, world, np.asarray(q0, dtype=float), GoalBook(goal_set, world.robot), timings)
    result = optimization.run() if settings.loop is PlanLoop.python else optimization.run_native()
    timings["total"] = clock() - t + goal_set.seconds
    result.goal_reasons = goal_set.reason_counts()
    result.limits = robot_limits(world.robot)
    return result


def _clock(settings: OMGSettings):
    """The timer ``settings.clock`` names (looked up per call: a bench may replace perf_counter)."""
    return time.thread_time if settings.clock is StageClock.thread_cpu else time.perf_counter


def target_graspability(world: World):
    """Whether the world's gripper can grasp its target as it lies at all (``core.graspability``;
    computed once per world)."""
    return world.graspability


class GoalBook:
    """The goal set as the planner changes it: the first time C-Space ISF moves a goal, its refined
    copy joins the set; later refinements update that copy in place. Goals ISF cannot improve (no
    decrease found, or beyond ``isf_max_shift`` from their input grasp) are left alone."""

    def __init__(self, gs: GoalSet, robot):
        self.robot = robot
        self.initial_goals = np.array(gs.goals)  # the IK goal set as built, before any refinement
        self.goals = list(gs.goals)
        self.tails = list(gs.tails)
        self.origin = list(gs.grasp_index)         # input grasp of each goal
        self.origin_goal = list(range(len(gs)))    # goal-set goal each goal came from (refined copies: their source)
        self.refined_copy: dict = {}               # goal index -> index of its refined copy
        self.stalled: set = set()                  # goals ISF leaves alone
        self.grasp_hand: dict = {}                 # hand position at an input goal, made when ISF first refines it
        self.tail_length = gs.tails.shape[1]

    def __len__(self) -> int:
        return len(self.goals)

    def on_goal(self, xi, g: int) -> bool:
        """The tail sits on goal g's tail (after a projection step: to round-off)."""
        # np.allclose(rtol=0, atol=1e-9) without its ~0.1 ms of overhead; NaN is never on a goal.
        return bool(np.abs(xi[-self.tail_length:] - self.tails[g]).max() <= 1e-9)

    def is_refined(self, g: int) -> bool:
        return g in self.refined_copy.values()

    def refine(self, g: int, refiner, steps: int, max_shift: float) -> Tuple[int, bool]:
        """ISF steps on goal g; returns the goal to follow (g or its refined copy) and whether that
        copy is new (a selection policy then grows by one goal)."""
        q_ref, _ = refiner.refine(self.goals[g], steps)
        hand_link = self.robot.hand_link
        source = self.origin_goal[g]
        if source not in self.grasp_hand:
            self.grasp_hand[source] = self.robot.link_pose(self.goals[source], hand_link)[:3, 3]
        shift = np.linalg.norm(self.robot.link_pose(q_ref, hand_link)[:3, 3] - self.grasp_hand[source])
        if np.abs(q_ref - self.goals[g]).max() == 0 or shift > max_shift:
            self.stalled.add(g)  # deterministic: refine would give the same again
            return g, False
        shifted = self.tails[g] + (q_ref - self.goals[g])  # keep the approach's shape
        if self.is_refined(g):  # already a refined goal: update in place
            self.goals[g], self.tails[g] = q_ref, shifted
            return g, False
        if g in self.refined_copy:
            k = self.refined_copy[g]
            self.goals[k], self.tails[k] = q_ref, shifted
            return k, False
        self.goals.append(q_ref)
        self.tails.append(shifted)
        self.origin.append(self.origin[g])
        self.origin_goal.append(g)
        self.refined_copy[g] = len(self.goals) - 1
        return len(self.goals) - 1, True


class _Optimization:
    """The loop of Algorithm 2 over a non-empty goal set; ``timings`` accumulates its phases."""

    def __init__(self, settings: OMGSettings, world: World, q0: np.ndarray, book: GoalBook, timings: dict):
        s = self.settings = settings
        self.world, self.q0, self.book, self.timings = world, q0, book, timings
        m = book.tail_length
        # The standoff approach (the last m waypoints) carries no obstacle cost, so the transit before it
        # may keep away from the target too: the arm does not sweep through the object it will grasp.
        avoid = m > 0 and s.transit_avoids_target
        self.chomp = world.chomp(replace(s.chomp, obstacle_tail=m), avoid_target=avoid)
        self.metric_settings = replace(s.metrics, tail_waypoints=m)
        self.ws = self.chomp.workspace() if s.loop is PlanLoop.python else None  # the native loop has its own
        self.refiner = world.grasp_refiner(s.isf, s.seed) if s.refine else None
        self.policy = make_policy(s.selection)

    def estimates(self, xi, i: int) -> np.ndarray:
        """Normalized cost of each goal for the trajectory xi at iteration i."""
        s, goals = self.settings, np.array(self.book.goals)
        if self.policy.cost_kind is CostKind.distance:  # Proj: distance of the free end point to each goal
            _, grad = self.chomp.problem.objective(xi, self.q0, i)
            free_end = xi[-1] - s.chomp.step_size * self.chomp.problem.solve_A(grad)[-1]
            c = np.linalg.norm(goals - free_end, axis=1)
        else:
            c = self.chomp.problem.goal_costs(xi, self.q0, i, s.iterations, goals, s.cost_time_stride,
                                              s.cost_point_stride, self.ws)
        norm = np.linalg.norm(c)
        return c / norm if norm > 0 else c

    def _timed(self, phase: str, fn, *args):
        clock = _clock(self.settings)
        t = clock()
        out = fn(*args)
        self.timings[phase] += clock() - t
        return out

    def _select(self, c) -> Tuple[int, np.ndarray]:
        """The policy's update and its choice: (goal, p)."""
        p = self.policy.update(c)
        return self.policy.select(), p

    def _refine(self, g: int) -> int:
        g, added = self.book.refine(g, self.refiner, self.settings.isf_steps, self.settings.isf_max_shift)
        if added:
            self.policy.add_goal()
        return g

    def _succeeds(self, xi, g: int, iterations: int):
        """The trajectory that would be returned (its tail on goal g) and its metrics when it succeeds."""
        book, q0 = self.book, self.q0
        cand = xi if book.on_goal(xi, g) else self.chomp.step(xi.copy(), q0, book.tails[g], iterations, self.ws)[0]
        metrics = self.chomp.metrics(cand, q0, self.metric_settings)
        return (cand, metrics) if metrics["success"] else (None, None)

    def run(self) -> PlanResult:
        s, book, q0, chomp, ws = self.settings, self.book, self.q0, self.chomp, self.ws
        xi = cubic_initialization(q0, book.goals[0], s.chomp.n)
        c0 = self._timed("costs", self.estimates, xi, 0)
        self.policy.reset(len(book), s.iterations, c0)
        g = int(np.argmin(c0))  # the initial goal: best by the initial estimate (as Fixed)
        xi = cubic_initialization(q0, book.goals[g], s.chomp.n)
        xi[-book.tail_length:] = book.tails[g]
        history = {"objective": [], "goal": [], "p": [], "costs": [], "switches": 0,
                   "initial_grasp": int(book.origin[g])}
        iterations, metrics = 0, None
        for i in range(s.iterations):
            iterations = i + 1
            xi, info = self._timed("chomp", chomp.step, xi, q0, book.tails[g], i, ws)
            history["objective"].append(info["before"]["total"])
            c = self._timed("costs", self.estimates, xi, i + 1)
            history["costs"].append(c)
            g_next, p = self._timed("selection", self._select, c)
            if self.refiner is not None and g_next not in book.stalled:
                g_next = self._timed("isf", self._refine, g_next)
            history["switches"] += int(g_next != g)
            history["goal"].append(g_next)
            history["p"].append(p.copy())
            # On a switch the tail is left where it is: the next CHOMP-Proj step's offset term
            # (eq. 7, -A^-1 C^T (C A^-1 C^T)^-1 b) moves the whole trajectory smoothly onto the new
            # goal; overwriting the tail instead would leave a jump before it for CHOMP to undo.
            g = g_next
            if s.pre_terminate and iterations >= s.min_iterations and iterations % s.check_every == 0:
                cand, metrics = self._timed("metrics", self._succeeds, xi, g, iterations)
                if cand is not None:
                    xi = cand
                    break
        if not book.on_goal(xi, g):  # the last selection (a switch or a refined goal): project onto it
            xi, _ = chomp.step(xi, q0, book.tails[g], iterations, ws)
        return self._result(xi, g, iterations, metrics, history)

    def run_native(self) -> PlanResult:
        """The same loop as ``run``, in C++ (``native_loop``), with the GIL released."""
        book = self.book
        out = run_native(self.chomp, self.refiner, self.world.robot, self.q0, book, self.settings, self.policy,
                         self.metric_settings)
        for phase, seconds in out["seconds"].items():
            self.timings[phase] += seconds
        history = {"objective": list(out["objective"]), "goal": list(out["goals_chosen"]), "p": out["p"],
                   "costs": out["costs"], "switches": out["switches"], "initial_grasp": out["initial_grasp"]}
        xi, robot = out["xi"], self.world.robot
        return PlanResult(PlanStatus.of(out["metrics"]), np.vstack([self.q0, xi]), xi[-1].copy(), out["grasp_index"],
                          robot.link_pose(xi[-1], robot.hand_link), out["refined"], out["metrics"], out["grasp_cost"],
                          out["goal_set_size"], out["iterations"], history, self.timings,
                          goal_set=book.initial_goals.copy(), goal_source=out["goal_source"])

    def _result(self, xi, g: int, iterations: int, metrics: Optional[dict], history: dict) -> PlanResult:
        clock = _clock(self.settings)
        t = clock()
        if metrics is None:
            metrics = self.chomp.metrics(xi, self.q0, self.metric_settings)
        refiner = self.refiner
        grasp_cost = float(refiner.cost(xi[-1])[0]["total"]) if refiner is not None else float("nan")
        self.timings["metrics"] += clock() - t
        robot = self.world.robot
        return PlanResult(PlanStatus.of(metrics), np.vstack([self.q0, xi]), xi[-1].copy(), int(self.book.origin[g]),
                          robot.link_pose(xi[-1], robot.hand_link), self.book.is_refined(g), metrics, grasp_cost,
                          len(self.book), iterations, history, self.timings,
                          goal_set=self.book.initial_goals.copy(), goal_source=int(self.book.origin_goal[g]))
