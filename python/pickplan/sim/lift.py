"""The lift after a grasp (``execution``): straight up with the hand's orientation held, by
``ExecutionSettings.lift_height`` or, under an obstacle (a shelf's next board), by the headroom the
lift's waypoints find when probed kinematically in the simulation."""

from __future__ import annotations

from typing import List, Optional

import numpy as np

from pickplan.sim import scenes as scenes_mod
from pickplan.sim.hand_path import hand_path

#: m PyBullet's URDF importer gives the links' convex hulls as a collision margin (gUrdfDefaultCollisionMargin):
#: ``lift_headroom``'s distances can be up to this much shorter than the exact ones of the same hulls.
URDF_COLLISION_MARGIN = 0.001


def lift_path(robot, q0: np.ndarray, s, height: Optional[float] = None) -> np.ndarray:
    """Arm configurations (lift_waypoints + 1, dof) moving the hand straight up by ``height`` (default
    ``lift_height``), orientation held."""
    up = np.zeros((s.lift_waypoints, 3))
    up[:, 2] = (s.lift_height if height is None else height) * np.arange(1, s.lift_waypoints + 1) / s.lift_waypoints
    return hand_path(robot, q0, up, s.ik_damping)


def lift_headroom(sim, robot, q: np.ndarray, obstacles: List[int]) -> float:
    """How far (m, at most ``lift_height``) the hand can lift from ``q`` with the target carried
    rigidly: the lift's waypoints probed kinematically (robot and target reset to them, no physics
    step) against the ``obstacles`` bodies (``s``: the ``ExecutionSettings``); the lift ends at the
    last waypoint before the robot or the target comes closer to one than ``lift_clearance`` (and
    closer than it started: a wall it slides along is not above it). The world is put back as it was."""
    s, pb, c = sim.s, sim.pb, sim.c
    if not obstacles:
        return s.lift_height
    path = lift_path(robot, q, s)
    joints = sim.arm + sim.fingers
    target = sim.bodies[sim.target]
    saved_joints = [st[0] for st in pb.getJointStates(sim.robot, joints, physicsClientId=c)]
    pos, quat = pb.getBasePositionAndOrientation(target, physicsClientId=c)
    base = np.eye(4)
    base[:3, :3], base[:3, 3] = scenes_mod._quat_to_mat(quat), pos
    hand0 = robot.link_pose(q, robot.hand_link)

    def distances(qk) -> np.ndarray:  # per (body, obstacle) pair, inf beyond the clearance
        for j, v in zip(joints, qk):
            pb.resetJointState(sim.robot, j, float(v), physicsClientId=c)
        B = robot.link_pose(qk, robot.hand_link) @ np.linalg.inv(hand0) @ base
        pb.resetBasePositionAndOrientation(
            target, B[:3, 3].tolist(), scenes_mod._mat_to_quat(B[:3, :3]), physicsClientId=c
        )
        pb.performCollisionDetection(physicsClientId=c)
        return np.array(
            [
                min((p[8] for p in pb.getClosestPoints(body, ob, s.lift_clearance, physicsClientId=c)), default=np.inf)
                for body in (sim.robot, target)
                for ob in obstacles
            ]
        )

    try:
        start = distances(path[0])
        free = 0
        for k in range(1, len(path)):
            d = distances(path[k])
            if np.any((d < s.lift_clearance) & (d < start - 1e-4)):
                break
            free = k
    finally:
        for j, v in zip(joints, saved_joints):
            pb.resetJointState(sim.robot, j, v, physicsClientId=c)
        pb.resetBasePositionAndOrientation(target, pos, quat, physicsClientId=c)
    return s.lift_height * free / s.lift_waypoints
