"""Timed trajectories: planned waypoints become q(t), qd(t), qdd(t) within joint velocity and
acceleration limits, by time-optimal path parameterization (TOPP-RA, the ``toppra`` library).

The waypoints (T, dof) define a path q(s) through them, s in [0, 1] spaced evenly (the planner spaces
its waypoints evenly in time). toppra finds the fastest s(t) from rest to rest with every joint inside
its limits; the result is sampled at exactly ``rate`` Hz. The path is not changed, only the speed
along it: with the default PCHIP interpolation each joint moves monotonically between two waypoints,
so the path stays inside every segment's bounding box (and inside the joint limits).

Jerk is not bounded: toppra's solution has piecewise constant path acceleration. The datasheet's
jerk limits are stated in the robot's description (``assets/robots/*.toml``) for controllers that smooth
the samples.

>>> timed = time_parameterize(plan.trajectory, rate=1000.0)     # the Panda's limits by default
>>> timed.duration, timed.q.shape, timed.qd[0]
>>> timed.save("out/timed.json"); timed.save("out/timed.npz")
"""

from __future__ import annotations

import enum
import json
import math
import os
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core import robots
from pickplan.core.io import atomic_open

FORMAT = "pickplan.timed_trajectory/1"


class Interpolation(enum.Enum):
    """How the path passes through the waypoints."""

    PCHIP = "pchip"  # shape-preserving cubic (C1): no overshoot between waypoints
    CUBIC = "cubic"  # not-a-knot cubic spline (C2): smoother, rounds sharp corners more widely


class TimingError(RuntimeError):
    """TOPP-RA found no parameterization (numerical trouble; rest to rest is always feasible)."""


@dataclass(frozen=True)
class KinematicLimits:
    """Symmetric per-joint limits: |qd| <= velocity, |qdd| <= acceleration."""

    velocity: np.ndarray
    acceleration: np.ndarray

    def __post_init__(self):
        for name in ("velocity", "acceleration"):
            v = np.asarray(getattr(self, name), dtype=float)
            if v.ndim != 1 or not np.all(np.isfinite(v)) or not np.all(v > 0):
                raise ValueError(f"{name} limits: expected a vector of positive finite numbers, got {v}")
            object.__setattr__(self, name, v)
        if self.velocity.shape != self.acceleration.shape:
            raise ValueError(
                f"limits: {len(self.velocity)} velocity limits but {len(self.acceleration)} acceleration limits"
            )


def robot_limits(robot) -> KinematicLimits:
    """A described robot's limits (``robots.DescribedRobot``): arm velocity and acceleration from its
    description (velocity: the URDF's where the description states none), finger velocity from the
    URDF and finger acceleration from the description."""
    info = robot.info
    velocity = np.array(robot.velocity_limits, dtype=float)
    if info.arm_velocity_limits is not None:
        velocity[: info.arm_dof] = info.arm_velocity_limits
    fingers = (info.finger_acceleration_limit,) * (robot.dof - info.arm_dof)
    return KinematicLimits(velocity, np.array(tuple(info.arm_acceleration_limits) + fingers))


def panda_limits(robot=None) -> KinematicLimits:
    """The Panda's limits (``robot``, default ``robots.panda()``): ``robot_limits`` of its description."""
    return robot_limits(robots.panda() if robot is None else robot)


@dataclass
class TimedTrajectory:
    """Samples of a timed trajectory every 1 / ``rate`` s, from rest (t = 0) to rest (t = duration)."""

    t: np.ndarray  # (K,) s
    q: np.ndarray  # (K, dof)
    qd: np.ndarray  # (K, dof) per s
    qdd: np.ndarray  # (K, dof) per s^2
    rate: float  # Hz
    slowdown: float = 1.0  # factor TOPP-RA's optimum was stretched by: whole samples, limits between grid points

    def __post_init__(self):
        self.t = np.asarray(self.t, dtype=float)
        if self.t.ndim != 1 or len(self.t) < 1 or np.any(np.diff(self.t) <= 0):
            raise ValueError(f"timed trajectory: t must be increasing times, shape (K,), got shape {self.t.shape}")
        arrays = {name: np.asarray(getattr(self, name), dtype=float) for name in ("q", "qd", "qdd")}
        for name, a in arrays.items():
            if a.ndim != 2 or a.shape[0] != len(self.t):
                raise ValueError(f"timed trajectory: {name} must be ({len(self.t)}, dof), got {a.shape}")
            setattr(self, name, a)
        self.rate = _check_rate(self.rate)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "rate": self.rate,
            "duration": self.duration,
            "slowdown": self.slowdown,
            "t": self.t.tolist(),
            "q": self.q.tolist(),
            "qd": self.qd.tolist(),
            "qdd": self.qdd.tolist(),
        }

    def save(self, path: str) -> None:
        """Write JSON (``.json``) or NumPy (``.npz``) with t, q, qd, qdd, rate; atomically."""
        ext = os.path.splitext(os.fspath(path))[1].lower()
        if ext == ".json":
            with atomic_open(path, "w") as f:
                json.dump(self.to_dict(), f, separators=(",", ":"))  # compact: thousands of samples
        elif ext == ".npz":
            with atomic_open(path, "wb") as f:
                np.savez(f, t=self.t, q=self.q, qd=self.qd, qdd=self.qdd, rate=self.rate, slowdown=self.slowdown)
        else:
            raise ValueError(f"timed trajectory: cannot save to {path!r}; expected a .json or .npz path")

    @classmethod
    def load(cls, path: str) -> "TimedTrajectory":
        ext = os.path.splitext(os.fspath(path))[1].lower()
        if ext == ".json":
            with open(path) as f:
                d = json.load(f)
            if d.get("format") != FORMAT:
                raise ValueError(f"{path}: not a timed trajectory ({FORMAT}), format={d.get('format')!r}")
        elif ext == ".npz":
            with np.load(path) as z:
                d = {k: z[k] for k in z.files}
        else:
            raise ValueError(f"timed trajectory: cannot load {path!r}; expected a .json or .npz path")
        return cls(d["t"], d["q"], d["qd"], d["qdd"], float(d["rate"]), float(d.get("slowdown", 1.0)))

    def resampled(self, rate: float) -> "TimedTrajectory":
        """The same motion at another rate: cubic Hermite through (q, qd) and (qd, qdd), qdd linear."""
        from scipy.interpolate import CubicHermiteSpline

        rate = _check_rate(rate)
        if len(self.t) < 2:
            return TimedTrajectory(self.t, self.q, self.qd, self.qdd, rate, self.slowdown)
        t = np.arange(int(math.ceil(self.duration * rate - 1e-9)) + 1) / rate
        t[-1] = min(t[-1], self.duration)
        qdd = np.column_stack([np.interp(t, self.t, a) for a in self.qdd.T])
        return TimedTrajectory(
            t,
            CubicHermiteSpline(self.t, self.q, self.qd)(t),
            CubicHermiteSpline(self.t, self.qd, self.qdd)(t),
            qdd,
            rate,
            self.slowdown,
        )


def _check_rate(rate) -> float:
    try:
        value = float(rate)
    except (TypeError, ValueError):
        value = float("nan")
    if not (value > 0 and math.isfinite(value)):
        raise ValueError(f"rate must be a positive number of Hz, got {rate!r}")
    return value


def _check_waypoints(waypoints) -> np.ndarray:
    try:
        Q = np.array(waypoints, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"waypoints: expected a (T, dof) array of numbers, got {type(waypoints).__name__}") from exc
    if Q.ndim != 2 or Q.shape[0] < 1 or Q.shape[1] < 1:
        raise ValueError(f"waypoints: expected shape (T, dof) with T >= 1, got {Q.shape}")
    if not np.all(np.isfinite(Q)):
        k, j = np.argwhere(~np.isfinite(Q))[0]
        raise ValueError(f"waypoints: contains NaN or infinity (first at waypoint {k}, joint {j})")
    return Q


def _path(Q: np.ndarray, interpolation: Interpolation):
    """The geometric path q(s) through Q, s evenly spaced on [0, the polyline's length], as toppra reads a
    path; its ``left(s, order)`` is the derivative's limit from the left (PCHIP's q'' jumps at the
    waypoints)."""
    from scipy.interpolate import CubicSpline, PchipInterpolator
    from toppra.interpolator import AbstractGeometricPath

    # s runs over the joint-space length, so the path speed s' is of the joints' speed: on [0, 1] a
    # short path's s' reached hundreds and TOPP-RA's LP (in s'^2) lost its sets to round-off
    ss = np.linspace(0.0, float(np.linalg.norm(np.diff(Q, axis=0), axis=1).sum()), len(Q))
    spline = PchipInterpolator(ss, Q) if interpolation is Interpolation.PCHIP else CubicSpline(ss, Q)
    derivatives = (spline, spline.derivative(1), spline.derivative(2))

    class _ScipyPath(AbstractGeometricPath):
        def __call__(self, path_positions, order=0):
            return derivatives[order](path_positions)

        def left(self, path_positions, order):
            pp = derivatives[order]
            s = np.asarray(path_positions, float)
            piece = np.clip(np.searchsorted(pp.x, s, side="left") - 1, 0, len(pp.x) - 2)
            h = (s - pp.x[piece])[:, None]
            out = np.zeros((len(s), Q.shape[1]))
            for c in pp.c:  # Horner on each grid point's piece (scipy's PPoly takes the right one at a knot)
                out = out * h + c[piece]
            return out

        @property
        def dof(self):
            return Q.shape[1]

        @property
        def path_interval(self):
            return np.array([0.0, ss[-1]])

        @property
        def waypoints(self):
            return ss, Q

    return _ScipyPath(), ss


def _acceleration_constraint(acceleration: np.ndarray):
    """toppra's joint acceleration constraint with q''(s) from both sides of every grid point, so a
    waypoint (where PCHIP's q'' jumps) is itself a grid point bounded on both of its pieces. (Grid points
    a hair either side of each waypoint did the same, but TOPP-RA's LP solver fails on such short stages:
    ``x + 2 delta u`` nearly parallel to the u axis; a smooth straight retract was not timed.)"""
    import toppra.constraint
    from toppra.constraint.linear_constraint import canlinear_colloc_to_interpolate

    class _BothSides(toppra.constraint.JointAccelerationConstraint):
        def compute_constraint_params(self, path, gridpoints, *args, **kwargs):
            qs = path(gridpoints, 1)
            a, b = np.hstack([qs, qs]), np.hstack([path.left(gridpoints, 2), path(gridpoints, 2)])
            rows = np.eye(a.shape[1])
            return canlinear_colloc_to_interpolate(
                a,
                b,
                np.zeros_like(a),
                np.vstack([rows, -rows]),
                np.tile(acceleration, 4),
                None,
                None,
                gridpoints,
                identical=True,
            )

    return _BothSides(acceleration)


def time_parameterize(
    waypoints,
    rate: float = 1000.0,
    limits: Optional[KinematicLimits] = None,
    interpolation: Interpolation = Interpolation.PCHIP,
    grid_per_segment: int = 16,
    start_velocity=None,
) -> TimedTrajectory:
    """Time-optimal rest-to-rest timing of ``waypoints`` (T, dof) under ``limits`` (default: the Panda's),
    sampled at ``rate`` Hz (default 1 kHz, Franka's control rate); see the module doc.

    ``grid_per_segment``: TOPP-RA grid points per waypoint interval (more: closer to time-optimal, slower).
    ``start_velocity`` (dof,): the joints' velocity at the start (a replan while moving): the path starts at
    its projection on the path's direction, or slower where TOPP-RA cannot stop in time from it; None: rest.
    """
    import toppra.algorithm  # toppra imports matplotlib: loaded when a trajectory is timed
    import toppra.constraint

    Q = _check_waypoints(waypoints)
    rate = _check_rate(rate)
    if not isinstance(interpolation, Interpolation):
        raise ValueError(f"interpolation: expected an Interpolation, got {interpolation!r}")
    if grid_per_segment < 1:
        raise ValueError(f"grid_per_segment must be >= 1, got {grid_per_segment}")
    limits = panda_limits() if limits is None else limits  # callers with another robot pass robot_limits(robot)
    if len(limits.velocity) != Q.shape[1]:
        raise ValueError(f"limits: expected {Q.shape[1]} joints (the waypoints' dof), got {len(limits.velocity)}")
    keep = np.concatenate([[True], np.any(np.diff(Q, axis=0) != 0.0, axis=1)])  # a repeated waypoint adds no path
    Q = Q[keep]
    if len(Q) == 1:
        zero = np.zeros_like(Q)
        return TimedTrajectory(np.zeros(1), Q, zero, zero.copy(), rate)
    path, ss = _path(Q, interpolation)
    # Every segment cut in grid_per_segment equal stages from its waypoint: the waypoints are grid points
    # exactly (no stage a rounding error long)
    grid = np.append(ss[:-1, None] + np.diff(ss)[:, None] * (np.arange(grid_per_segment) / grid_per_segment), ss[-1])
    velocity = toppra.constraint.JointVelocityConstraint(limits.velocity)
    # q'' from both sides of a waypoint first; where a joint turns back on one (PCHIP's q' exactly 0
    # there) its LP can give NaN and empty the sets: toppra's own constraint (q'' from one side) then
    # times the path, and the samples are checked against the limits below either way
    for acceleration in (_acceleration_constraint, toppra.constraint.JointAccelerationConstraint):
        constraints = [velocity, acceleration(limits.acceleration)]
        solver = toppra.algorithm.TOPPRA(constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel")
        timing = _compute(solver, path, Q, start_velocity)
        if timing is not None:
            break
    if timing is None:
        raise TimingError(f"TOPP-RA found no time parameterization of {len(Q)} waypoints")
    optimum = float(timing.duration)
    # Limits hold at TOPP-RA's grid points; between them they can be exceeded by a little. Stretch time
    # (qd / c, qdd / c^2) until every sample is within, with a whole number of samples at ``rate``.
    scale = 1.0
    for _ in range(5):
        k = max(1, int(math.ceil(optimum * scale * rate - 1e-9)))
        scale = k / (rate * optimum)
        t = np.arange(k + 1) / rate
        tau = np.clip(t / scale, 0.0, optimum)
        q, qd, qdd = timing(tau), timing(tau, 1) / scale, timing(tau, 2) / scale**2
        excess = max(np.max(np.abs(qd) / limits.velocity), math.sqrt(np.max(np.abs(qdd) / limits.acceleration)))
        if excess <= 1.0:
            break
        scale *= excess * (1.0 + 1e-9)
    else:
        raise TimingError(f"could not bring the samples within the limits (excess {excess:.4f})")
    qd[-1] = 0.0  # to rest (toppra's end velocity is zero to round-off)
    if start_velocity is None:
        qd[0] = 0.0
    q[0], q[-1] = Q[0], Q[-1]
    return TimedTrajectory(t, q, qd, qdd, rate, scale)


def _compute(solver, path, Q: np.ndarray, start_velocity):
    """TOPP-RA's timing from the start's path speed (the start velocity projected on q'(0); halved until
    feasible, at last from rest) to rest; None where even rest to rest fails."""
    sd = 0.0
    if start_velocity is not None:
        v = np.asarray(start_velocity, dtype=float)
        if v.shape != (Q.shape[1],) or not np.all(np.isfinite(v)):
            raise ValueError(f"start_velocity: expected {Q.shape[1]} finite numbers, got {start_velocity!r}")
        tangent = path(np.array([0.0]), 1)[0]
        sd = max(0.0, float(v @ tangent) / float(tangent @ tangent)) if np.any(tangent) else 0.0
    for _ in range(4):
        timing = solver.compute_trajectory(sd, 0.0)
        if timing is not None or sd == 0.0:
            return timing
        sd *= 0.5
    return solver.compute_trajectory(0.0, 0.0)


def joint_move(q_from, q_to, limits: KinematicLimits, rate: float, min_duration: float = 0.0) -> TimedTrajectory:
    """A rest-to-rest quintic move from ``q_from`` to ``q_to`` (a gripper closing, the arm still), as short
    as ``limits`` allow but at least ``min_duration`` s: the quintic's peak speed is 15/8 and its peak
    acceleration 10/sqrt(3) of the distance over the duration (to the first and second power)."""
    a, b = np.asarray(q_from, float), np.asarray(q_to, float)
    rate = _check_rate(rate)
    d = np.abs(b - a)
    need = max(
        min_duration,
        float(np.max(1.875 * d / limits.velocity)),
        float(np.sqrt(np.max(10.0 / math.sqrt(3.0) * d / limits.acceleration))),
        1.0 / rate,
    )
    k = int(math.ceil(need * rate - 1e-9))
    T = k / rate
    s = np.arange(k + 1) / k
    p = 10 * s**3 - 15 * s**4 + 6 * s**5
    dp = (30 * s**2 - 60 * s**3 + 30 * s**4) / T
    ddp = (60 * s - 180 * s**2 + 120 * s**3) / T**2
    delta = b - a
    return TimedTrajectory(
        np.arange(k + 1) / rate, a + np.outer(p, delta), np.outer(dp, delta), np.outer(ddp, delta), rate
    )


def concatenate(parts: Sequence[TimedTrajectory]) -> Tuple[TimedTrajectory, List[Tuple[float, float]]]:
    """Rest-to-rest trajectories at one rate, one after another (each junction sample once), and each
    part's start and end time in the whole. Raises ``ValueError`` when rates differ or a part does not
    start where the one before it ended."""
    if not parts:
        raise ValueError("concatenate: no trajectory")
    rate = parts[0].rate
    t, q, qd, qdd, spans = [parts[0].t], [parts[0].q], [parts[0].qd], [parts[0].qdd], [(0.0, parts[0].duration)]
    for k, part in enumerate(parts[1:], 1):
        if part.rate != rate:
            raise ValueError(f"concatenate: part {k} at {part.rate} Hz, expected {rate} Hz")
        if not np.allclose(part.q[0], q[-1][-1], atol=1e-9):
            raise ValueError(
                f"concatenate: part {k} starts {np.max(np.abs(part.q[0] - q[-1][-1])):.3g} away from "
                "where the one before it ends"
            )
        offset = spans[-1][1]
        t.append(part.t[1:] + offset)
        q.append(part.q[1:])
        qd.append(part.qd[1:])
        qdd.append(part.qdd[1:])
        spans.append((offset, offset + part.duration))
    whole = TimedTrajectory(
        np.concatenate(t), np.vstack(q), np.vstack(qd), np.vstack(qdd), rate, max(p.slowdown for p in parts)
    )
    return whole, spans
