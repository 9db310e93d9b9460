"""Replay of a planned pick-up in PyBullet (`pickplan pickup cases --replay NAME [--gui]`).

The mobile UR5 (assets/mobile_ur5.urdf, its planar base as two prismatic joints and a yaw joint)
is loaded with a fixed root; the case's obstacles are static spheres and the part a small box at
the grasp point. The stored trajectory (the JSON a plan dict carries: t, q) is played back
kinematically (joint states reset at every frame, no dynamics), optionally in the GUI in real time.

The replay is also an independent check of the native results: PyBullet's own forward kinematics
gives the tool pose at T2 (compared with the grasp pose), and its collision detection the least
distance between the robot's links and the obstacles over the frames (PyBullet uses the URDF's
collision shapes, not the body spheres of the NLP, so the figures differ by that approximation).
"""

from __future__ import annotations

import math
import time
from typing import Optional

import numpy as np

from pickplan.core.errors import InputError
from pickplan.core.io import read_json
from pickplan.pickup.nlp import cases
from pickplan.pickup.nlp import planner
from pickplan.pickup.nlp import problem_file


def replay(plan_dict: dict, problem, gui: bool = False, frames: int = 400, realtime: bool = False) -> dict:
    """Plays the plan back in a private PyBullet client against ``problem`` (a native
    PickupProblem, or a paper case's number); returns {"frames", "tool_error_T2"
    (position m, angle rad by PyBullet's FK), "min_distance" (m, robot links vs obstacles),
    "min_distance_t" (s)}. Raises ValueError for a plan without a solution."""
    from pickplan.sim.bullet import connect, pb

    if not plan_dict.get("stages_completed"):
        raise ValueError(f"plan has no solution to replay (status {plan_dict.get('status')!r})")
    if frames < 2:
        raise ValueError("frames must be >= 2")
    robot = planner.mobile_ur5()
    if isinstance(problem, int):  # a paper case by its number
        problem = cases.make_problem(robot, problem)
    cid = connect(gui)
    try:
        body = pb.loadURDF(robot.urdf_path, [0, 0, 0], [0, 0, 0, 1], useFixedBase=True, physicsClientId=cid)
        info = [
            pb.getJointInfo(body, j, physicsClientId=cid) for j in range(pb.getNumJoints(body, physicsClientId=cid))
        ]
        by_name = {inf[1].decode(): j for j, inf in enumerate(info)}  # joint name -> index
        link_of = {inf[12].decode(): j for j, inf in enumerate(info)}  # child link name -> index
        missing = [n for n in robot.joint_names if n not in by_name]
        if missing:
            raise RuntimeError(f"PyBullet model lacks joints {missing}")
        joints = [by_name[n] for n in robot.joint_names]
        obstacles = []
        for center, radius in problem.obstacles:
            shape = pb.createCollisionShape(pb.GEOM_SPHERE, radius=radius, physicsClientId=cid)
            vis = pb.createVisualShape(pb.GEOM_SPHERE, radius=radius, rgbaColor=[0.6, 0.6, 0.6, 1], physicsClientId=cid)
            obstacles.append(pb.createMultiBody(0, shape, vis, list(np.asarray(center, float)), physicsClientId=cid))
        grasp = np.asarray(problem.grasp_pose, float)
        part = pb.createVisualShape(
            pb.GEOM_BOX, halfExtents=[0.02, 0.02, 0.02], rgbaColor=[0.9, 0.3, 0.1, 1], physicsClientId=cid
        )
        pb.createMultiBody(0, -1, part, list(grasp[:3, 3]), physicsClientId=cid)
        t = np.linspace(0.0, float(plan_dict["T"]), frames)
        q, _ = cases.plan_states(plan_dict, t)
        tool = link_of["tool"]
        best, best_t = math.inf, 0.0
        for k in range(frames):
            for j, v in zip(joints, q[k]):
                pb.resetJointState(body, j, float(v), physicsClientId=cid)
            for ob in obstacles:  # getClosestPoints computes its own narrow phase
                for c in pb.getClosestPoints(body, ob, 1.0, physicsClientId=cid):
                    if c[8] < best:
                        best, best_t = c[8], float(t[k])
            if realtime and k + 1 < frames:
                time.sleep(float(t[k + 1] - t[k]))
        # Tool pose at T2 by PyBullet's forward kinematics.
        qT2 = cases.plan_states(plan_dict, [plan_dict["T2"]])[0][0]
        for j, v in zip(joints, qT2):
            pb.resetJointState(body, j, float(v), physicsClientId=cid)
        st = pb.getLinkState(body, tool, computeForwardKinematics=True, physicsClientId=cid)
        p = np.asarray(st[4])
        R = np.asarray(pb.getMatrixFromQuaternion(st[5])).reshape(3, 3)
        Rg, pg = grasp[:3, :3], grasp[:3, 3]
        ang = math.acos(max(-1.0, min(1.0, (np.trace(Rg.T @ R) - 1.0) / 2.0)))
        return {
            "frames": frames,
            "tool_error_T2": [float(np.linalg.norm(p - pg)), ang],
            "min_distance": float(best),
            "min_distance_t": best_t,
        }
    finally:
        pb.disconnect(physicsClientId=cid)


def replay_file(path: str, gui: bool = False, realtime: Optional[bool] = None) -> dict:
    """Replays a trajectory JSON written by `pickplan pickup cases` (its "case" field names the
    case) or `pickplan pickup plan` (its "problem" field holds the problem)."""
    d = read_json(path, "trajectory file")
    robot = planner.mobile_ur5()
    if "problem" in d:  # the replay needs the geometry only: any surface will do
        spec = problem_file.problem_from_dict(d["problem"], path)
        problem = problem_file.native_problem(robot, spec, planner.synthetic_rho(spec.sigma_r, spec.sigma_phi))
    elif "case" in d:
        problem = cases.make_problem(robot, int(d["case"]))
    else:
        raise InputError("expected a 'problem' or a 'case' key (a trajectory written by pickplan pickup)", path=path)
    return replay(d, problem, gui=gui, realtime=gui if realtime is None else realtime)
