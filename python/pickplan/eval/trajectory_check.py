"""The independent trajectory checker every benchmarked planner's output passes through (ours and the
baselines'): FCL on the URDF's own collision meshes against the scene's obstacles (exact primitives),
the robot against itself but for the pairs the SRDF disables, and the joint limits, at states so dense
that no point of the robot moves more than ``resolution`` between two consecutive ones.

It shares no code path with a planner's own validity test: its states come from the robot's collision
hulls moving between waypoints (the largest displacement of a rigid body's points is reached at a
vertex of its convex hull), measured by forward kinematics and bisected until every step is below the
resolution; a planner's resolution, step rule and checker settings play no part.

>>> checker = TrajectoryChecker(robot, obstacles, allowed_pairs)
>>> report = checker.check(path)       # report.valid, report.reason, report.min_clearance
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np

from pickplan.core import collision
from pickplan.core.robots import Robot
from pickplan.core.shapes import Obstacle
from pickplan.omg.model_cache import ModelCache

MAX_STATES = 200_000  # per trajectory: a path that needs more is refused (reported), not checked for hours


@dataclass(frozen=True)
class CheckReport:
    valid: bool
    reason: str  # "" when valid; else what failed and where
    states: int  # states checked
    min_clearance: float  # m: smallest robot-obstacle distance over the states sampled for it (inf: none)


class TrajectoryChecker:
    """FCL collision checks of a joint path, densely interpolated (see the module doc)."""

    def __init__(
        self,
        robot: Robot,
        obstacles: Sequence[Obstacle],
        allowed_pairs: Sequence[Tuple[str, str]] = (),
        resolution: float = 0.002,
        clearance_resolution: float = 0.02,
        limit_tolerance: float = 1e-6,
        cache: Optional[ModelCache] = None,
    ):
        if not (resolution > 0 and clearance_resolution >= resolution):
            raise ValueError("resolution must be > 0 and clearance_resolution >= resolution")
        self.robot, self.resolution = robot, float(resolution)
        self.clearance_resolution, self.limit_tolerance = float(clearance_resolution), float(limit_tolerance)
        cache = ModelCache() if cache is None else cache  # the URDF's meshes, loaded once per robot
        link_meshes = cache.link_meshes(robot)
        links = set(robot.link_names)
        pairs = tuple((a, b) for a, b in allowed_pairs if a in links and b in links)
        meshes = [collision.SceneMesh(o.name, o.shape, o.pose) for o in obstacles]
        self._collide = collision.CollisionChecker(
            robot,
            meshes,
            None,
            collision.CollisionSettings(allowed_pairs=pairs, self_collision=True),
            shapes=cache.shapes,
            link_meshes=link_meshes,
        )
        self._clearance = (
            collision.CollisionChecker(robot, meshes, None, shapes=cache.shapes, link_meshes=link_meshes)
            if meshes
            else None
        )
        # The convex hull of every link's geometry, in the link frame: its vertices bound the link's motion.
        self._hulls = cache.robot_derived(
            robot,
            "trajectory_check_hulls",
            lambda: [
                (i, np.ascontiguousarray(np.asarray(link_meshes[name].convex_hull.vertices, dtype=float).T))
                for i, name in enumerate(robot.link_names)
                if link_meshes[name] is not None
            ],
        )

    def _points(self, Q: np.ndarray) -> np.ndarray:
        """(B, P, 3) world positions of every hull vertex at each of the (B, dof) states."""
        poses = self.robot.fk_batch(Q)  # (B, links, 4, 4)
        return np.concatenate(
            [np.swapaxes(poses[:, i, :3, :3] @ Vt, 1, 2) + poses[:, i, None, :3, 3] for i, Vt in self._hulls], axis=1
        )

    def _segment(self, a: np.ndarray, b: np.ndarray, resolution: float) -> np.ndarray:
        """States from ``a`` to ``b`` (both included), halving every step that moves a hull vertex more
        than ``resolution``; only the new states' points are computed each round."""
        t = np.array([0.0, 1.0])
        X = self._points(a + t[:, None] * (b - a))
        while True:
            far = np.linalg.norm(X[1:] - X[:-1], axis=2).max(axis=1) > resolution
            if not far.any():
                return a + t[:, None] * (b - a)
            if len(t) > MAX_STATES:
                raise ValueError(f"the path needs more than {MAX_STATES} states at {resolution} m")
            mid = 0.5 * (t[:-1][far] + t[1:][far])
            order = np.argsort(np.concatenate([t, mid]), kind="stable")
            t = np.concatenate([t, mid])[order]
            X = np.concatenate([X, self._points(a + mid[:, None] * (b - a))])[order]

    def dense(self, path: np.ndarray, resolution: float) -> np.ndarray:
        """The path's states with every step moving no hull vertex more than ``resolution`` (m)."""
        P = np.asarray(path, dtype=float)
        return np.concatenate([P[:1]] + [self._segment(a, b, resolution)[1:] for a, b in zip(P[:-1], P[1:])])

    def check(self, path) -> CheckReport:
        P = np.asarray(path, dtype=float)
        if P.ndim != 2 or P.shape[1] != self.robot.dof or len(P) < 1 or not np.all(np.isfinite(P)):
            return CheckReport(False, f"not a ({'k'}, {self.robot.dof}) finite path: shape {P.shape}", 0, float("nan"))
        lo, hi = self.robot.lower_limits, self.robot.upper_limits
        over = np.maximum(lo - P, P - hi)
        if over.max() > self.limit_tolerance:
            k, j = np.unravel_index(int(np.argmax(over)), over.shape)
            return CheckReport(
                False,
                f"waypoint {k}: joint {self.robot.joint_names[j]} outside its limits by {over[k, j]:.2g}",
                0,
                float("nan"),
            )
        try:
            Q = self.dense(P, self.resolution)
        except ValueError as exc:
            return CheckReport(False, str(exc), 0, float("nan"))
        hits = self._collide.in_collision_batch(Q)
        if hits.any():
            k = int(np.argmax(hits))
            contact = self._collide.contacts(Q[k])
            what = f"{contact[0].link} with {contact[0].other}" if contact else "a collision"
            return CheckReport(False, f"state {k} of {len(Q)}: {what}", len(Q), float("nan"))
        clearance = float("inf")
        if self._clearance is not None:
            C = self.dense(P, self.clearance_resolution)
            clearance = float(self._clearance.min_distance_batch(C).min())
        return CheckReport(True, "", len(Q), clearance)
