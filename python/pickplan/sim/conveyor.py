"""A moving target in PyBullet (issue 36): a conveyor belt under it, and a nudge.

``TargetPath``: the belt's constant velocity and, optionally, one sudden displacement at a given time.
``conveyor_scene`` places the target upstream, so that the belt brings it to its scene pose at
``meet_time``, and clears a lane: the other objects whose footprint the target would sweep (from its
start to where it is at ``end_time``, the nudge included) are left out.

``Conveyor.before_step(t)`` and ``after_step()`` run around every physics step. The belt is ideal:
while the target rests on it (its centre of mass less than ``release_height`` above where it started),
it moves horizontally with the belt and does not turn (no slip: the belt's grip overcomes the table's
friction and the fingers' push); lifted off, or ``release``d (a gripper holds it), it is free. The nudge moves the
target by ``nudge`` at ``nudge_time`` in one step (a person pushing it).

>>> scene2 = conveyor_scene(scene, path, meet_time=2.0, end_time=6.0)
>>> belt = Conveyor(client, body, model, path, time_step)  # before_step(t), step, after_step()
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Optional

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.sim.bodies import object_pose
from pickplan.sim.scenes import Scene


@dataclass(frozen=True)
class TargetPath:
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m/s of the belt (horizontal)
    nudge: np.ndarray = field(default_factory=lambda: np.zeros(3))  # m the target jumps by at nudge_time
    nudge_time: Optional[float] = None  # s; None: no nudge
    release_height: float = 0.005  # m above its start: off the belt

    def __post_init__(self):
        for name in ("velocity", "nudge"):
            v = np.array(getattr(self, name), dtype=float)
            if v.shape != (3,) or not np.all(np.isfinite(v)):
                raise ValueError(f"target path: {name} must be 3 finite numbers (m/s, m), got {getattr(self, name)!r}")
            if abs(v[2]) > 0:
                raise ValueError(f"target path: {name} must be horizontal (z = 0), got {v.tolist()}")
            object.__setattr__(self, name, v)
        if self.nudge_time is not None and not (math.isfinite(self.nudge_time) and self.nudge_time >= 0):
            raise ValueError(f"target path: nudge_time must be a time >= 0 s or None, got {self.nudge_time}")
        if not self.release_height > 0:
            raise ValueError(f"target path: release_height must be > 0 m, got {self.release_height}")

    def offset(self, t: float) -> np.ndarray:
        """Where the belt and the nudge have moved the target by time ``t`` (from its start)."""
        jumped = self.nudge_time is not None and t >= self.nudge_time
        return self.velocity * t + (self.nudge if jumped else 0.0)


def footprint_radius(model: objects_mod.ObjectModel, pose: np.ndarray) -> float:
    """The radius of the object's footprint (horizontal) about its origin, at ``pose``."""
    xy = (np.asarray(model.mesh.vertices) @ np.asarray(pose)[:3, :3].T)[:, :2]
    return float(np.max(np.linalg.norm(xy, axis=1)))


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    s = 0.0 if not np.any(ab) else float(np.clip(np.dot(p - a, ab) / np.dot(ab, ab), 0.0, 1.0))
    return float(np.linalg.norm(p - (a + s * ab)))


def conveyor_scene(
    scene: Scene, path: TargetPath, meet_time: float, end_time: float, margin: float = 0.02, library=None
) -> Scene:
    """The scene with its target moved upstream (it reaches its scene pose at ``meet_time``) and the
    objects in its lane up to ``end_time`` left out (see the module doc)."""
    if not 0 <= meet_time <= end_time:
        raise ValueError(f"conveyor scene: need 0 <= meet_time <= end_time, got {meet_time}, {end_time}")

    def model(o):
        return library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)

    target = scene.object(scene.target)
    start = np.array(target.pose, float)
    start[:3, 3] -= path.offset(meet_time)
    ends = [start[:2, 3], start[:2, 3] + path.velocity[:2] * end_time]
    if path.nudge_time is not None:
        ends += [e + path.nudge[:2] for e in ends]
    a, b = np.min(ends, axis=0), np.max(ends, axis=0)  # the lane: along the belt or the nudge (each one axis)
    r = footprint_radius(model(target), start)
    keep = []
    for o in scene.objects:
        if o.name == scene.target:
            keep.append(replace(o, pose=start))
        elif _segment_distance(np.asarray(o.pose)[:2, 3], a, b) > r + footprint_radius(model(o), o.pose) + margin:
            keep.append(o)
    return replace(scene, objects=keep)


class Conveyor:
    """Drives one body along a ``TargetPath`` (see the module doc)."""

    def __init__(self, client: int, body: int, model: objects_mod.ObjectModel, path: TargetPath, time_step: float):
        from pickplan.sim.bullet import pb

        self.pb, self.c, self.body, self.model, self.path, self.time_step = pb, client, body, model, path, time_step
        self._held = None
        self.z0 = self.com()[2]
        self.nudged = self.released = False

    def com(self) -> np.ndarray:
        return np.asarray(self.pb.getBasePositionAndOrientation(self.body, physicsClientId=self.c)[0], float)

    def pose(self) -> np.ndarray:
        """The target's pose now (its object frame)."""
        return object_pose(self.c, self.body, self.model)

    def on_belt(self) -> bool:
        return not self.released and self.com()[2] - self.z0 < self.path.release_height

    def release(self) -> None:
        """The belt lets the target go (a gripper holds it: its grip dwarfs the belt's)."""
        self.released = True

    def before_step(self, t: float) -> None:
        """The nudge when its time came; where the belt holds the target (before the step)."""
        pb, p = self.pb, self.path
        if p.nudge_time is not None and not self.nudged and t >= p.nudge_time:
            pos, quat = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.c)
            pb.resetBasePositionAndOrientation(
                self.body, (np.asarray(pos) + p.nudge).tolist(), quat, physicsClientId=self.c
            )
            self.nudged = True
        self._held = None
        if np.any(p.velocity) and self.on_belt():
            self._held = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.c)

    def after_step(self) -> None:
        """A target on the belt moved with it: its horizontal position the belt's step on from where it was
        (the table's friction, which the step applied, is the belt's to overcome), its turn undone."""
        if self._held is None:
            return
        pb, p, dt = self.pb, self.path, self.time_step
        (x, y, _), quat = self._held
        z = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.c)[0][2]
        vz = pb.getBaseVelocity(self.body, physicsClientId=self.c)[0][2]
        pb.resetBasePositionAndOrientation(
            self.body, [x + p.velocity[0] * dt, y + p.velocity[1] * dt, z], quat, physicsClientId=self.c
        )
        pb.resetBaseVelocity(
            self.body, [float(p.velocity[0]), float(p.velocity[1]), vz], [0.0, 0.0, 0.0], physicsClientId=self.c
        )
