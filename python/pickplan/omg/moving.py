"""Moving targets (issue 36): goals indexed by time.

A target moving at a constant, known or estimated velocity is grasped where it will be when the hand
arrives. ``MovingPlanner.plan(motion, now, start)`` predicts the target's pose at ``now + d``, ``d`` the
plan's duration as it will be executed (TOPP-RA within the robot's limits, ``time_parameterize``, from
the robot's velocity now to rest, through ``timing_waypoints``), plans there with a ``Replanner`` (warm from its last plan, or from scratch) and, when the
new plan's duration moves the arrival by more than ``arrival_tolerance``, predicts again with it
(``prediction_rounds`` in all).

The velocity comes from noisy pose observations: ``MotionEstimator`` fits position = p + v (t - t_last)
by least squares over the last ``window`` observations (``horizontal``, the default: a target on a
support, its height the observations' mean and its velocity horizontal). An observation farther than ``jump`` from the
prediction (the target was nudged) restarts the fit from it, keeping the velocity until two new
observations give one.

>>> estimator = MotionEstimator()
>>> for t, pose in observations: motion = estimator.observe(t, pose)
>>> moving = MovingPlanner(Replanner(OMGPlanner(None, scene)))
>>> plan = moving.plan(motion, now=t, start=q_now)     # plan.timed: the trajectory from now; plan.arrival
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan.core.fields import FieldReader
from pickplan.core.settings import Option
from pickplan.core.timing import Interpolation, TimedTrajectory, TimingError, time_parameterize
from pickplan.omg.planner import PlanResult, _clock
from pickplan.omg.replan import Replanner


def _finite(value, shape, name: str) -> np.ndarray:
    """A finite float array of ``shape`` (the project's input check: an ``InputError`` naming ``name``)."""
    with FieldReader() as reader:
        return reader.array(value, name, shape=shape)


@dataclass(frozen=True)
class TargetMotion:
    """A target's pose at ``time`` (s) and its constant linear velocity (m/s, world frame)."""

    pose: np.ndarray
    velocity: np.ndarray
    time: float = 0.0

    def __post_init__(self):
        pose = _finite(self.pose, (4, 4), "target motion: pose")
        if not np.allclose(pose[:3, :3] @ pose[:3, :3].T, np.eye(3), atol=1e-6) or not np.allclose(
            pose[3], [0, 0, 0, 1]
        ):
            raise ValueError("target motion: pose is not a rigid transform")
        object.__setattr__(self, "pose", pose)
        object.__setattr__(self, "velocity", _finite(self.velocity, (3,), "target motion: velocity"))
        if not math.isfinite(self.time):
            raise ValueError(f"target motion: time must be finite, got {self.time}")

    @property
    def speed(self) -> float:
        return float(np.linalg.norm(self.velocity))

    def predict(self, t: float) -> np.ndarray:
        """The pose at time ``t`` (translation along the velocity, orientation kept)."""
        pose = self.pose.copy()
        pose[:3, 3] += self.velocity * (float(t) - self.time)
        return pose


class MotionEstimator:
    """A target's motion from pose observations (see the module doc). One per target."""

    def __init__(self, window: int = 30, jump: float = 0.02, horizontal: bool = True):
        if int(window) != window or window < 2:
            raise ValueError(f"motion estimator: window must be an integer >= 2, got {window}")
        if not jump > 0:
            raise ValueError(f"motion estimator: jump must be > 0 m, got {jump}")
        self.window, self.jump, self.horizontal = int(window), float(jump), bool(horizontal)
        self._times: deque = deque(maxlen=self.window)
        self._positions: deque = deque(maxlen=self.window)
        self.motion: Optional[TargetMotion] = None
        self.jumps = 0
        self._fitted = False  # a velocity was fitted (two observations or more)

    def observe(self, t: float, pose) -> TargetMotion:
        """Adds the pose observed at time ``t`` (later than the last) and returns the motion estimated now."""
        pose = _finite(pose, (4, 4), "observation: pose")
        if not math.isfinite(t) or (self._times and t <= self._times[-1]):
            raise ValueError(
                f"observation: time must be finite and after the last ({self._times[-1] if self._times else None}), got {t}"
            )
        velocity = np.zeros(3) if self.motion is None else self.motion.velocity
        # (the jump test needs a velocity: before the first fit, a moving target is not where it was)
        if self._fitted and np.linalg.norm(pose[:3, 3] - self.motion.predict(t)[:3, 3]) > self.jump:
            self._times.clear()  # nudged: the old positions say nothing about where it is now
            self._positions.clear()
            self.jumps += 1
        self._times.append(float(t))
        self._positions.append(pose[:3, 3].copy())
        fitted = pose.copy()
        if len(self._times) >= 2:
            dt = np.asarray(self._times) - t
            A = np.column_stack([np.ones_like(dt), dt])
            (p, velocity), *_ = np.linalg.lstsq(A, np.asarray(self._positions), rcond=None)
            if self.horizontal:  # on a support: its height does not change, the noise does
                velocity[2], p[2] = 0.0, float(np.mean(np.asarray(self._positions)[:, 2]))
            fitted[:3, 3] = p
            self._fitted = True
        self.motion = TargetMotion(fitted, velocity, float(t))
        return self.motion


class ReplanMode(Option):
    """How each plan of a ``MovingPlanner`` is made."""

    warm = "warm"  # Replanner.replan: from the last plan, goals following the target
    fresh = "fresh"  # Replanner.plan: from scratch in the moved world


@dataclass(frozen=True)
class MovingSettings:
    timing_rate: float = 240.0  # Hz the plan is timed at (its duration is the arrival)
    timing_grid: int = 4  # TOPP-RA grid points per waypoint interval (time_parameterize)
    timing_spacing: float = 0.1  # rad between the waypoints timed (timing_waypoints; 0: all)
    prediction_rounds: int = 3  # plans per call at most: predict, plan, time, predict again
    arrival_tolerance: float = 0.02  # s: a plan whose arrival moved less is kept
    mode: ReplanMode = ReplanMode.warm

    def __post_init__(self):
        if not (math.isfinite(self.timing_rate) and self.timing_rate > 0):
            raise ValueError(f"moving settings: timing_rate must be > 0 Hz, got {self.timing_rate}")
        for name in ("prediction_rounds", "timing_grid"):
            if int(getattr(self, name)) != getattr(self, name) or getattr(self, name) < 1:
                raise ValueError(f"moving settings: {name} must be an integer >= 1, got {getattr(self, name)}")
        if not (self.arrival_tolerance >= 0 and self.timing_spacing >= 0):
            raise ValueError(
                f"moving settings: arrival_tolerance and timing_spacing must be >= 0, got "
                f"{self.arrival_tolerance}, {self.timing_spacing}"
            )
        object.__setattr__(self, "mode", ReplanMode.parse(self.mode, "replan mode"))


@dataclass
class MovingPlan:
    result: PlanResult
    timed: Optional[TimedTrajectory]  # from ``now``: sample k at now + k / timing_rate (None: nothing planned)
    start_time: float  # s, ``now``
    arrival: float  # s, when the timed plan ends (the hand at its goal)
    target_pose: np.ndarray  # the target's pose predicted for the arrival, that was planned to
    rounds: int  # plans made (prediction rounds)
    # s of the call on the planner's clock (OMGSettings.clock): plans and timing, the scene's preparation left out
    seconds: float
    arrival_error: float = 0.0  # m the target moves between the arrival planned for and the plan's
    planner_seconds: float = 0.0  # of ``seconds``, in the planner (PlanResult.timings' totals; the rest: timing)


def timing_waypoints(Q: np.ndarray, spacing: float, tail: int) -> np.ndarray:
    """The waypoints timed: the first, then each at least ``spacing`` (rad, joint-space arc length) on from
    the last kept, and the last ``tail`` + 1 as they are (the standoff approach). CHOMP's waypoints of a
    short replanned path lie a few mrad apart with as large wiggles, and a spline through all of them turns
    so tightly that TOPP-RA crawls along it; through these it does not, within the same polyline."""
    Q = np.asarray(Q, dtype=float)
    last = max(1, len(Q) - tail - 1)
    keep, run = [0], 0.0
    for k in range(1, last):
        run += float(np.linalg.norm(Q[k] - Q[k - 1]))
        if run >= spacing:
            keep.append(k)
            run = 0.0
    return Q[keep + list(range(last, len(Q)))]


def _timed(Q: np.ndarray, limits, s: "MovingSettings", start_velocity) -> TimedTrajectory:
    """The plan timed as executed, from ``start_velocity``: PCHIP, or the cubic spline where TOPP-RA finds
    no timing of the PCHIP path (a short path that turns back on itself: PCHIP stops at every turn)."""
    for interpolation in (Interpolation.PCHIP, Interpolation.CUBIC):
        try:
            return time_parameterize(Q, s.timing_rate, limits, interpolation, s.timing_grid, start_velocity)
        except TimingError:
            if interpolation is Interpolation.CUBIC:
                raise


class MovingPlanner:
    """Plans to a moving target's predicted pose (see the module doc); one per target and thread."""

    def __init__(self, replanner: Replanner, settings: MovingSettings = MovingSettings()):
        self.replanner, self.settings = replanner, settings
        self.last: Optional[MovingPlan] = None

    def plan(
        self,
        motion: TargetMotion,
        now: float,
        start: Optional[np.ndarray] = None,
        start_velocity: Optional[np.ndarray] = None,
    ) -> MovingPlan:
        """A plan from ``start`` (moving at ``start_velocity``; None: at rest) at time ``now`` to the target
        where ``motion`` puts it on the hand's arrival."""
        if not isinstance(motion, TargetMotion):
            raise TypeError(f"motion: expected a TargetMotion, got {type(motion).__name__}")
        if not math.isfinite(now):
            raise ValueError(f"now: expected a finite time, got {now}")
        s, clock = self.settings, _clock(self.replanner.planner.settings)
        t0 = clock()
        # The first guess of the duration: what is left of the last plan (0 for the first plan: no move).
        d = max(0.0, self.last.arrival - now) if self.last is not None and self.last.timed is not None else 0.0
        target = self.replanner.world.target
        result, timed, rounds, pose, d_planned, planner, prepare = None, None, 0, None, d, 0.0, 0.0
        for rounds in range(1, s.prediction_rounds + 1):
            pose, d_planned = motion.predict(now + d), d
            result = self._plan_once(target, pose, start)
            planner += result.timings.get("total", 0.0)
            prepare += result.timings.get("prepare", 0.0)
            if not result.planned:
                timed = None
                break
            Q = timing_waypoints(
                result.trajectory, s.timing_spacing, self.replanner.planner.settings.goals.standoff_steps
            )
            timed = _timed(Q, result.limits, s, start_velocity)
            d = timed.duration
            if abs(d - d_planned) <= s.arrival_tolerance:
                break
        arrival = now + (timed.duration if timed is not None else 0.0)
        plan = MovingPlan(
            result,
            timed,
            float(now),
            float(arrival),
            pose,
            rounds,
            clock() - t0 - prepare,
            motion.speed * abs(arrival - now - d_planned),
            planner,
        )
        self.last = plan
        return plan

    def _plan_once(self, target: str, pose: np.ndarray, start) -> PlanResult:
        if self.settings.mode is ReplanMode.warm:
            return self.replanner.replan(start, moved={target: pose})
        self.replanner.world.move_object(target, pose)
        return self.replanner.plan(start)
