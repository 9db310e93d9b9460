"""Executing a plan in PyBullet: follow the trajectory, close the gripper, lift, hold (OMG Sec. IV-A).

One call, one fresh DIRECT client (always disconnected): the scene is loaded with
``scenes.load_into_pybullet``, the robot (``ExecutionSettings.robot``: a described robot, the Panda by
default, with its gripper) is loaded at the scene's base and reset to ``trajectory[0]`` and then

1. **approach**: follows the (T, dof) joint trajectory at ``waypoint_dt`` per segment, densely
   interpolated at the 240 Hz control rate, under joint position control with the URDF's effort
   limits (the Panda's: 87 Nm joints 1-4, 12 Nm joints 5-7) and velocity feed-forward; segments that would exceed
   the joint speed limits are slowed down (a ``TimedTrajectory`` is followed at its own times, its
   velocities as the feed-forward, resampled to the control rate); contacts of the robot with every
   body but the target are recorded (max penetration per body);
2. **close**: both finger joints are commanded together to their closed value at ``finger_speed``, squeezing
   with ``finger_force`` N per finger (both by default the robot description's gripper ``speed`` and
   ``force``) for ``close_duration`` (by default: the fingers' travel at that speed, plus
   ``close_settle``); PyBullet ignores the URDF's ``<mimic>``, so a gear constraint makes the second
   finger follow the first (``couple_fingers``), as the real hand's mechanism does;
3. **lift**: the hand moves straight up by ``lift_height`` with its orientation held: joint targets
   come from the native damped-least-squares IK of the hand link (the arm joints),
   precomputed from the last waypoint (the arm's commanded pose while closing). Under a shelf's next
   board the lift is shorter: the lift's waypoints are first probed kinematically in the simulation
   (the robot at them, the target carried rigidly by the hand) against the scene's obstacles, and the
   lift stops ``lift_clearance`` short of the first one it would come closer to than that
   (``lift_headroom``); on a tabletop nothing is above and the lift is ``lift_height``;
4. **hold**: the final targets are held for ``hold_duration``.

"Execution success" (the paper's metric) = the target's centre of mass rose by at least
``success_lift_fraction`` of the lift (``lift_height``, or the headroom under an obstacle, which must
leave at least ``min_lift``) and the target is still between the fingers at the end.

Beside the status, ``ExecutionResult.slip`` / ``slip_rotation``: how far the target's centre of mass
moved and how far it turned in the hand from the closed grasp to the end of the hold (the grasp's own
test: a lifted target that slid 2 cm held by luck).

``ExecutionResult.status``: "lifted" (success); otherwise "collision" (the robot penetrated a
non-target object or the table deeper than ``collision_depth`` while following the plan),
"missed" (the target was not between the fingers after closing), "dropped" (it was, but it was not
lifted or not held at the end), "blocked" (obstacles above the grasp leave less than ``min_lift``), "invalid_trajectory" (waypoints outside the joint limits: not run),
"unstable" (the simulation diverged). Touches are recorded even when they are not collisions.

>>> result = execute_plan(scene, plan.trajectory)
>>> result.success, result.status, round(result.target_lift, 3)
(True, 'lifted', 0.15)
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.timing import TimedTrajectory
from pickplan.core.settings import Option
from pickplan.sim import scenes as scenes_mod
from pickplan.core import robots
from pickplan.core.description import load_description
from pickplan.sim.arm_sim import follow, hold, open_sim, segment_steps
from pickplan.sim.lift import lift_headroom, lift_path
from pickplan.sim import render as viz
from pickplan.sim.render import RecordSettings, save_frames, save_gif  # noqa: F401 - where callers find them


class ExecutionStatus(Option):
    """Every value ``ExecutionResult.status`` takes (see the module docstring)."""

    lifted, dropped, missed, collision, blocked = "lifted", "dropped", "missed", "collision", "blocked"
    invalid_trajectory, unstable = "invalid_trajectory", "unstable"


STATUSES = tuple(ExecutionStatus)


@dataclass(frozen=True)
class ExecutionSettings:
    """Simulation, controller, gripper and success-test settings; defaults model the real Panda."""

    robot: str = "panda"  # the robot executed: a shipped description's name or a .toml file
    # --- simulation
    time_step: float = 1.0 / 240.0  # s; also the control rate (a new target every step)
    solver_iterations: int = 100  # PyBullet constraint-solver iterations per step
    start_settle: float = 0.05  # s simulated with the robot held at trajectory[0] first
    # --- following the trajectory
    waypoint_dt: float = 0.1  # s per trajectory segment (the planner's default)
    respect_velocity_limits: bool = True  # stretch segments that exceed the URDF joint speed limits
    joint_limit_tolerance: float = 1e-3  # rad (m for fingers) beyond the limits -> "invalid_trajectory"
    approach_settle: float = 0.25  # s holding the last waypoint so the tracking lag vanishes
    # --- joint position control (PyBullet's motor: v_cmd = kp * err / dt + v_ff, force-limited)
    arm_forces: Optional[Tuple[float, ...]] = None  # Nm per arm joint; None: the URDF's effort limits
    position_gain: float = 0.1  # fraction of the position error corrected per step
    velocity_gain: float = 1.0  # weight of the velocity feed-forward term
    # --- gripper
    couple_fingers: bool = True  # a gear constraint keeps finger 2 = finger 1, like the real hand
    finger_force: Optional[float] = None  # N per finger when squeezing; None: the description's gripper.force
    finger_speed: Optional[float] = None  # m/s per finger while closing; None: the description's gripper.speed
    close_duration: Optional[float] = None  # s from the close command to the lift; None: the time the fingers
    #                                       take from open to closed at finger_speed, plus close_settle
    close_settle: float = 0.25  # s the squeeze settles for after the fingers could have closed
    finger_friction: float = 1.0  # lateral friction of the finger pads (the URDF's value)
    finger_spinning_friction: float = 0.1  # torsional friction of the pads (the URDF's value)
    object_friction: float = 0.8  # lateral friction of the objects (and the table)
    object_spinning_friction: float = 0.003
    # --- lift and hold
    lift_height: float = 0.15  # m, straight up (less where an obstacle is above: lift_headroom)
    lift_clearance: float = 0.01  # m the lifted robot and target keep from obstacles above
    min_lift: float = 0.05  # m; obstacles above that leave less make the lift "blocked"
    lift_duration: float = 1.5  # s (0.1 m/s)
    lift_waypoints: int = 30  # damped-least-squares waypoints along the lift
    ik_damping: float = 0.01  # DLS damping lambda
    hold_duration: float = 0.5  # s
    # --- success test and bookkeeping
    success_lift_fraction: float = 0.8  # the target must rise by this fraction of the lift
    hold_margin: float = 0.005  # m; the target is "between the fingers" within this of both
    min_finger_gap: float = 0.002  # m; fingers closer than this hold nothing
    collision_depth: float = 0.002  # m; deeper contact with a non-target body = "collision"

    def __post_init__(self):
        for name in ("time_step", "waypoint_dt", "finger_force", "finger_speed", "lift_duration", "ik_damping"):
            if getattr(self, name) is not None and not getattr(self, name) > 0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        for name in (
            "start_settle",
            "approach_settle",
            "close_duration",
            "close_settle",
            "hold_duration",
            "lift_height",
            "lift_clearance",
            "min_lift",
            "hold_margin",
            "min_finger_gap",
            "collision_depth",
            "joint_limit_tolerance",
        ):
            if getattr(self, name) is not None and not getattr(self, name) >= 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)}")
        if self.arm_forces is not None:
            arm = len(load_description(self.robot).arm_joints)
            if len(self.arm_forces) != arm or min(self.arm_forces) <= 0:
                raise ValueError(f"arm_forces: expected {arm} positive values ({self.robot}), got {self.arm_forces}")
        if not 0 < self.position_gain <= 1 or not 0 <= self.velocity_gain <= 1:
            raise ValueError("position_gain must be in (0, 1] and velocity_gain in [0, 1]")
        if not 0 < self.success_lift_fraction <= 1:
            raise ValueError(f"success_lift_fraction must be in (0, 1], got {self.success_lift_fraction}")
        if self.lift_waypoints < 1 or self.solver_iterations < 1:
            raise ValueError("lift_waypoints and solver_iterations must be >= 1")

    def closing_time(self, info) -> float:
        """Seconds from the close command to the lift for a robot (``RobotInfo``): ``close_duration``, else
        the fingers' travel from open to closed at the closing speed, plus ``close_settle``."""
        if self.close_duration is not None:
            return float(self.close_duration)
        speed = self.finger_speed if self.finger_speed is not None else info.grip_speed
        return abs(info.finger_travel) / float(speed) + self.close_settle


@dataclass
class ExecutionResult:
    success: bool  # execution success: lifted and still held
    status: ExecutionStatus
    target: str
    target_lift: float  # m, rise of the target's centre of mass
    target_final_pose: np.ndarray  # (4, 4) object frame -> world at the end
    contacts_during_approach: Dict[str, float]  # non-target body touched by the robot -> max penetration (m)
    max_penetration: float  # m, over contacts_during_approach (0 if none)
    collided: bool  # some penetration deeper than settings.collision_depth
    object_displacements: Dict[str, float]  # non-target object -> centre-of-mass travel (m) by the end
    target_pushed: float  # m, target centre-of-mass travel before the fingers closed
    held: bool  # target between the fingers at the end
    finger_gap: float  # m, opening between the finger pads at the end (0 if not run)
    tracking_error: float  # rad, worst arm joint error at the plan's waypoints
    sim_time: float  # simulated seconds
    steps: int
    seconds: float  # wall time of the whole call
    message: str = ""
    frames: List[np.ndarray] = field(default_factory=list, repr=False)
    # m the target's centre of mass moved in the hand from the closed grasp to the end of the hold (nan: not between
    # the fingers after closing)
    slip: float = float("nan")
    slip_rotation: float = float("nan")  # deg the target turned in the hand over the same time
    grip_force: float = 0.0  # N per finger the gripper squeezed with (settings or description)
    lift: float = float("nan")  # m the hand was lifted by (lift_height, or less under an obstacle)

    def to_dict(self) -> dict:
        """JSON-ready (frames left out)."""
        d = asdict(self)
        d.pop("frames")
        d["target_final_pose"] = np.asarray(self.target_final_pose).tolist()
        return d


# --- input checks --------------------------------------------------------------------------------
def _check_trajectory(trajectory, robot) -> np.ndarray:
    dof, arm = robot.dof, robot.info.arm_dof
    try:
        Q = np.array(trajectory, dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValueError(
            f"trajectory: expected a (T, {dof}) array of numbers, got {type(trajectory).__name__}"
        ) from exc
    if Q.ndim != 2 or Q.shape[1] != dof:
        raise ValueError(
            f"trajectory: expected shape (T, {dof}) ({arm} arm + {dof - arm} finger joints of "
            f"{robot.info.name}), got {Q.shape}"
        )
    if Q.shape[0] < 1:
        raise ValueError("trajectory: expected at least one waypoint, got 0")
    bad = np.argwhere(~np.isfinite(Q))
    if len(bad):
        raise ValueError(f"trajectory: contains NaN or infinity (first at waypoint {bad[0][0]}, joint {bad[0][1]})")
    return Q


# --- the entry point -----------------------------------------------------------------------------
def _outside_limits(scene, robot, Q: np.ndarray, over: np.ndarray, seconds: float) -> "ExecutionResult":
    """The result of a trajectory not run: its worst waypoint and joint outside the limits."""
    lo, hi = robot.lower_limits, robot.upper_limits
    k, j = np.unravel_index(int(np.argmax(over)), over.shape)
    return ExecutionResult(
        success=False,
        status=ExecutionStatus.invalid_trajectory,
        target=scene.target,
        target_lift=0.0,
        target_final_pose=np.asarray(scene.object(scene.target).pose, dtype=float).copy(),
        contacts_during_approach={},
        max_penetration=0.0,
        collided=False,
        object_displacements={o.name: 0.0 for o in scene.objects if o.name != scene.target},
        target_pushed=0.0,
        held=False,
        finger_gap=0.0,
        tracking_error=0.0,
        sim_time=0.0,
        steps=0,
        seconds=seconds,
        message=f"waypoint {k}, joint {robot.joint_names[j]}: {Q[k, j]:.4f} outside "
        f"[{lo[j]:.4f}, {hi[j]:.4f}] by {over[k, j]:.4f}",
    )


def _approach(sim, robot, Q: np.ndarray, timed, s: ExecutionSettings) -> None:
    """Settle at the start, follow the plan (timed, or at the velocity limits) and settle at its end."""
    sim.command_arm(Q[0], np.zeros(robot.dof))
    sim.command_fingers(Q[0, robot.info.arm_dof], sim.grip_force)
    for _ in range(int(round(s.start_settle / s.time_step))):
        sim.step(True)
    segments = [(s.time_step, 1)] * (len(Q) - 1) if timed is not None else segment_steps(Q, robot.velocity_limits, s)
    follow(sim, Q, segments, True, sim.grip_force, True, None if timed is None else timed.qd)
    hold(sim, Q[-1], s.approach_settle, True)


def _scene_com(scene, model, name: str) -> np.ndarray:
    """An object's centre of mass where the scene puts it (world frame)."""
    T = np.asarray(scene.object(name).pose, dtype=float)
    return T[:3, :3] @ model.com + T[:3, 3]


def _lift(sim, robot, q_grasp: np.ndarray, s: ExecutionSettings, height: float) -> None:
    """Lift by ``height`` (the headroom probed) in ``lift_duration``, then hold."""
    q_lift = q_grasp.copy()  # continue from the commanded pose, so the arm target does not jump
    q_lift[robot.info.arm_dof :] = sim.joint_positions()[robot.info.arm_dof :]
    lift = lift_path(robot, q_lift, s, height)
    seg = s.lift_duration / s.lift_waypoints
    follow(sim, lift, [(seg, max(1, int(round(seg / s.time_step))))] * s.lift_waypoints, False, sim.grip_force, False)
    hold(sim, lift[-1], s.hold_duration, False)


def _status(
    finite: bool,
    success: bool,
    contacts: dict,
    collided: bool,
    held_after_close: bool,
    held: bool,
    lift_m: float,
    height: float,
    s: ExecutionSettings,
) -> Tuple[ExecutionStatus, str]:
    """The execution's status and message: the first failure in the order of the task."""
    if not finite:
        status, msg = ExecutionStatus.unstable, "the simulation produced non-finite states"
    elif success:
        status, msg = ExecutionStatus.lifted, ""
    elif collided:
        worst = max(contacts, key=contacts.get)
        status, msg = (
            ExecutionStatus.collision,
            f"robot penetrated {worst} by {contacts[worst] * 1000:.1f} mm during the approach",
        )
    elif not held_after_close:
        status, msg = ExecutionStatus.missed, "the fingers closed without the target between them"
    elif height < s.min_lift:
        status, msg = (
            ExecutionStatus.blocked,
            (f"obstacles above the grasp leave a lift of {height:.3f} m (at least {s.min_lift:.3f} m)"),
        )
    else:
        status, msg = (
            ExecutionStatus.dropped,
            (f"target held after closing but at the end held={held}, lift {lift_m:.3f} m of {height:.3f} m"),
        )
    return status, msg


def execute_plan(
    scene: scenes_mod.Scene,
    trajectory,
    settings: ExecutionSettings = ExecutionSettings(),
    library: Optional[objects_mod.ObjectLibrary] = None,
    record: Optional[RecordSettings] = None,
) -> ExecutionResult:
    """Run ``trajectory`` ((T, dof) waypoints or a ``TimedTrajectory``) in ``scene`` with ``settings.robot``,
    grasp ``scene.target`` and lift it; see the module doc.

    Raises ValueError for a malformed trajectory (shape, NaN); a trajectory outside the joint limits
    is not run and reports status "invalid_trajectory". Deterministic for identical inputs.
    """
    from pickplan.sim.bullet import pb

    t_start = time.perf_counter()
    s = settings
    timed = trajectory if isinstance(trajectory, TimedTrajectory) else None
    if timed is not None and abs(timed.rate * s.time_step - 1.0) > 1e-9:
        timed = timed.resampled(1.0 / s.time_step)  # one sample per control step
    robot = robots.load_robot(s.robot, np.asarray(scene.robot_base, dtype=float))
    Q = _check_trajectory(trajectory if timed is None else timed.q, robot)
    if scene.target not in [o.name for o in scene.objects]:
        raise ValueError(f"scene target {scene.target!r} is not one of its objects")
    lo, hi = robot.lower_limits, robot.upper_limits
    over = np.maximum(lo - Q, Q - hi)
    models = {
        o.name: library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)
        for o in scene.objects
    }

    if np.max(over) > s.joint_limit_tolerance:
        return _outside_limits(scene, robot, Q, over, time.perf_counter() - t_start)
    Q = np.clip(Q, lo, hi)

    sim = open_sim(scene, robot, Q[0], s, models, record)
    client = sim.c
    try:
        # how far the plan's grasp can lift under what is above it (probed before anything moves)
        height = lift_headroom(sim, robot, Q[-1], [sim_id for name, sim_id in sim.obstacle_ids.items()])
        com0 = {name: _scene_com(scene, models[name], name) for name in sim.bodies}
        if record is not None:
            if record.colorize:
                viz.colorize(client, sim.bodies, sim.target)
            sim.capture()

        _approach(sim, robot, Q, timed, s)  # 1.
        target_pushed = float(np.linalg.norm(sim.com(scene.target) - com0[scene.target]))

        # 2. close (arm holds the last waypoint)
        sim.command_fingers(robot.info.finger_closed, sim.grip_force)
        hold(sim, Q[-1], s.closing_time(robot.info), False)
        held_after_close = sim.held()
        grasped = sim.in_hand()  # the target in the hand as the lift starts: slip is measured from here

        _lift(sim, robot, Q[-1], s, height)  # 3. lift, 4. hold

        # outcome
        T_final = scenes_mod.object_pose(client, sim.bodies[scene.target], models[scene.target])
        com_final = {name: sim.com(name) for name in sim.bodies}
        held = sim.held()
        gap = sim.finger_gap()
        slip, slip_rotation = (
            _slip(grasped, sim.in_hand(), models[scene.target].com)
            if held_after_close
            else (float("nan"), float("nan"))
        )
        if record is not None and sim.steps % record.every != 0:
            sim.capture()
        finite = np.all(np.isfinite(sim.joint_positions())) and all(np.all(np.isfinite(c)) for c in com_final.values())
    finally:
        pb.disconnect(client)

    lift_m = float(com_final[scene.target][2] - com0[scene.target][2]) if finite else float("nan")
    max_pen = max(sim.contacts.values(), default=0.0)
    collided = max_pen > s.collision_depth
    success = bool(finite and lifted_and_held(s, held, lift_m, height))
    status, msg = _status(finite, success, sim.contacts, collided, held_after_close, held, lift_m, height, s)
    return ExecutionResult(
        success=success,
        status=status,
        target=scene.target,
        target_lift=lift_m,
        target_final_pose=T_final,
        contacts_during_approach=dict(sorted(sim.contacts.items())),
        max_penetration=float(max_pen),
        collided=bool(collided),
        object_displacements={
            n: float(np.linalg.norm(com_final[n] - com0[n])) for n in sorted(sim.bodies) if n != scene.target
        },
        target_pushed=target_pushed,
        held=bool(held),
        finger_gap=gap,
        tracking_error=sim.tracking_error,
        sim_time=sim.steps * s.time_step,
        steps=sim.steps,
        seconds=time.perf_counter() - t_start,
        message=msg,
        frames=sim.frames,
        slip=slip,
        slip_rotation=slip_rotation,
        grip_force=sim.grip_force,
        lift=height,
    )


def lifted_and_held(s: ExecutionSettings, held: bool, lift_m: float, height: Optional[float] = None) -> bool:
    """Execution success: the target is between the fingers and rose by ``success_lift_fraction`` of the lift
    (``height``, default ``lift_height``), a lift of at least ``min_lift``."""
    height = s.lift_height if height is None else float(height)
    return bool(held and height >= s.min_lift and lift_m >= s.success_lift_fraction * height)


def _slip(before: np.ndarray, after: np.ndarray, com: np.ndarray) -> Tuple[float, float]:
    """How far (m) the centre of mass ``com`` (object frame) moved and how far (deg) the object turned
    between two of its poses in the hand."""
    c = np.append(np.asarray(com, float), 1.0)
    moved = float(np.linalg.norm((after @ c - before @ c)[:3]))
    cos = (np.trace(before[:3, :3].T @ after[:3, :3]) - 1.0) / 2.0
    return moved, float(np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))))
