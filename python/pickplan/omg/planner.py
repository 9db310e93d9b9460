"""The OMG planner (Algorithm 2): CHOMP-Proj steps, online goal selection over the goal set and
C-Space ISF refinement of the selected goal, for N iterations with pre-termination.

>>> planner = OMGPlanner(None, scene, OMGSettings())
>>> result = planner.plan()                # start and target from the scene, its default grasps
>>> result.status, result.metrics["smoothness"]
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Optional, Union

import numpy as np

from pickplan.omg import grasps as grasps_mod
from pickplan.omg.chomp import Chomp, ChompSettings, MetricSettings, cubic_initialization
from pickplan.omg.goals import GoalSetSettings, IkSettings, build_goal_set
from pickplan.omg.isf import IsfSettings
from pickplan.sim.scenes import Scene
from pickplan.omg.selection import make_policy
from pickplan.omg.world import World, WorldSettings


@dataclass(frozen=True)
class OMGSettings:
    """The planner's settings; defaults are the paper's (Sec. IV-B)."""

    chomp: ChompSettings = field(default_factory=ChompSettings)
    goals: GoalSetSettings = field(default_factory=GoalSetSettings)
    ik: IkSettings = field(default_factory=IkSettings)
    isf: IsfSettings = field(default_factory=IsfSettings)
    metrics: MetricSettings = field(default_factory=MetricSettings)
    world: WorldSettings = field(default_factory=WorldSettings)
    selection: str = "MD"          # Fixed | Proj | FTC | FTL | EXP | MD
    iterations: int = 50           # N, the optimization horizon
    refine: bool = True            # C-Space ISF on the selected goal every iteration
    isf_steps: int = 1             # ISF steps per planner iteration
    isf_max_shift: float = 0.01    # m: ISF may move the hand at most this far from the input grasp (a
                                   # local refinement; verified grasps moved farther were dropped in execution)
    cost_time_stride: int = 2      # goal-cost estimates on every k-th tail waypoint ...
    cost_point_stride: int = 2     # ... and every k-th body point (rescaled)
    pre_terminate: bool = True     # stop once the plan succeeds (checked every check_every iterations)
    min_iterations: int = 10
    check_every: int = 5
    grasp_kind: str = "simulated"  # default grasps when plan() gets none: stored set, else generated
    grasp_count: int = 100
    seed: int = 0

    def __post_init__(self):
        for name, low in (("iterations", 1), ("check_every", 1), ("min_iterations", 0), ("isf_steps", 0),
                          ("cost_time_stride", 1), ("cost_point_stride", 1), ("grasp_count", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low:
                raise ValueError(f"OMGSettings.{name}: expected an integer >= {low}, got {value!r}")


@dataclass
class PlanResult:
    status: str                    # "success", "in_collision", "not_smooth", "no_goals"
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

    @property
    def success(self) -> bool:
        return self.status == "success"


class OMGPlanner:
    """Joint motion and grasp planning for one scene (``robot`` None: the scene's Panda)."""

    def __init__(self, robot, scene: Scene, settings: OMGSettings = OMGSettings(),
                 world: Optional[World] = None):
        self.settings = settings
        self.scene = scene
        self._world = world
        if robot is not None and world is None and not hasattr(robot, "info"):
            raise ValueError("OMGPlanner currently plans for the Panda (robots.panda()); got another robot")

    def world(self, target: Optional[str] = None) -> World:
        target = target or self.scene.target
        if self._world is None or self._world.target != target:
            scene = self.scene if target == self.scene.target else replace(self.scene, target=target)
            self._world = World(scene, self.settings.world)
        return self._world

    def default_grasps(self, world: World) -> np.ndarray:
        s = self.settings
        return grasps_mod.grasp_set(world.target_model, s.grasp_kind, s.grasp_count, seed=s.seed).poses

    def plan(self, start: Optional[np.ndarray] = None, target: Optional[str] = None,
             grasps: Optional[Union[np.ndarray, str]] = None) -> PlanResult:
        s = self.settings
        t = time.perf_counter()
        world = self.world(target)
        q0 = world.robot.check_within_limits(world.start if start is None else start, "start")
        if grasps is None:
            grasps = self.default_grasps(world)
        elif isinstance(grasps, str):
            grasps = grasps_mod.grasp_set(world.target_model, grasps, s.grasp_count, seed=s.seed).poses
        world.checker("goal"), world.checker("hand")  # FCL models: built once per scene, cached
        if s.refine:
            world.grasp_refiner(s.isf, s.seed)  # hand SDF, object samples: cached likewise
        # Scene preparation (SDFs, FCL models, grasp generation) is not planning: timed apart.
        timings = dict.fromkeys(("goal_set", "chomp", "costs", "selection", "isf", "metrics"), 0.0)
        timings["prepare"] = time.perf_counter() - t
        t_total = time.perf_counter()

        t = time.perf_counter()
        gs = build_goal_set(world, grasps, q0, s.goals, s.ik)
        timings["goal_set"] = time.perf_counter() - t
        if len(gs) == 0:
            timings["total"] = time.perf_counter() - t_total
            empty = np.zeros((0, world.robot.dof))
            return PlanResult("no_goals", np.vstack([q0]), q0, -1, np.eye(4), False, {}, float("nan"), 0, 0,
                              {"objective": [], "goal": [], "p": [], "costs": [], "switches": 0, "initial_grasp": -1}, timings, gs.reason_counts())

        m = gs.tails.shape[1]
        chomp = Chomp(world.robot, world.sdf, world.body, replace(s.chomp, obstacle_tail=m), exclude=(world.target,))
        metric_settings = replace(s.metrics, tail_waypoints=m)
        ws = chomp.workspace()
        goals = [g for g in gs.goals]
        tails = [t_ for t_ in gs.tails]
        origin = list(gs.grasp_index)          # input grasp of each goal
        origin_goal = list(range(len(gs)))     # goal-set goal each goal came from (refined copies: their source)
        refined_copy: dict = {}                # goal index -> index of its refined copy
        refiner = world.grasp_refiner(s.isf, s.seed) if s.refine else None
        isf_stalled: set = set()               # goals ISF leaves alone: no decrease found, or at its trust radius
        hand_link = world.robot.hand_link
        grasp_hand: dict = {}                  # hand position at an input goal, made when ISF first refines it
        policy = make_policy(s.selection)
        N = s.iterations

        def on_goal(xi, g):  # the tail sits on goal g's tail (after a projection step: to round-off)
            return np.allclose(xi[-m:], tails[g], rtol=0.0, atol=1e-9)

        def estimates(xi, i):
            if policy.cost_kind == "distance":  # Proj: distance of the free end point to each goal
                _, grad = chomp.problem.objective(xi, q0, i)
                free_end = xi[-1] - s.chomp.step_size * chomp.problem.solve_A(grad)[-1]
                c = np.linalg.norm(np.array(goals) - free_end, axis=1)
            else:
                c = chomp.problem.goal_costs(xi, q0, i, N, np.array(goals), s.cost_time_stride,
                                             s.cost_point_stride, ws)
            norm = np.linalg.norm(c)
            return c / norm if norm > 0 else c

        t = time.perf_counter()
        xi = cubic_initialization(q0, goals[0], s.chomp.n)
        c0 = estimates(xi, 0)
        timings["costs"] += time.perf_counter() - t
        policy.reset(len(goals), N, c0)
        g = int(np.argmin(c0))  # the initial goal: best by the initial estimate (as Fixed)
        xi = cubic_initialization(q0, goals[g], s.chomp.n)
        xi[-m:] = tails[g]
        history = {"objective": [], "goal": [], "p": [], "costs": [], "switches": 0, "initial_grasp": int(origin[g])}
        iterations = 0
        metrics = None
        for i in range(N):
            iterations = i + 1
            t = time.perf_counter()
            xi, info = chomp.step(xi, q0, tails[g], i, ws)
            timings["chomp"] += time.perf_counter() - t
            history["objective"].append(info["before"]["total"])
            t = time.perf_counter()
            c = estimates(xi, i + 1)
            timings["costs"] += time.perf_counter() - t
            t = time.perf_counter()
            history["costs"].append(c)
            p = policy.update(c)
            g_next = policy.select()
            timings["selection"] += time.perf_counter() - t
            if refiner is not None and g_next not in isf_stalled:
                t = time.perf_counter()
                q_ref, _ = refiner.refine(goals[g_next], s.isf_steps)
                source = origin_goal[g_next]
                if source not in grasp_hand:
                    grasp_hand[source] = world.robot.link_pose(goals[source], hand_link)[:3, 3]
                shift = np.linalg.norm(world.robot.link_pose(q_ref, hand_link)[:3, 3] - grasp_hand[source])
                if np.abs(q_ref - goals[g_next]).max() == 0 or shift > s.isf_max_shift:
                    isf_stalled.add(g_next)  # deterministic: refine would give the same again
                else:
                    shifted = tails[g_next] + (q_ref - goals[g_next])  # keep the approach's shape
                    if g_next in refined_copy.values():       # already a refined goal: update in place
                        goals[g_next], tails[g_next] = q_ref, shifted
                    elif g_next in refined_copy:
                        k = refined_copy[g_next]
                        goals[k], tails[k] = q_ref, shifted
                        g_next = k
                    else:
                        goals.append(q_ref)
                        tails.append(shifted)
                        origin.append(origin[g_next])
                        origin_goal.append(g_next)
                        refined_copy[g_next] = len(goals) - 1
                        policy.add_goal()
                        g_next = len(goals) - 1
                timings["isf"] += time.perf_counter() - t
            history["switches"] += int(g_next != g)
            history["goal"].append(g_next)
            history["p"].append(p.copy())
            # On a switch the tail is left where it is: the next CHOMP-Proj step's offset term
            # (eq. 7, -A^-1 C^T (C A^-1 C^T)^-1 b) moves the whole trajectory smoothly onto the new
            # goal; overwriting the tail instead would leave a jump before it for CHOMP to undo.
            g = g_next
            if s.pre_terminate and iterations >= s.min_iterations and iterations % s.check_every == 0:
                t = time.perf_counter()
                # Judge the trajectory that would be returned: with its tail on the current goal.
                cand = xi if on_goal(xi, g) else chomp.step(xi.copy(), q0, tails[g], iterations, ws)[0]
                metrics = chomp.metrics(cand, q0, metric_settings)
                timings["metrics"] += time.perf_counter() - t
                if metrics["success"]:
                    xi = cand
                    break
                metrics = None
        if not on_goal(xi, g):  # the last selection (a switch or a refined goal): project onto it
            xi, _ = chomp.step(xi, q0, tails[g], iterations, ws)
        t = time.perf_counter()
        if metrics is None:
            metrics = chomp.metrics(xi, q0, metric_settings)
        grasp_cost = float(refiner.cost(xi[-1])[0]["total"]) if refiner is not None else float("nan")
        timings["metrics"] += time.perf_counter() - t
        timings["total"] = time.perf_counter() - t_total
        status = "success" if metrics["success"] else ("in_collision" if not metrics["collision_free"] else "not_smooth")
        hand = world.robot.link_pose(xi[-1], world.robot.hand_link)
        return PlanResult(status, np.vstack([q0, xi]), xi[-1].copy(), int(origin[g]), hand, g in refined_copy.values(),
                          metrics, grasp_cost, len(goals), iterations, history, timings, gs.reason_counts())
