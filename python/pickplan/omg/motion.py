"""Motion planning to joint-space goals among obstacles (shelves, bins, MoveIt scenes): a straight
line when it is free, else RRT-Connect (native, to the whole goal set) shortened by shortcuts, then
CHOMP smooths it (the sampling-based path is CHOMP's initialization, where a straight line is none);
every candidate passes the motion check before it is returned: each segment proved free by
conservative advancement (FCL distances; from a state with clearance d the next is where no robot point
can have moved d), or, ``certified=False``, sampled so that no point moves more than ``resolution``
between checked states (which lets a finger graze an obstacle between samples).

>>> world = MotionWorld(robot, obstacles, allowed_pairs=srdf_pairs)
>>> result = plan_motion(world, q_start, q_goals, MotionSettings())
>>> result.status, result.path          # (k, dof) joint waypoints, start first
>>> plan_motion(world, q_start, PoseGoal(T_hand, free_axis=Axis.z))   # a pose goal: IK's goal set
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import Optional, Sequence, Tuple, Union

import numpy as np

from pickplan import _core
from pickplan.core import collision, sdf
from pickplan.core.robots import Robot
from pickplan.core.settings import Option, to_native
from pickplan.core.shapes import Obstacle, add_to_sdf
from pickplan.omg.chomp import Chomp, ChompSettings
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.pose_goal import PoseGoal, pose_goal_configurations


class MotionStatus(Option):
    solved = "solved"
    invalid_start = "invalid_start"  # the start collides
    invalid_goals = "invalid_goals"  # every goal collides
    unreachable = "unreachable"  # a pose goal without an IK solution
    not_found = "not_found"  # no path within the time and sample budget


class Smoothing(Option):
    """What becomes of a found path."""

    none = "none"  # the shortcut path as it is
    chomp = "chomp"  # CHOMP from it, kept when it passes the motion check


@dataclass(frozen=True)
class RrtSettings:
    """Mirror of the native ``RrtSettings``."""

    range: float = 0.5  # rad: largest extension
    resolution: float = 0.01  # m: largest motion of a robot point between sampled states (not certified)
    max_iterations: int = 200000
    time_limit: float = 1.0  # s
    seed: int = 0
    goal_bias: float = 0.05
    certified: bool = True  # prove each segment free (conservative advancement), not sample it

    def to_native(self, active=None) -> "_core.RrtSettings":
        return to_native(self, _core.RrtSettings, active=[] if active is None else [bool(a) for a in active])


@dataclass(frozen=True)
class MotionSettings:
    rrt: RrtSettings = field(default_factory=RrtSettings)
    shortcut_attempts: int = 100  # random shortcuts of an RRT path
    shortcut_min_gain: float = 0.01  # a shortcut gaining less than this fraction of the path's length is not checked
    smoothing: Smoothing = Smoothing.chomp
    chomp: ChompSettings = field(default_factory=lambda: ChompSettings(n=30, epsilon=0.05))
    chomp_iterations: int = 30
    straight_first: bool = True  # try the straight line to each goal before sampling
    attempts: int = 3  # RRT-Connect runs (new seeds) before "not_found"

    def __post_init__(self):
        object.__setattr__(self, "smoothing", Smoothing.parse(self.smoothing, "smoothing"))


@dataclass
class MotionResult:
    status: MotionStatus
    path: np.ndarray  # (k, dof) waypoints, the start first (empty rows when not solved)
    goal: int  # row of the goal set reached (-1: none)
    source: str  # "straight", "rrt" (shortcut) or "chomp" (smoothed)
    timings: dict  # seconds: check (ends), straight, rrt, shortcut, chomp, total
    stats: dict = field(default_factory=dict)  # rrt iterations, checks, attempts
    goals: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (G, dof) the goal set planned to

    @property
    def solved(self) -> bool:
        return self.status is MotionStatus.solved


class MotionWorld:
    """A robot among obstacles for motion planning: the FCL checker (robot vs obstacles, and the
    robot against itself unless a pair is allowed), the scene SDF (primitives in closed form),
    body points, CHOMP problems and the native motion planner. ``robot``: any URDF ``Robot``."""

    def __init__(
        self,
        robot: Robot,
        obstacles: Sequence[Obstacle],
        allowed_pairs: Sequence[Tuple[str, str]] = (),
        self_collision: bool = True,
        body_points_per_link: int = 20,
        body_seed: int = 0,
        cache: Optional[ModelCache] = None,
        sdf_settings: sdf.SdfSettings = sdf.SdfSettings(),
    ):
        self.robot, self.obstacles = robot, list(obstacles)
        self.cache = cache = ModelCache() if cache is None else cache
        links = set(robot.link_names)
        names = {o.name for o in self.obstacles}
        # Pairs naming something absent (an ACM entry for an object of another scene) are moot.
        pairs = tuple((a, b) for a, b in allowed_pairs if a in links and (b in links or b in names))
        settings = collision.CollisionSettings(allowed_pairs=pairs, self_collision=self_collision)
        # The links as their convex hulls (FCL's convex solids): conservative, and a GJK query per pair.
        self.checker = collision.CollisionChecker(
            robot,
            [collision.SceneMesh(o.name, o.shape, o.pose) for o in self.obstacles],
            None,
            settings,
            convex_links=True,
            shapes=cache.shapes,
            link_meshes=cache.link_meshes(robot),
        )
        self.sdf = sdf.SceneSdf()
        add_to_sdf(self.sdf, self.obstacles, sdf_settings, cache.grids)
        # Primitives answer in closed form, cheaper than filling a merged grid; meshes gain from one.
        if any(not o.shape.primitive for o in self.obstacles) and sdf_settings.merged:
            self.sdf.merge(resolution=sdf_settings.merged_resolution, cutoff=sdf_settings.merged_cutoff)
        self.body = cache.body_points(robot, body_points_per_link, body_seed)
        # A described robot's fingers keep the start's opening; a bare URDF's joints all move.
        info = getattr(robot, "info", None)
        self.active = [info is None or i < info.arm_dof for i in range(robot.dof)]
        self._chomps: dict = {}
        self._planners: dict = {}

    def chomp(self, settings: ChompSettings) -> Chomp:
        if settings not in self._chomps:
            self._chomps[settings] = Chomp(self.robot, self.sdf, self.body, settings, active=self.active)
        return self._chomps[settings]

    def planner(self, settings: RrtSettings) -> "_core.MotionPlanner":
        if settings not in self._planners:
            self._planners[settings] = _core.MotionPlanner(self.checker.native, settings.to_native(self.active))
        return self._planners[settings]

    def valid(self, path: np.ndarray, resolution: float, certified: bool = True) -> bool:
        """The path's segments proved free (``certified``), or free at states at most ``resolution`` m of
        robot motion apart."""
        planner = self.planner(RrtSettings(resolution=resolution, certified=certified))
        return planner.first_invalid_segment(np.asarray(path, dtype=float)) < 0


def path_length(path: np.ndarray) -> float:
    """Joint-space length of the polyline (rad, Euclidean)."""
    P = np.asarray(path, dtype=float)
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()) if len(P) > 1 else 0.0


def resample(path: np.ndarray, count: int) -> np.ndarray:
    """``count`` points at equal joint-space arc length along the polyline, its ends included."""
    P = np.asarray(path, dtype=float)
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    if s[-1] <= 0:
        return np.repeat(P[:1], count, axis=0)
    t = np.linspace(0.0, s[-1], count)
    return np.stack([np.interp(t, s, P[:, j]) for j in range(P.shape[1])], axis=1)


def plan_motion(
    world: MotionWorld, start, goals: Union[np.ndarray, PoseGoal], settings: MotionSettings = MotionSettings()
) -> MotionResult:
    """A collision-free joint path from ``start`` to one row of ``goals`` ((G, dof), or one (dof,)),
    or to a ``PoseGoal`` (its IK solutions are the goal set; ``result.goal`` indexes ``result.goals``)."""
    t_total = time.perf_counter()
    robot = world.robot
    q0 = robot.check_within_limits(start, "start")
    timings = dict.fromkeys(("ik", "check", "straight", "rrt", "shortcut", "chomp"), 0.0)
    if isinstance(goals, PoseGoal):
        t = time.perf_counter()
        goals = pose_goal_configurations(robot, world.active, q0, goals)
        timings["ik"] = time.perf_counter() - t
    G = np.atleast_2d(np.asarray(goals, dtype=float))
    for g in G:
        robot.check_within_limits(g, "goal")
    stats = {"attempts": 0, "iterations": 0, "checks": 0}

    def done(status, path, goal, source):
        timings["total"] = time.perf_counter() - t_total
        return MotionResult(
            status,
            np.asarray(path, dtype=float).reshape(-1, robot.dof),
            goal,
            source,
            timings,
            stats,
            G.reshape(-1, robot.dof),
        )

    if G.size == 0:
        return done(MotionStatus.unreachable, np.zeros((0, robot.dof)), -1, "")

    t = time.perf_counter()
    checker = world.checker.native
    if checker.in_collision(q0):
        timings["check"] = time.perf_counter() - t
        return done(MotionStatus.invalid_start, np.zeros((0, robot.dof)), -1, "")
    free = [i for i, g in enumerate(G) if not checker.in_collision(g)]
    timings["check"] = time.perf_counter() - t
    if not free:
        return done(MotionStatus.invalid_goals, np.zeros((0, robot.dof)), -1, "")
    rrt = settings.rrt
    planner = world.planner(rrt)
    if settings.straight_first:
        t = time.perf_counter()
        for i in sorted(free, key=lambda i: np.linalg.norm(G[i] - q0)):
            if planner.first_invalid_segment(np.stack([q0, G[i]])) < 0:
                timings["straight"] = time.perf_counter() - t
                return done(MotionStatus.solved, np.stack([q0, G[i]]), i, "straight")
        timings["straight"] = time.perf_counter() - t
    path, goal = None, -1
    for attempt in range(settings.attempts):
        stats["attempts"] = attempt + 1
        t = time.perf_counter()
        out = (
            planner.rrt_connect(q0, G[free])
            if attempt == 0
            else world.planner(replace(rrt, seed=rrt.seed + attempt)).rrt_connect(q0, G[free])
        )
        timings["rrt"] += time.perf_counter() - t
        stats["iterations"] += int(out.iterations)
        stats["checks"] += int(out.checks)
        if out.status == _core.RrtStatus.solved:
            path, goal = np.asarray(out.path), free[int(out.goal)]
            break
    if path is None:
        return done(MotionStatus.not_found, np.zeros((0, robot.dof)), -1, "")
    t = time.perf_counter()
    path = planner.shortcut(path, settings.shortcut_attempts, rrt.seed, settings.shortcut_min_gain)
    timings["shortcut"] = time.perf_counter() - t
    if settings.smoothing is Smoothing.chomp and len(path) > 2:
        t = time.perf_counter()
        smooth = smooth_path(world, path, settings)
        timings["chomp"] = time.perf_counter() - t
        if smooth is not None:
            return done(MotionStatus.solved, smooth, goal, "chomp")
    return done(MotionStatus.solved, path, goal, "rrt")


def smooth_path(world: MotionWorld, path: np.ndarray, settings: MotionSettings) -> Optional[np.ndarray]:
    """CHOMP from ``path`` (resampled to its n waypoints) with the end fixed; the result (start first)
    when it passes the motion check, else None."""
    chomp = world.chomp(settings.chomp)
    n = settings.chomp.n
    xi0 = resample(path, n + 1)[1:]
    out = chomp.optimize(path[0], path[-1], settings.chomp_iterations, xi0=xi0, metric_settings=None)
    smooth = np.vstack([path[:1], out.xi])
    return smooth if world.valid(smooth, settings.rrt.resolution, settings.rrt.certified) else None


def plan_chomp(
    world: MotionWorld,
    start,
    goal,
    settings: MotionSettings = MotionSettings(),
    initializations: int = 1,
    seed: int = 0,
) -> MotionResult:
    """CHOMP alone (no sampling): from the straight line to ``goal``, then, while none passes the motion
    check, from ``initializations - 1`` more paths through a random configuration (seeded); the first
    that passes is returned. What CHOMP does without a sampling-based seed (the ablation of ``plan_motion``)."""
    t_total = time.perf_counter()
    robot = world.robot
    q0 = robot.check_within_limits(start, "start")
    g = robot.check_within_limits(goal, "goal")
    rng = np.random.default_rng(seed)
    chomp, n = world.chomp(settings.chomp), settings.chomp.n
    timings = {"chomp": 0.0}
    for k in range(max(1, int(initializations))):
        via = [] if k == 0 else [rng.uniform(robot.lower_limits, robot.upper_limits)]
        xi0 = resample(np.vstack([q0] + via + [g]), n + 1)[1:]
        out = chomp.optimize(q0, g, settings.chomp_iterations, xi0=xi0, metric_settings=None)
        path = np.vstack([q0[None], out.xi])
        if world.valid(path, settings.rrt.resolution, settings.rrt.certified):
            timings["total"] = time.perf_counter() - t_total
            return MotionResult(MotionStatus.solved, path, 0, "chomp", timings, {"initializations": k + 1})
    timings["total"] = time.perf_counter() - t_total
    return MotionResult(
        MotionStatus.not_found, np.zeros((0, robot.dof)), -1, "", timings, {"initializations": int(initializations)}
    )
