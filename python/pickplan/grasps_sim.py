"""Physics-verified grasps (the OMG paper's "Simulated" set, after Eppner et al. [12]) and an
independent lift test, in PyBullet DIRECT with a free-floating Panda hand.

Shake test (what ``simulated_grasps`` keeps): antipodal candidates; the hand is held in space with
its approach axis pointing down, the object free with gravity off; the fingers close; gravity comes
on; the hand shakes (a translation along a random direction, then a rotation about a random axis
through the pads). A grasp holds when the fingers did not close on nothing and the object point
that sat between the pads drifted less than ``max_drift`` relative to the hand.

Lift test (``lift_test``, for evaluation): the object rests on a table in its most stable pose,
gravity on throughout; the open hand is placed at the grasp (grasps whose hand touches the table
are not applicable), closes and lifts; success when the object rose with the hand.

Every candidate runs from a fresh ``resetSimulation`` with its own seed, so results do not depend on
the number of workers or the order of the runs. ``simulated_grasps`` caches its result on disk.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np

from . import grasps as G
from .io import atomic_open
from .scenes import _mat_to_quat, _quat_to_mat, add_object_body

CACHE_ENV = "PICKPLAN_CACHE_DIR"
CACHE_VERSION = 1
_FINGERS = (0, 1)  # joint indices of finger_joint1/2 in the hand URDF


@dataclass(frozen=True)
class SimSettings:
    """Physics and shake-test settings (the candidates come from ``grasps.AntipodalSettings``)."""

    time_step: float = 1.0 / 240.0
    solver_iterations: int = 50
    finger_force: float = 35.0     # N per finger (the Franka hand: 70 N continuous in total)
    finger_speed: float = 0.1      # m/s per finger
    close_time: float = 0.5        # s, gravity off
    settle_time: float = 0.25      # s with gravity on before shaking
    shake_time: float = 1.0        # s: first half translation, second half rotation
    shake_frequency: float = 2.0   # Hz
    shake_amplitude: float = 0.02  # m (peak acceleration 3.2 m/s^2 at 2 Hz)
    shake_angle: float = 0.35      # rad (about 20 deg)
    max_drift: float = 0.02        # m: the held object point may move this much relative to the hand
    min_gap: float = 0.001         # m between the pads at the end: less = closed on nothing
    object_friction: float = 0.8
    pad_friction: float = 1.0      # the Panda URDF's lateral friction (Bullet multiplies the two bodies')
    pad_spinning_friction: float = 0.005  # m; the URDF's 0.1 would let a pinch resist any torque
    hand_force: float = 2000.0     # N of the constraint that carries the hand


@dataclass(frozen=True)
class LiftSettings:
    time_step: float = 1.0 / 240.0
    solver_iterations: int = 50
    finger_force: float = 35.0
    finger_speed: float = 0.1
    close_time: float = 0.5
    lift_height: float = 0.1       # m
    lift_time: float = 1.0         # s (smooth-step profile)
    hold_time: float = 0.5
    min_rise: float = 0.7          # success: the object rose by at least this fraction of the lift
    min_gap: float = 0.001
    table_clearance: float = 0.002  # m: an open hand closer than this to the table is not applicable
    object_friction: float = 0.8
    pad_friction: float = 1.0
    pad_spinning_friction: float = 0.005
    table_friction: float = 0.8
    hand_force: float = 2000.0
    rest_index: Optional[int] = None  # resting pose; None: the most stable one where the hand clears the table


class _SimObject:
    """What ``scenes.add_object_body`` needs of a model: cheap to send to worker processes."""

    def __init__(self, model):
        self.name, self.mass = model.name, float(model.mass)
        self.com, self.inertia = np.asarray(model.com, float), np.asarray(model.inertia, float)
        self._path = model.collision_obj_path()

    def collision_obj_path(self) -> str:
        return self._path


# --- one PyBullet world per process -----------------------------------------------------------------
_CLIENT = {"id": None}


def _client() -> int:
    import pybullet as pb

    if _CLIENT["id"] is None or not pb.isConnected(_CLIENT["id"]):
        _CLIENT["id"] = pb.connect(pb.DIRECT)
    return _CLIENT["id"]


def _pose_of(cid: int, body: int) -> np.ndarray:
    import pybullet as pb

    pos, quat = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = _quat_to_mat(quat), pos
    return T


class _World:
    """A reset world with the hand (base = panda_hand, carried by a fixed constraint) and the object."""

    def __init__(self, s, obj: _SimObject, T_hand: np.ndarray, T_obj: np.ndarray, gravity: bool,
                 table: bool = False, table_friction: float = 0.8):
        import pybullet as pb

        self.pb, self.s = pb, s
        cid = self.cid = _client()
        pb.resetSimulation(physicsClientId=cid)
        pb.setPhysicsEngineParameter(fixedTimeStep=s.time_step, numSolverIterations=s.solver_iterations,
                                     deterministicOverlappingPairs=1, physicsClientId=cid)
        self.gravity(gravity)
        self.table = -1
        if table:  # the scenes' table: a box whose top face is z = 0
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[0.5, 0.5, 0.025], physicsClientId=cid)
            self.table = pb.createMultiBody(0.0, shape, basePosition=[0, 0, -0.025], physicsClientId=cid)
            pb.changeDynamics(self.table, -1, lateralFriction=table_friction, physicsClientId=cid)
        self.hand = pb.loadURDF(G.hand_urdf_path(False), T_hand[:3, 3].tolist(), _mat_to_quat(T_hand[:3, :3]),
                                useFixedBase=False, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=cid)
        for j in _FINGERS:
            pb.changeDynamics(self.hand, j, lateralFriction=s.pad_friction,
                              spinningFriction=s.pad_spinning_friction, physicsClientId=cid)
            pb.resetJointState(self.hand, j, G.FINGER_OPEN, physicsClientId=cid)
            pb.setJointMotorControl2(self.hand, j, pb.POSITION_CONTROL, targetPosition=G.FINGER_OPEN,
                                     force=s.finger_force, physicsClientId=cid)
        # the base pose PyBullet reports (and constrains) is the inertial frame: keep its offset
        T_in = np.eye(4)
        info = pb.getDynamicsInfo(self.hand, -1, physicsClientId=cid)
        T_in[:3, :3], T_in[:3, 3] = _quat_to_mat(info[4]), info[3]
        self.T_inertial = T_in
        self.T_hand0 = np.asarray(T_hand, float)
        target = T_hand @ T_in
        self.drive = pb.createConstraint(self.hand, -1, -1, -1, pb.JOINT_FIXED, [0, 0, 0], [0, 0, 0],
                                         target[:3, 3].tolist(), childFrameOrientation=_mat_to_quat(target[:3, :3]),
                                         physicsClientId=cid)
        pb.changeConstraint(self.drive, maxForce=s.hand_force, physicsClientId=cid)
        self.body = add_object_body(cid, obj, T_obj, friction=s.object_friction)

    def gravity(self, on: bool) -> None:
        self.pb.setGravity(0, 0, -9.81 if on else 0.0, physicsClientId=self.cid)

    def move_hand(self, T_hand: np.ndarray) -> None:
        t = T_hand @ self.T_inertial
        self.pb.changeConstraint(self.drive, jointChildPivot=t[:3, 3].tolist(),
                                 jointChildFrameOrientation=_mat_to_quat(t[:3, :3]), maxForce=self.s.hand_force,
                                 physicsClientId=self.cid)

    def close(self) -> None:
        for j in _FINGERS:
            self.pb.setJointMotorControl2(self.hand, j, self.pb.POSITION_CONTROL, targetPosition=0.0,
                                          force=self.s.finger_force, maxVelocity=self.s.finger_speed,
                                          physicsClientId=self.cid)

    def step(self, seconds: float, hand_path=None) -> None:
        n = int(round(seconds / self.s.time_step))
        for i in range(n):
            if hand_path is not None:
                self.move_hand(hand_path((i + 1) / n))
            self.pb.stepSimulation(physicsClientId=self.cid)

    def gap(self) -> float:
        return sum(self.pb.getJointState(self.hand, j, physicsClientId=self.cid)[0] for j in _FINGERS)

    def hand_pose(self) -> np.ndarray:
        return _pose_of(self.cid, self.hand) @ np.linalg.inv(self.T_inertial)

    def body_pose(self) -> np.ndarray:
        return _pose_of(self.cid, self.body)  # the body's inertial frame: fine for relative motion

    def touches(self, other: int, distance: float) -> bool:
        return bool(self.pb.getClosestPoints(self.hand, other, distance, physicsClientId=self.cid))


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(axis * angle).as_matrix()


def shake_test(obj, grasp: np.ndarray, seed: int, settings: SimSettings = SimSettings()) -> dict:
    """One shake test of a hand pose ``grasp`` (object frame). Returns held, drift (m), gap (m)."""
    s = settings
    obj = obj if isinstance(obj, _SimObject) else _SimObject(obj)
    rng = np.random.default_rng(seed)
    T_hand = np.eye(4)
    T_hand[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach pointing down: gravity pulls out of the hand
    T_hand[2, 3] = 0.5
    world = _World(s, obj, T_hand, T_hand @ np.linalg.inv(grasp), gravity=False)
    world.close()
    world.step(s.close_time)
    world.gravity(True)
    world.step(s.settle_time)
    # the object point between the pads, in the body frame, and where it sits in the hand
    pad = np.array([0.0, 0.0, G.PAD_DEPTH, 1.0])
    H0, B0 = world.hand_pose(), world.body_pose()
    p_body = np.linalg.inv(B0) @ H0 @ pad
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    half, w = 0.5 * s.shake_time, 2 * np.pi * s.shake_frequency
    pivot = H0 @ pad

    def translate(u):
        T = H0.copy()
        T[:3, 3] += d * s.shake_amplitude * math.sin(w * half * u)
        return T

    def rotate(u):
        T = np.eye(4)
        T[:3, :3] = _rot(axis, s.shake_angle * math.sin(w * half * u))
        T[:3, 3] = pivot[:3] - T[:3, :3] @ pivot[:3]
        return T @ H0

    world.step(half, translate)
    world.step(half, rotate)
    world.step(0.1, lambda u: H0)
    H1, B1 = world.hand_pose(), world.body_pose()
    drift = float(np.linalg.norm((np.linalg.inv(H1) @ B1 @ p_body - pad)[:3]))
    gap = world.gap()
    return {"held": bool(gap > s.min_gap and drift < s.max_drift), "drift": drift, "gap": gap}


def close_on_object(model, grasp: np.ndarray, settings: SimSettings = SimSettings()) -> dict:
    """Close the hand at ``grasp`` (object frame) on the free object with gravity off: the final
    pad gap (m) and whether each finger ends touching the object ("left", "right")."""
    obj = model if isinstance(model, _SimObject) else _SimObject(model)
    world = _World(settings, obj, np.eye(4), np.linalg.inv(G.check_grasps([grasp])[0]), gravity=False)
    world.close()
    world.step(settings.close_time)
    touch = [bool(world.pb.getContactPoints(world.hand, world.body, j, physicsClientId=world.cid))
             for j in _FINGERS]
    return {"gap": world.gap(), "left": touch[0], "right": touch[1]}


def _shake_chunk(obj: _SimObject, poses: np.ndarray, seeds, settings: SimSettings):
    """Worker entry point (module level so ``spawn`` can import it)."""
    return [shake_test(obj, T, int(sd), settings) for T, sd in zip(poses, seeds)]


def lift_test(model, poses, settings: LiftSettings = LiftSettings()) -> np.ndarray:
    """Table lift test of hand poses (object frame): (N,) int8, 1 lifted, 0 failed, -1 not
    applicable (the open hand touches the table at the grasp in every resting pose tried: the
    ``rest_index`` one, or by default the three most stable ones, first clear one used).
    Independent of the shake test: table, gravity throughout, lift instead of shaking."""
    s = settings
    poses = G.check_grasps(poses)
    obj = _SimObject(model)
    rests = [model.resting_poses[s.rest_index]] if s.rest_index is not None else model.resting_poses[:3]
    out = np.zeros(len(poses), dtype=np.int8)
    for i, T in enumerate(poses):
        for rest in rests:
            rest = np.asarray(rest, float)
            world = _World(s, obj, rest @ T, rest, gravity=True, table=True, table_friction=s.table_friction)
            if not world.touches(world.table, s.table_clearance):
                break
        else:
            out[i] = -1
            continue
        z0 = world.body_pose()[2, 3]
        H0 = world.hand_pose()
        world.close()
        world.step(s.close_time, lambda u: H0)

        def lift(u):
            T_ = H0.copy()
            T_[2, 3] += s.lift_height * (3 * u * u - 2 * u ** 3)
            return T_

        world.step(s.lift_time, lift)
        world.step(s.hold_time, lambda u: lift(1.0))
        rise = world.body_pose()[2, 3] - z0
        out[i] = int(world.gap() > s.min_gap and rise >= s.min_rise * s.lift_height)
    return out


def lift_rate(results: np.ndarray) -> float:
    """Success rate over the applicable grasps (nan when none is)."""
    r = np.asarray(results)
    ok = r >= 0
    return float(r[ok].mean()) if ok.any() else float("nan")


# --- the "Simulated" set ------------------------------------------------------------------------------
class _Progress:
    def __init__(self, total: int, desc: str, enabled: bool):
        self.total, self.desc, self.enabled, self.count, self.t0 = max(total, 1), desc, enabled, 0, time.time()

    def update(self, k: int) -> None:
        self.count += k
        if self.enabled:
            f = min(self.count / self.total, 1.0)
            sys.stderr.write(f"\r{self.desc} [{'#' * int(24 * f):<24}] {self.count}/{self.total} "
                             f"{time.time() - self.t0:.0f}s" + ("\n" if f >= 1 else ""))
            sys.stderr.flush()


def cache_dir() -> str:
    root = os.environ.get(CACHE_ENV) or os.path.join(os.path.expanduser("~"), ".cache", "pickplan")
    return os.path.join(root, "grasps")


def _cache_path(model, n, seed, settings, antipodal, oversample, max_rounds) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(model.mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(model.mesh.faces, dtype=np.int64).tobytes())
    with open(model.collision_obj_path(), "rb") as f:
        h.update(f.read())
    h.update(json.dumps({"v": CACHE_VERSION, "mass": float(model.mass), "sim": asdict(settings),
                         "antipodal": asdict(antipodal), "n": int(n), "seed": int(seed),
                         "oversample": float(oversample), "rounds": int(max_rounds)}, sort_keys=True).encode())
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in model.name)
    return os.path.join(cache_dir(), f"{safe}-simulated-{h.hexdigest()[:24]}.npz")


def simulated_grasps(model, n: int = 100, seed: int = 0, workers: int = 1,
                     settings: SimSettings = SimSettings(),
                     antipodal: G.AntipodalSettings = G.AntipodalSettings(), oversample: float = 3.0,
                     max_rounds: int = 4, progress: Optional[bool] = None, cache: bool = True) -> G.GraspSet:
    """The "Simulated" set: antipodal candidates (``ceil(n * oversample)`` per round, seeded per
    round) that hold in the shake test, first ``n`` in candidate order; fewer (with a warning)
    when ``max_rounds`` rounds do not give ``n``. ``workers`` > 1 runs worker processes (spawn);
    the result does not depend on it. ``scores`` = 1 - drift / max_drift; ``info`` carries the
    antipodal contacts, normals, widths and drifts, plus "tested" (candidates simulated, 0-d).
    Cached in ``$PICKPLAN_CACHE_DIR/grasps`` (default ``~/.cache/pickplan/grasps``)."""
    G._check_count(n, seed)
    if int(workers) < 1:
        raise ValueError(f"workers: expected >= 1, got {workers}")
    path = _cache_path(model, n, seed, settings, antipodal, oversample, max_rounds) if cache else None
    if path and os.path.isfile(path):
        with np.load(path) as z:
            info = {k[5:]: z[k] for k in z.files if k.startswith("info_")}
            return G.GraspSet("simulated", z["poses"], model.name, scores=z["scores"], info=info)
    progress = sys.stderr.isatty() if progress is None else progress
    obj = _SimObject(model)
    m = int(math.ceil(n * oversample))
    keep = {k: [] for k in ("poses", "scores", "contacts", "normals", "width", "drift")}
    tested = 0
    pool = None
    try:
        for rnd in range(max_rounds):
            rseed = int(np.random.SeedSequence([int(seed), rnd]).generate_state(1)[0])
            cand = G.antipodal_grasps(model, m, rseed, settings=antipodal)
            if len(cand) == 0:
                break
            seeds = [int(np.random.SeedSequence([int(seed), rnd, i]).generate_state(1)[0]) for i in range(len(cand))]
            chunk = max(1, min(8, len(cand) // (4 * int(workers)) or 1))
            jobs = [(obj, cand.poses[i:i + chunk], seeds[i:i + chunk], settings) for i in range(0, len(cand), chunk)]
            bar = _Progress(len(cand), f"{model.name} shake round {rnd + 1}", progress)
            results = []
            if int(workers) == 1:
                for job in jobs:
                    results += _shake_chunk(*job)
                    bar.update(len(job[1]))
            else:
                if pool is None:
                    import multiprocessing as mp
                    pool = mp.get_context("spawn").Pool(int(workers))
                for res in pool.imap(_star_shake, jobs):  # imap keeps the candidate order
                    results += res
                    bar.update(len(res))
            tested += len(cand)
            for i, r in enumerate(results):
                if r["held"]:
                    keep["poses"].append(cand.poses[i])
                    keep["scores"].append(1.0 - r["drift"] / settings.max_drift)
                    for k in ("contacts", "normals", "width"):
                        keep[k].append(cand.info[k][i])
                    keep["drift"].append(r["drift"])
            if len(keep["poses"]) >= n:
                break
    finally:
        if pool is not None:
            pool.close()
            pool.join()
    got = min(n, len(keep["poses"]))
    if got < n:
        import warnings
        warnings.warn(f"{model.name}: only {got} of {n} simulated grasps held ({tested} tested)", stacklevel=2)
    arr = {k: np.asarray(v[:got], dtype=float) for k, v in keep.items()}
    if got == 0:
        arr["poses"] = np.zeros((0, 4, 4))
    info = {k: arr[k] for k in ("contacts", "normals", "width", "drift")}
    info["tested"] = np.asarray(tested)
    gs = G.GraspSet("simulated", arr["poses"], model.name, scores=arr["scores"], info=info)
    if path:
        with atomic_open(path, "wb") as f:
            np.savez(f, poses=gs.poses, scores=gs.scores, **{f"info_{k}": v for k, v in info.items()})
    return gs


def _star_shake(job):
    return _shake_chunk(*job)
