"""The PyBullet world of the physics grasp tests (``physics``): a free-floating hand (any described
gripper; the Panda's by default) carried by a
constraint, its coupled fingers, the object (and optionally the table), in one DIRECT client per process;
plus the in-hand motion measures and the motion profiles the tests use."""

from __future__ import annotations

import numpy as np

from pickplan.core.description import RobotInfo
from pickplan.core.panda import PANDA
from pickplan.omg.grasps.hand import hand_urdf_path
from pickplan.sim.scenes import _mat_to_quat, _quat_to_mat, add_object_body

_CLIENT = {"id": None}  # one DIRECT client per process, reused by every test it runs


class SimObject:
    """What ``scenes.add_object_body`` needs of a model: cheap to send to worker processes."""

    def __init__(self, model):
        self.name, self.mass = model.name, float(model.mass)
        self.com, self.inertia = np.asarray(model.com, float), np.asarray(model.inertia, float)
        self._path = model.collision_obj_path()

    def collision_obj_path(self) -> str:
        return self._path


def _client() -> int:
    from pickplan.sim.bullet import connect, pb

    if _CLIENT["id"] is None or not pb.isConnected(_CLIENT["id"]):
        _CLIENT["id"] = connect()
    return _CLIENT["id"]


def _pose_of(cid: int, body: int) -> np.ndarray:
    from pickplan.sim.bullet import pb

    pos, quat = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = _quat_to_mat(quat), pos
    return T


class HandWorld:
    """A reset world with the hand (base = the hand link, carried by a fixed constraint) and the object."""

    def __init__(
        self,
        s,
        obj: SimObject,
        T_hand: np.ndarray,
        T_obj: np.ndarray,
        gravity: bool,
        table: bool = False,
        table_friction: float = 0.8,
        gripper: RobotInfo = PANDA,
    ):
        from pickplan.sim.bullet import pb

        self.pb, self.s, self.gripper = pb, s, gripper
        # the squeeze and the closing speed: the settings', else the gripper description's
        self.force = float(s.finger_force if s.finger_force is not None else gripper.grip_force)
        self.speed = float(s.finger_speed if s.finger_speed is not None else gripper.grip_speed)
        cid = self.cid = _client()
        pb.resetSimulation(physicsClientId=cid)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=s.time_step,
            numSolverIterations=s.solver_iterations,
            deterministicOverlappingPairs=1,
            physicsClientId=cid,
        )
        self.gravity(gravity)
        self.table = -1
        if table:  # the scenes' table: a box whose top face is z = 0
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.5, 0.5, 0.025], physicsClientId=cid)
            self.table = pb.createMultiBody(0.0, shape, basePosition=[0, 0, -0.025], physicsClientId=cid)
            pb.changeDynamics(self.table, -1, lateralFriction=table_friction, physicsClientId=cid)
        self.hand = pb.loadURDF(
            hand_urdf_path(False, gripper),
            T_hand[:3, 3].tolist(),
            _mat_to_quat(T_hand[:3, :3]),
            useFixedBase=False,
            flags=pb.URDF_USE_INERTIA_FROM_FILE,
            physicsClientId=cid,
        )
        names = [
            pb.getJointInfo(self.hand, j, physicsClientId=cid)[1].decode()
            for j in range(pb.getNumJoints(self.hand, physicsClientId=cid))
        ]
        self.fingers = [names.index(name) for name in gripper.finger_joints]
        for j in self.fingers:
            pb.changeDynamics(
                self.hand,
                j,
                lateralFriction=s.pad_friction,
                spinningFriction=s.pad_spinning_friction,
                physicsClientId=cid,
            )
            pb.resetJointState(self.hand, j, gripper.finger_open, physicsClientId=cid)
            pb.setJointMotorControl2(
                self.hand,
                j,
                pb.POSITION_CONTROL,
                targetPosition=gripper.finger_open,
                force=self.force,
                physicsClientId=cid,
            )
        if getattr(s, "couple_fingers", False):
            # PyBullet ignores the URDF's <mimic>: without the gear two force-limited fingers let a
            # load along the closing axis push the object (and both fingers) sideways in the hand
            # (as execution.py, and the Franka hand's single motor).
            gear = pb.createConstraint(
                self.hand,
                self.fingers[0],
                self.hand,
                self.fingers[1],
                pb.JOINT_GEAR,
                [1, 0, 0],
                [0, 0, 0],
                [0, 0, 0],
                physicsClientId=cid,
            )
            pb.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=2 * self.force, physicsClientId=cid)
        # the base pose PyBullet reports (and constrains) is the inertial frame: keep its offset
        T_in = np.eye(4)
        info = pb.getDynamicsInfo(self.hand, -1, physicsClientId=cid)
        T_in[:3, :3], T_in[:3, 3] = _quat_to_mat(info[4]), info[3]
        self.T_inertial = T_in
        self.T_hand0 = np.asarray(T_hand, float)
        target = T_hand @ T_in
        self.drive = pb.createConstraint(
            self.hand,
            -1,
            -1,
            -1,
            pb.JOINT_FIXED,
            [0, 0, 0],
            [0, 0, 0],
            target[:3, 3].tolist(),
            childFrameOrientation=_mat_to_quat(target[:3, :3]),
            physicsClientId=cid,
        )
        pb.changeConstraint(self.drive, maxForce=s.hand_force, physicsClientId=cid)
        self.body = add_object_body(cid, obj, T_obj, friction=s.object_friction)

    def approach(self, distance: float, seconds: float) -> None:
        """Put the open hand ``distance`` back along its approach axis and move it in to where it was
        made (a smooth step over ``seconds``): what the approach does to the object (a finger meeting it
        pushes it) happens before the grasp closes."""
        pb, axis = self.pb, self.T_hand0[:3, :3] @ self.gripper.grasp_frame[:3, 2]

        def path(u: float) -> np.ndarray:
            T = self.T_hand0.copy()
            T[:3, 3] -= (1.0 - smooth_step(u)) * distance * axis
            return T

        start = path(0.0) @ self.T_inertial
        pb.resetBasePositionAndOrientation(
            self.hand, start[:3, 3].tolist(), _mat_to_quat(start[:3, :3]), physicsClientId=self.cid
        )
        self.move_hand(path(0.0))
        self.step(seconds, path)

    def gravity(self, on: bool) -> None:
        self.pb.setGravity(0, 0, -9.81 if on else 0.0, physicsClientId=self.cid)

    def move_hand(self, T_hand: np.ndarray) -> None:
        t = T_hand @ self.T_inertial
        self.pb.changeConstraint(
            self.drive,
            jointChildPivot=t[:3, 3].tolist(),
            jointChildFrameOrientation=_mat_to_quat(t[:3, :3]),
            maxForce=self.s.hand_force,
            physicsClientId=self.cid,
        )

    def close(self) -> None:
        for j in self.fingers:
            self.pb.setJointMotorControl2(
                self.hand,
                j,
                self.pb.POSITION_CONTROL,
                targetPosition=self.gripper.finger_closed,
                force=self.force,
                maxVelocity=self.speed,
                physicsClientId=self.cid,
            )

    def step(self, seconds: float, hand_path=None) -> None:
        n = int(round(seconds / self.s.time_step))
        for i in range(n):
            if hand_path is not None:
                self.move_hand(hand_path((i + 1) / n))
            self.pb.stepSimulation(physicsClientId=self.cid)

    def gap(self) -> float:
        """Opening between the pads: the open width less each finger's travel towards closed."""
        travel = sum(
            abs(self.pb.getJointState(self.hand, j, physicsClientId=self.cid)[0] - self.gripper.finger_open)
            for j in self.fingers
        )
        return self.gripper.max_opening - travel

    def hand_pose(self) -> np.ndarray:
        return _pose_of(self.cid, self.hand) @ np.linalg.inv(self.T_inertial)

    def body_pose(self) -> np.ndarray:
        return _pose_of(self.cid, self.body)  # the body's inertial frame: fine for relative motion

    def touches(self, other: int, distance: float) -> bool:
        return bool(self.pb.getClosestPoints(self.hand, other, distance, physicsClientId=self.cid))


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(axis * angle).as_matrix()


def smooth_step(u: float) -> float:
    return u * u * (3.0 - 2.0 * u)


def quintic_step(u: float) -> float:
    return u**3 * (10.0 - 15.0 * u + 6.0 * u * u)


def turned_about(T: np.ndarray, pivot: np.ndarray, axis: np.ndarray, angle: float) -> np.ndarray:
    """``T`` rotated by ``angle`` about the world ``axis`` through the world point ``pivot``."""
    R = np.eye(4)
    R[:3, :3] = _rot(axis, angle)
    R[:3, 3] = pivot[:3] - R[:3, :3] @ pivot[:3]
    return R @ T


def rotation_deg(R: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


class InHand:
    """The object's pose in the hand at a reference instant, and how far it has moved since."""

    def __init__(self, world: "HandWorld"):
        self.world = world
        self.ref = np.linalg.inv(world.hand_pose()) @ world.body_pose()

    def now(self) -> np.ndarray:
        return np.linalg.inv(self.world.hand_pose()) @ self.world.body_pose()

    def rotation(self) -> float:
        """Degrees the object turned relative to the hand."""
        return rotation_deg(self.ref[:3, :3].T @ self.now()[:3, :3])

    def moved(self, p_body: np.ndarray) -> float:
        """Metres the body-frame point ``p_body`` moved relative to the hand."""
        return float(np.linalg.norm((self.now() @ p_body - self.ref @ p_body)[:3]))
