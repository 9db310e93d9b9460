"""The PyBullet world of one execution and how the arm is driven in it: ``open_sim`` (the scene, the robot
at its start, frictions, the finger coupling), ``ArmSim`` (commands, steps, contacts watched, frames,
whether the target is held), ``follow`` (waypoints at given durations, feed-forward velocities) and
``hold``. Shared by the grasp execution (``execution``), pick and place (``pickplace_exec``) and moving
targets (``eval.moving``)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Dict, List, Optional, Tuple

import numpy as np

from pickplan.sim import bodies
from pickplan.sim import render as viz
from pickplan.sim import scenes as scenes_mod
from pickplan.sim.render import RecordSettings

if TYPE_CHECKING:
    from pickplan.sim.execution import ExecutionSettings


class ArmSim:
    """The PyBullet world of one execution: robot, bodies, models, frame recorder."""

    def __init__(self, pb, client, ids, models, scene, settings, record, info):
        self.pb, self.c, self.s, self.record, self.info = pb, client, settings, record, info
        # the gripper's squeeze and closing speed: the settings', else the robot description's
        self.grip_force = float(settings.finger_force if settings.finger_force is not None else info.grip_force)
        self.grip_speed = float(settings.finger_speed if settings.finger_speed is not None else info.grip_speed)
        self.robot = ids["robot"]
        self.names = {bid: name for name, bid in ids.items() if name != "robot"}
        self.bodies = {name: bid for name, bid in ids.items() if name in models}  # the objects (not obstacles)
        self.obstacle_ids = {o.name: ids[o.name] for o in scene.obstacles}  # furniture (the table apart)
        self.models = models
        self.target = scene.target
        joints = {
            pb.getJointInfo(self.robot, j, physicsClientId=client)[1].decode(): j
            for j in range(pb.getNumJoints(self.robot, physicsClientId=client))
        }
        links = {
            pb.getJointInfo(self.robot, j, physicsClientId=client)[12].decode(): j
            for j in range(pb.getNumJoints(self.robot, physicsClientId=client))
        }
        self.arm = [joints[name] for name in info.arm_joints]
        self.fingers = [joints[name] for name in info.finger_joints]
        self.finger_links = [links[name] for name in info.finger_links]
        self.hand = links[info.hand_link]
        self.forces = (
            list(settings.arm_forces)
            if settings.arm_forces is not None
            else [pb.getJointInfo(self.robot, j, physicsClientId=client)[10] for j in self.arm]
        )
        self.steps = 0
        self.frames: List[np.ndarray] = []
        self.contacts: Dict[str, float] = {}
        self.tracking_error = 0.0

    def com(self, name: str) -> np.ndarray:
        T = scenes_mod.object_pose(self.c, self.bodies[name], self.models[name])
        return T[:3, :3] @ self.models[name].com + T[:3, 3]

    def joint_positions(self) -> np.ndarray:
        states = self.pb.getJointStates(self.robot, self.arm + self.fingers, physicsClientId=self.c)
        return np.array([st[0] for st in states])

    def command_arm(self, q, v) -> None:
        s, n = self.s, len(self.arm)
        self.pb.setJointMotorControlArray(
            self.robot,
            self.arm,
            self.pb.POSITION_CONTROL,
            targetPositions=[float(x) for x in q[:n]],
            targetVelocities=[float(x) for x in v[:n]],
            forces=self.forces,
            positionGains=[s.position_gain] * n,
            velocityGains=[s.velocity_gain] * n,
            physicsClientId=self.c,
        )

    def command_fingers(self, value: float, force: float) -> None:
        """Every finger joint to ``value`` (a joint value: open, closed or between)."""
        for j in self.fingers:  # one command for both (and the gear constraint couples them)
            self.pb.setJointMotorControl2(
                self.robot,
                j,
                self.pb.POSITION_CONTROL,
                targetPosition=float(value),
                force=float(force),
                maxVelocity=self.grip_speed,
                physicsClientId=self.c,
            )

    def step(self, watch_contacts: bool = False) -> None:
        self.pb.stepSimulation(physicsClientId=self.c)
        self.steps += 1
        if watch_contacts:
            for cp in self.pb.getContactPoints(bodyA=self.robot, physicsClientId=self.c):
                other = self.names.get(cp[2])
                if other is None or other == self.target or cp[8] > 0:
                    continue
                self.contacts[other] = max(self.contacts.get(other, 0.0), -float(cp[8]))
        if self.record is not None and self.steps % self.record.every == 0:
            self.capture()

    def capture(self) -> None:

        r = self.record
        if len(self.frames) >= r.max_frames:
            self.frames.pop()  # keep the latest in the last slot
        self.frames.append(viz.render(self.c, r.width, r.height, r.target, r.distance, r.yaw, r.pitch))

    def finger_gap(self) -> float:
        """Opening between the pads: the open width less each finger's travel towards closed (the Panda:
        the sum of its two finger joint positions)."""
        states = self.pb.getJointStates(self.robot, self.fingers, physicsClientId=self.c)
        return float(self.info.max_opening - sum(abs(st[0] - self.info.finger_open) for st in states))

    def in_hand(self) -> np.ndarray:
        """The target's pose (its model frame) in the hand link's frame."""
        state = self.pb.getLinkState(self.robot, self.hand, computeForwardKinematics=True, physicsClientId=self.c)
        H = np.eye(4)
        H[:3, :3], H[:3, 3] = scenes_mod._quat_to_mat(state[5]), state[4]
        return np.linalg.inv(H) @ scenes_mod.object_pose(self.c, self.bodies[self.target], self.models[self.target])

    def held(self) -> bool:
        """The target touches (within hold_margin) both fingers, and the fingers are not shut."""
        if self.finger_gap() < self.s.min_finger_gap:
            return False
        for link in self.finger_links:
            if not self.pb.getClosestPoints(
                self.robot, self.bodies[self.target], self.s.hold_margin, linkIndexA=link, physicsClientId=self.c
            ):
                return False
        return True


def segment_steps(Q: np.ndarray, vmax: np.ndarray, s: ExecutionSettings) -> List[Tuple[float, int]]:
    """(duration, steps) per segment; stretched where a joint would exceed its speed limit."""
    out = []
    for k in range(len(Q) - 1):
        d = s.waypoint_dt
        if s.respect_velocity_limits:
            d = max(d, float(np.max(np.abs(Q[k + 1] - Q[k]) / vmax)))
        out.append((d, max(1, int(round(d / s.time_step)))))
    return out


def follow(
    sim: ArmSim,
    Q: np.ndarray,
    segments,
    fingers_from_plan: bool,
    finger_force: float,
    watch: bool,
    V: Optional[np.ndarray] = None,
) -> None:
    for k, (d, n) in enumerate(segments):
        v = (Q[k + 1] - Q[k]) / d if V is None else V[k + 1]  # feed-forward: the timed velocities if given
        for i in range(1, n + 1):
            q = Q[k] + (i / n) * (Q[k + 1] - Q[k])
            sim.command_arm(q, v)
            if fingers_from_plan:
                sim.command_fingers(q[len(sim.arm)], finger_force)
            sim.step(watch)
        if watch:  # tracking error of the arm at each waypoint of the plan
            n = len(sim.arm)
            err = float(np.max(np.abs(sim.joint_positions()[:n] - Q[k + 1, :n])))
            sim.tracking_error = max(sim.tracking_error, err)


def hold(sim: ArmSim, q: np.ndarray, seconds: float, watch: bool) -> None:
    zero = np.zeros(len(q))
    sim.command_arm(q, zero)
    for _ in range(int(round(seconds / sim.s.time_step))):
        sim.step(watch)


def open_sim(
    scene: scenes_mod.Scene,
    robot,
    q0: np.ndarray,
    s: ExecutionSettings,
    models: dict,
    record: Optional[RecordSettings] = None,
    sim_class=None,
) -> "ArmSim":
    """A fresh DIRECT client with the scene's table and objects and ``robot`` at ``q0``, frictions and
    the finger coupling set (the caller disconnects ``sim.c``). ``sim_class``: a ``ArmSim`` subclass."""
    from pickplan.sim.bullet import pb

    client, ids = bodies.open_world(scene, robot, q0, models, s.time_step, s.solver_iterations)
    try:
        sim = (sim_class or ArmSim)(pb, client, ids, models, scene, s, record, robot.info)
        for link in sim.finger_links:
            pb.changeDynamics(
                sim.robot,
                link,
                lateralFriction=s.finger_friction,
                spinningFriction=s.finger_spinning_friction,
                frictionAnchor=1,
                physicsClientId=client,
            )
        for name, bid in ids.items():
            if name != "robot":
                own = getattr(models.get(name), "friction", None)  # an object's own friction, where it has one
                pb.changeDynamics(
                    bid,
                    -1,
                    lateralFriction=s.object_friction if own is None else own,
                    spinningFriction=s.object_spinning_friction,
                    physicsClientId=client,
                )
        if s.couple_fingers:  # PyBullet ignores <mimic>: couple the fingers' motion with a gear constraint
            gear = pb.createConstraint(
                sim.robot,
                sim.fingers[0],
                sim.robot,
                sim.fingers[1],
                pb.JOINT_GEAR,
                [1, 0, 0],
                [0, 0, 0],
                [0, 0, 0],
                physicsClientId=client,
            )
            pb.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=2 * sim.grip_force, physicsClientId=client)
    except BaseException:
        pb.disconnect(client)
        raise
    return sim
