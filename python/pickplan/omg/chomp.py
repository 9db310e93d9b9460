"""CHOMP and CHOMP-Proj (OMG paper Sec. III-A..C), native, with the paper's defaults.

>>> chomp = Chomp(robot, scene_sdf, body, ChompSettings(), exclude=("target",))
>>> result = chomp.optimize(q0, goal, iterations=100)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Union

import numpy as np

from pickplan import _core
from pickplan.core import collision
from pickplan.core.settings import Option, native_defaults, to_native
from pickplan.core.robots import BodyPoints, Robot
from pickplan.core.sdf import SceneSdf


@dataclass(frozen=True)
@native_defaults(_core.ChompSettings)
class ChompSettings:
    """Mirrors the native ``ChompSettings``; defaults are the paper's (Sec. IV-B)."""

    n: int  # waypoints after the fixed start
    duration: float  # dt = duration / n = 0.1 s at n = 30
    lambda_: float  # smoothness weight lambda (eq. 2)
    lambda_growth: float  # lambda_i = lambda * growth**i
    step_size: float  # 1 / eta_motion (eq. 6)
    epsilon: float  # obstacle padding (m)
    top_k: int  # largest obstacle terms that contribute (0 = all)
    clip_gradient: float  # element-wise clip of the obstacle gradient (0 = none)
    joint_limit_steps: int
    obstacle_tail: int  # last waypoints without obstacle cost (standoff approach)
    link_culling: bool  # skip links whose bounding sphere is beyond epsilon (exact, faster)

    def to_native(self, exclude_mask: int = 0, active: Optional[Sequence[bool]] = None) -> "_core.ChompSettings":
        return to_native(
            self,
            _core.ChompSettings,
            exclude_mask=int(exclude_mask),
            active=[] if active is None else [bool(a) for a in active],
        )


@dataclass(frozen=True)
@native_defaults(_core.MetricSettings)
class MetricSettings:
    """The paper's metrics (Sec. IV-A): dense interpolation to 200 steps, 5 cm padding."""

    steps: int
    collision_padding: float
    epsilon: float
    clearance: float
    table_clearance: float
    tail_waypoints: int  # last waypoints (standoff approach) held to tail_clearance only
    tail_clearance: float
    smoothness_threshold: float
    # The transit (before the tail) keeps this from the target (the metrics' excluded objects); -inf: not
    # measured (the paper's test). The planner asks for it among furniture (OMGPlanner, LoopInputs).
    transit_target_clearance: float
    # The finger links may reach this far into the table (fingertips resting on it), as the goal set
    # lets them: None = the robot's finger links (bit = link index) and the gripper's default
    # tolerance (core.collision.SupportContact); Chomp.metrics resolves them.
    support_link_mask: Optional[int] = None
    support_tolerance: Optional[float] = None

    def to_native(
        self, exclude_mask: int = 0, support_link_mask: int = 0, support_tolerance: float = 0.0
    ) -> "_core.MetricSettings":
        return to_native(
            self,
            _core.MetricSettings,
            exclude_mask=int(exclude_mask),
            support_link_mask=int(support_link_mask),
            support_tolerance=float(support_tolerance),
        )


class ChompStatus(Option):
    """How a CHOMP run ended (the native ``ChompStatus``); bad input raises instead."""

    ok = "ok"


@dataclass
class ChompResult:
    xi: np.ndarray  # (n, dof) waypoints after the start
    objective: list  # f_motion before each iteration
    final: "_core.ObjectiveTerms"  # obstacle, prior, total, colliding_points at the end
    iterations: int
    status: ChompStatus
    seconds: float
    metrics: Optional["_core.TrajectoryMetrics"] = None  # when optimize was given metric settings


class Initialization(Option):
    """The initial trajectory from the start to a goal."""

    cubic = "cubic"  # zero end velocities (the paper's)
    linear = "linear"


def cubic_blend(n: int) -> np.ndarray:
    """The cubic's fraction of the way from q0 to the goal at t = 1/n .. 1 (zero end velocities)."""
    s = np.arange(1, n + 1) / n
    return 3 * s**2 - 2 * s**3


def cubic_initialization(q0: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
    """Cubic spline from q0 to goal with zero end velocities, sampled at t = 1/n .. 1 (paper Sec. IV)."""
    return np.asarray(q0)[None, :] + cubic_blend(n)[:, None] * (np.asarray(goal) - np.asarray(q0))[None, :]


def linear_initialization(q0: np.ndarray, goal: np.ndarray, n: int) -> np.ndarray:
    s = np.arange(1, n + 1) / n
    return np.asarray(q0)[None, :] + s[:, None] * (np.asarray(goal) - np.asarray(q0))[None, :]


class Chomp:
    """A CHOMP problem: robot + scene SDF + body points + settings.

    ``exclude`` names SDF objects the obstacle cost and the metrics ignore (the grasp target);
    ``obstacle_exclude``, when given, replaces it for the obstacle cost only; ``active``
    marks the joints the optimizer moves (default: all; for the Panda, the 7 arm joints).
    """

    def __init__(
        self,
        robot: Robot,
        scene: SceneSdf,
        body: BodyPoints,
        settings: ChompSettings = ChompSettings(),
        exclude: Sequence[str] = (),
        active: Optional[Sequence[bool]] = None,
        obstacle_exclude: Optional[Sequence[str]] = None,
    ):
        self.robot, self.scene, self.body, self.settings = robot, scene, body, settings
        self.exclude_mask = sum(1 << scene.index(name) for name in exclude)
        # the optimizer's obstacle cost may leave out fewer objects than the metrics (default: the same)
        obstacle_mask = (
            self.exclude_mask if obstacle_exclude is None else sum(1 << scene.index(name) for name in obstacle_exclude)
        )
        if active is None and hasattr(robot, "info"):
            active = [i < robot.info.arm_dof for i in range(robot.dof)]
        self.active = None if active is None else list(active)
        self.problem = _core.ChompProblem(
            robot.native, scene.native, body.links, body.points, settings.to_native(obstacle_mask, self.active)
        )
        self._native_metrics: dict = {}  # (MetricSettings, extra exclusion) -> its native struct (native_metric_settings)

    @property
    def dt(self) -> float:
        return self.problem.dt

    def initial_trajectory(self, q0, goal, kind: Union[Initialization, str] = Initialization.cubic) -> np.ndarray:
        kind = Initialization.parse(kind, "initialization")
        if kind is Initialization.cubic:
            return cubic_initialization(q0, goal, self.settings.n)
        return linear_initialization(q0, goal, self.settings.n)

    def workspace(self):
        return self.problem.workspace()

    def step(self, xi, q0, goal=None, iteration: int = 0, workspace=None):
        """One CHOMP-Proj step toward ``goal`` ((dof,) or a (m, dof) standoff tail); returns (xi, info)."""
        return self.problem.step(xi, q0, goal, iteration, workspace)

    def objective(self, xi, q0, iteration: int = 0):
        return self.problem.objective(xi, q0, iteration)

    def optimize(
        self,
        q0,
        goal,
        iterations: int = 100,
        xi0: Optional[np.ndarray] = None,
        metric_settings: Optional[MetricSettings] = MetricSettings(),
    ) -> ChompResult:
        """Plain CHOMP toward a fixed goal (or standoff tail) from ``xi0`` (default: cubic)."""
        goal = np.asarray(goal, dtype=float)
        final_goal = goal if goal.ndim == 1 else goal[-1]
        xi0 = self.initial_trajectory(q0, final_goal) if xi0 is None else xi0
        if goal.ndim == 2:  # put the initial tail on the standoff chain
            xi0 = np.array(xi0, dtype=float)
            xi0[-len(goal) :] = goal
        out = self.problem.optimize(xi0, q0, goal, iterations)
        result = ChompResult(
            out.xi,
            list(out.objective),
            out.final_terms,
            out.iterations,
            ChompStatus.from_native(out.status),
            out.seconds,
        )
        if metric_settings is not None:
            result.metrics = self.metrics(result.xi, q0, metric_settings)
        return result

    def metrics(self, xi, q0, settings: MetricSettings = MetricSettings()) -> "_core.TrajectoryMetrics":
        return self.problem.metrics(xi, q0, self.native_metric_settings(settings))

    def native_metric_settings(
        self, settings: MetricSettings = MetricSettings(), extra_exclude: int = 0
    ) -> "_core.MetricSettings":
        """``settings`` resolved for this robot and scene (support links and tolerance, excluded objects,
        with the SDF objects of the ``extra_exclude`` bits left out besides: the furniture a caller checks
        exactly), converted once per settings value and kept (every plan's success test reads them; the
        native struct is shared: read it, do not modify it)."""
        key = (settings, int(extra_exclude))
        cached = self._native_metrics.get(key)
        if cached is None:
            cached = self._native_metrics[key] = self._resolve_metric_settings(settings, int(extra_exclude))
        return cached

    def _resolve_metric_settings(self, settings: MetricSettings, extra_exclude: int = 0) -> "_core.MetricSettings":
        fingers = getattr(self.robot, "finger_links", ())
        mask = settings.support_link_mask
        if mask is None:
            mask = sum(1 << self.robot.link_index(f) for f in fingers)
        tolerance = collision.SupportContact(settings.support_tolerance).resolved(self.robot) if mask else 0.0
        return settings.to_native(self.exclude_mask | extra_exclude, mask, tolerance)
