"""Executing a pick and place in PyBullet: approach, close, lift, transfer and set-down, release,
retract, settle; then the place test.

One ``PickPlaceSim`` is one DIRECT client (``execution.open_sim``: the same bodies, frictions, gains and
finger coupling as ``execute_plan``). The arm follows each timed segment (``TimedTrajectory``, the
velocities as feed-forward); the fingers follow the plan on the approach, squeeze with the
gripper's force (``ExecutionSettings.finger_force``, else the description's) while carrying (the
planned finger values are the open hand's: conservative for the planner, ignored here) and open to release. ``execute_pick_and_place`` runs the segments; between
the lift and the transfer it may hand the grasp as executed (``hand_T_object``) to a ``replan``
callback, which returns the transfer and retract planned for it.

Success (``PlaceCheck``): the object at rest (waited for up to ``settle_max``), its whole hull inside the region (within
``region_tolerance``), its up axis within the tolerance of the planned pose's (not toppled; turns about
an axis of rotational symmetry do not count), its yaw too when one was asked; no other object moved more than ``max_moved``; the robot never penetrated a
body other than the target deeper than ``collision_depth`` and the held object no body other than the
robot and its support.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core import robots
from pickplan.core.meshes import symmetry_axes
from pickplan.core.settings import Option
from pickplan.core.timing import TimedTrajectory
from pickplan.sim import render as viz
from pickplan.sim import scenes as scenes_mod
from pickplan.sim.arm_sim import ArmSim, follow, hold, open_sim
from pickplan.sim.execution import ExecutionSettings, RecordSettings


class PlaceOutcome(Option):
    """How an executed pick and place ended."""

    placed = "placed"  # every test passed
    missed = "missed"  # the fingers closed without the object between them
    dropped = "dropped"  # the object left the hand before the release
    not_planned = "not_planned"  # no place plan for the grasp as executed (replan failed)
    collision = "collision"  # the robot or the held object penetrated another body
    outside_region = "outside_region"
    toppled = "toppled"  # at rest in the region but not in the asked orientation
    moving = "moving"  # still moving at the end
    moved_others = "moved_others"  # another object moved more than max_moved
    unstable = "unstable"  # the simulation diverged


@dataclass(frozen=True)
class PlaceCheck:
    """What the placed object must satisfy (from a ``place.PlaceRequest`` and the planned place)."""

    region_min: Tuple[float, float, float]
    region_max: Tuple[float, float, float]
    place_pose: np.ndarray  # (4, 4) planned pose at release
    tolerance_deg: float = 10.0  # up axis
    yaw_tolerance_deg: Optional[float] = None  # None: yaw free
    region_tolerance: float = 0.01  # m the hull may reach beyond the region
    max_moved: float = 0.02  # m any other object may move
    rest_speed: float = 0.01  # m/s
    rest_spin: float = 0.2  # rad/s


@dataclass(frozen=True)
class PickPlaceExecSettings:
    execution: ExecutionSettings = field(default_factory=ExecutionSettings)
    release_duration: float = 0.5  # s the open fingers are given before the retract
    settle_duration: float = 1.0  # s after the retract at least before the test
    # ... and at most, while the object still moves (a set-down rocks a tall object for 1-3 s before it
    # stands still): the test reads it at rest, or moving when it never stopped
    settle_max: float = 5.0
    # s between the checks for rest; at rest at 3 checks in a row (a rocking object is still for an
    # instant at each turn)
    settle_check: float = 0.1
    held_penetration: float = 0.003  # m the held object may press into another body before it counts

    def __post_init__(self):
        if not (self.settle_check > 0 and self.settle_max >= self.settle_duration >= 0):
            raise ValueError(
                "pick-and-place settling: expected settle_check > 0 and settle_max >= settle_duration >= 0, got "
                f"{self.settle_check!r}, {self.settle_max!r}, {self.settle_duration!r}"
            )


@dataclass
class PickPlaceExecution:
    success: bool
    status: PlaceOutcome
    message: str
    held_after_close: bool
    held_before_release: bool
    hand_T_object: Optional[np.ndarray]  # the grasp as executed (object in the hand frame after the lift)
    final_pose: np.ndarray  # (4, 4) the object's pose at the end
    tilt_deg: float  # its up axis from the planned pose's
    yaw_error_deg: float
    in_region: bool
    at_rest: bool
    robot_contacts: Dict[str, float]  # body -> deepest robot penetration (m), the target left out
    held_contacts: Dict[str, float]  # body -> deepest penetration by the carried object (robot, table out)
    object_displacements: Dict[str, float]
    sim_time: float
    seconds: float
    frames: List[np.ndarray] = field(default_factory=list, repr=False)

    def to_dict(self) -> dict:
        d = {k: v for k, v in self.__dict__.items() if k != "frames"}
        d["status"] = self.status.value
        for k in ("hand_T_object", "final_pose"):
            d[k] = None if d[k] is None else np.asarray(d[k]).tolist()
        return d


class _CarrySim(ArmSim):
    """``ArmSim`` that also records the carried object's contacts while ``carrying``."""

    def __init__(self, *args):
        super().__init__(*args)
        self.carrying = False
        self.held_contacts: Dict[str, float] = {}

    def step(self, watch_contacts: bool = False) -> None:
        super().step(watch_contacts)
        if not (watch_contacts and self.carrying):
            return
        for cp in self.pb.getContactPoints(bodyA=self.bodies[self.target], physicsClientId=self.c):
            other = self.names.get(cp[2])
            if other is None or other == "table" or cp[8] > 0:
                continue
            self.held_contacts[other] = max(self.held_contacts.get(other, 0.0), -float(cp[8]))


def _resampled(timed: TimedTrajectory, time_step: float) -> TimedTrajectory:
    return timed if abs(timed.rate * time_step - 1.0) <= 1e-9 else timed.resampled(1.0 / time_step)


def _follow_timed(sim: ArmSim, timed: TimedTrajectory, fingers_from_plan: bool, watch: bool) -> None:
    t = _resampled(timed, sim.s.time_step)
    follow(sim, t.q, [(sim.s.time_step, 1)] * (len(t.q) - 1), fingers_from_plan, sim.grip_force, watch, t.qd)


def hand_T_object(sim: ArmSim, robot) -> np.ndarray:
    """The target's pose in the hand link's frame now (the grasp as executed)."""
    hand = robot.fk(sim.joint_positions())[robot.link_index(robot.hand_link)]
    T = scenes_mod.object_pose(sim.c, sim.bodies[sim.target], sim.models[sim.target])
    return np.linalg.inv(hand) @ T


def _tilt_and_yaw(final: np.ndarray, planned: np.ndarray, axes: Sequence[np.ndarray] = ()) -> Tuple[float, float]:
    """Degrees between the planned and the final up axis (in the object), and between their headings.
    ``axes`` (object frame): the object's axes of rotational symmetry (``meshes.symmetry_axes``), about
    which a turn leaves it as it was. With one, the tilt is the change in the up axis's angle to it (a pen
    that rolled on its side is not toppled), and an upright symmetry axis has no heading; with three (a
    ball) neither has a meaning."""
    up_f, up_p = final[:3, :3].T @ [0, 0, 1.0], planned[:3, :3].T @ [0, 0, 1.0]
    R = final[:3, :3] @ planned[:3, :3].T  # the rotation from the planned to the final pose
    yaw = math.degrees(abs(math.atan2(R[1, 0] - R[0, 1], R[0, 0] + R[1, 1])))
    if len(axes) == 0:
        return math.degrees(math.acos(float(np.clip(up_f @ up_p, -1.0, 1.0)))), yaw
    if len(axes) > 1:
        return 0.0, 0.0
    axis = axes[0]
    to_axis = [math.degrees(math.acos(float(np.clip(u @ axis, -1.0, 1.0)))) for u in (up_f, up_p)]
    return abs(to_axis[0] - to_axis[1]), 0.0 if min(to_axis[1], 180.0 - to_axis[1]) < 1.0 else yaw


Segments = Sequence[Tuple[str, TimedTrajectory]]
Replan = Callable[[np.ndarray, np.ndarray], Optional[Tuple[Segments, np.ndarray]]]


def execute_pick_and_place(
    scene: scenes_mod.Scene,
    segments: Segments,
    check: PlaceCheck,
    settings: PickPlaceExecSettings = PickPlaceExecSettings(),
    library: Optional[objects_mod.ObjectLibrary] = None,
    record: Optional[RecordSettings] = None,
    replan: Optional[Replan] = None,
) -> PickPlaceExecution:
    """Run ``segments`` (name, timed): "approach", "lift", "transfer", "retract"; see the module doc.
    ``replan(q_now, hand_T_object)`` -> (the transfer and retract segments, the new ``place_pose``) or None."""
    t_start = time.perf_counter()
    s = settings.execution
    parts = dict(segments)
    missing = (
        {"approach", "lift", "transfer", "retract"} - set(parts)
        if replan is None
        else {"approach", "lift"} - set(parts)
    )
    if missing:
        raise ValueError(f"segments: missing {sorted(missing)}")
    robot = robots.load_robot(s.robot, np.asarray(scene.robot_base, dtype=float))
    models = {
        o.name: library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)
        for o in scene.objects
    }
    sim = open_sim(scene, robot, parts["approach"].q[0], s, models, record, sim_class=_CarrySim)
    try:
        com0 = {name: sim.com(name) for name in sim.bodies}
        if record is not None:
            if record.colorize:
                viz.colorize(sim.c, sim.bodies, sim.target)
            sim.capture()
        held_after_close, held_after_lift = _pick_and_lift(sim, robot, parts, s)
        grasp = hand_T_object(sim, robot)
        place_pose, planned = check.place_pose, True
        if replan is not None and held_after_lift:
            out = replan(sim.joint_positions(), grasp)
            if out is None:
                planned = False
            else:
                parts.update(dict(out[0]))
                place_pose = out[1]
        held_before_release = bool(planned and held_after_lift) and _place_and_retract(sim, robot, parts, settings)
        v, w = _settle(sim, check, settings)
        final = scenes_mod.object_pose(sim.c, sim.bodies[scene.target], models[scene.target])
        com1 = {name: sim.com(name) for name in sim.bodies}
        if record is not None:
            sim.capture()
        finite = bool(np.all(np.isfinite(sim.joint_positions())) and np.all(np.isfinite(final)))
    finally:
        sim.pb.disconnect(sim.c)
    at_rest = bool(np.linalg.norm(v) <= check.rest_speed and np.linalg.norm(w) <= check.rest_spin)
    hull = np.asarray(models[scene.target].mesh.convex_hull.vertices) @ final[:3, :3].T + final[:3, 3]
    tol = check.region_tolerance
    in_region = bool(
        np.all(hull >= np.asarray(check.region_min) - tol) and np.all(hull <= np.asarray(check.region_max) + tol)
    )
    tilt, yaw = _tilt_and_yaw(final, np.asarray(place_pose, float), symmetry_axes(models[scene.target].mesh))
    moved = {n: float(np.linalg.norm(com1[n] - com0[n])) for n in sorted(sim.bodies) if n != scene.target}
    held_contacts = sim.held_contacts
    collided = (
        max(sim.contacts.values(), default=0.0) > s.collision_depth
        or max(held_contacts.values(), default=0.0) > settings.held_penetration
    )
    stages = {"close": held_after_close, "lift": held_after_lift, "planned": planned, "release": held_before_release}
    contacts = {
        **{f"robot-{k}": v for k, v in sim.contacts.items()},
        **{f"held-{k}": v for k, v in held_contacts.items()},
    }
    status, message = _outcome(
        finite, stages, contacts if collided else {}, in_region, at_rest, tilt, yaw, moved, check
    )
    return PickPlaceExecution(
        status is PlaceOutcome.placed,
        status,
        message,
        held_after_close,
        held_before_release,
        grasp,
        final,
        tilt,
        yaw,
        in_region,
        at_rest,
        dict(sorted(sim.contacts.items())),
        dict(sorted(held_contacts.items())),
        moved,
        sim.steps * s.time_step,
        time.perf_counter() - t_start,
        sim.frames,
    )


def _settle(sim, check: PlaceCheck, settings: PickPlaceExecSettings) -> Tuple[np.ndarray, np.ndarray]:
    """Hold the arm while the scene settles: ``settle_duration``, then until the target is at rest (``check``'s
    speeds, 3 checks in a row) or ``settle_max`` has passed; the target's last (linear, angular) velocity."""
    q, elapsed, still, target = sim.joint_positions(), settings.settle_duration, 0, sim.bodies[sim.target]
    hold(sim, q, settings.settle_duration, False)
    while True:
        v, w = (np.asarray(x) for x in sim.pb.getBaseVelocity(target, physicsClientId=sim.c))
        still = still + 1 if np.linalg.norm(v) <= check.rest_speed and np.linalg.norm(w) <= check.rest_spin else 0
        if still >= 3 or elapsed >= settings.settle_max - 1e-9:
            return v, w
        hold(sim, q, settings.settle_check, False)
        elapsed += settings.settle_check


def _pick_and_lift(sim, robot, parts: dict, s) -> Tuple[bool, bool]:
    """Settle at the start, approach, close, lift and hold: (held after closing, still held after the lift)."""
    sim.command_arm(parts["approach"].q[0], np.zeros(robot.dof))
    sim.command_fingers(parts["approach"].q[0, robot.info.arm_dof], sim.grip_force)
    for _ in range(int(round(s.start_settle / s.time_step))):
        sim.step(True)
    _follow_timed(sim, parts["approach"], True, True)
    hold(sim, parts["approach"].q[-1], s.approach_settle, True)
    sim.command_fingers(robot.info.finger_closed, sim.grip_force)
    hold(sim, parts["approach"].q[-1], s.closing_time(robot.info), False)
    held_after_close = sim.held()
    sim.carrying = True
    _follow_timed(sim, parts["lift"], False, True)
    hold(sim, parts["lift"].q[-1], s.hold_duration, True)
    return held_after_close, held_after_close and sim.held()  # lost on the lift: dropped, nothing to plan for


def _place_and_retract(sim, robot, parts: dict, settings: PickPlaceExecSettings) -> bool:
    """Carry, set down, release and retract: whether the object was still held before the release."""
    s = settings.execution
    _follow_timed(sim, parts["transfer"], False, True)
    hold(sim, parts["transfer"].q[-1], s.approach_settle, True)
    held_before_release = sim.held()
    sim.carrying = False
    sim.command_fingers(robot.info.finger_open, sim.grip_force)
    hold(sim, parts["transfer"].q[-1], settings.release_duration, True)
    _follow_timed(sim, parts["retract"], False, True)
    return held_before_release


def _outcome(
    finite: bool,
    stages: dict,
    collisions: dict,
    in_region: bool,
    at_rest: bool,
    tilt: float,
    yaw: float,
    moved: dict,
    check: PlaceCheck,
) -> Tuple[PlaceOutcome, str]:
    """The first test failed, in the order of the task, with its message (``collisions``: the
    penetrations when one was too deep, else empty)."""
    if not finite:
        return PlaceOutcome.unstable, "the simulation produced non-finite states"
    if not stages["close"]:
        return PlaceOutcome.missed, "the fingers closed without the object between them"
    if not stages["lift"]:
        return PlaceOutcome.dropped, "the object left the hand on the lift"
    if not stages["planned"]:
        return PlaceOutcome.not_planned, "no place plan for the grasp as executed"
    if not stages["release"]:
        return PlaceOutcome.dropped, "the object left the hand before the release"
    if collisions:
        name = max(collisions, key=collisions.get)
        return PlaceOutcome.collision, f"{name} penetration {collisions[name] * 1000:.1f} mm"
    if not at_rest:
        return PlaceOutcome.moving, "the object is still moving"
    if not in_region:
        return PlaceOutcome.outside_region, "the object is not inside the region"
    if tilt > check.tolerance_deg or (check.yaw_tolerance_deg is not None and yaw > check.yaw_tolerance_deg):
        return PlaceOutcome.toppled, f"orientation off by {tilt:.1f} deg (tilt), {yaw:.1f} deg (yaw)"
    worst = max(moved.values(), default=0.0)
    if worst > check.max_moved:
        return PlaceOutcome.moved_others, f"another object moved {worst * 100:.1f} cm"
    return PlaceOutcome.placed, ""
