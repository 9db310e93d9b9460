"""Physics-verified grasps (the OMG paper's "Simulated" set, after Eppner et al. [12]) and an
independent lift test, in PyBullet DIRECT with a free-floating Panda hand.

Shake test (what ``simulated_grasps`` keeps): antipodal candidates; the hand is held in space with
its approach axis pointing down, the object free with gravity off; the fingers close; gravity comes
on; the hand shakes (a translation along a random direction, then a rotation about a random axis
through the pads), then turns +-90 degrees about its closing axis and holds each side, so gravity
pulls along the approach axis and both ways across it. A grasp holds when the fingers did not
close on nothing, the object point that sat between the pads drifted less than ``max_drift``
relative to the hand and the object turned less than ``max_rotation`` in the hand (both measured
from the settled grasp, worst over the checkpoints). The rotation check matters: a two-finger
pinch fails mostly by the object pivoting about the closing axis (the pads' torsional friction
is small), which leaves the point between the pads in place.

Lift test (``lift_test``, for evaluation): the object rests on a table in its most stable pose,
gravity on throughout; the open hand is placed at the grasp (grasps whose hand touches the table
are not applicable), closes and lifts; success when the object rose with the hand.

Transport test (``transport_test``, a harder independent evaluation): the lift test's start, then
the object is carried: raised 30 cm, moved 25 cm sideways (quintic profiles, peak accelerations
1.7 and 1.4 m/s^2), tilted 60 degrees and swirled once around the vertical (gravity sweeps a cone
in the hand frame), with gravity on throughout. Success when the object stays in the hand in the
pose it took after the lift: off the table, turned at most ``max_rotation`` and its centre of
mass moved at most ``max_slip`` relative to the hand, at every checkpoint. It shares no motion,
start state or randomness with the shake test.

The two fingers are coupled by a gear constraint (PyBullet ignores the URDF's ``<mimic>``; the
Franka hand drives both with one motor, and ``execution.py`` couples them the same way): without
it, gravity along the closing axis pushes the object and both force-limited fingers sideways.

Every candidate runs from a fresh ``resetSimulation`` with its own seed, so results do not depend on
the number of workers or the order of the runs. The "Simulated" set itself (``simulated_grasps``, cached
on disk and shipped for the built-in objects) is ``grasps.simulated``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from pickplan.core.io import CACHE_ENV  # noqa: F401 - re-exported for callers
from pickplan.core.runner import run_jobs
from pickplan.omg.grasps.generators import AntipodalSettings, antipodal_grasps
from pickplan.core.description import RobotInfo
from pickplan.core.panda import PANDA
from pickplan.omg.grasps.hand_world import HandWorld, InHand, SimObject, quintic_step, smooth_step, turned_about
from pickplan.omg.grasps.sets import check_grasps


@dataclass(frozen=True)
class SimSettings:
    """Physics and shake-test settings (the candidates come from ``grasps.AntipodalSettings``)."""

    time_step: float = 1.0 / 240.0
    solver_iterations: int = 50
    finger_force: Optional[float] = None  # N per finger; None: the gripper description's force
    finger_speed: Optional[float] = None  # m/s per finger; None: the gripper description's speed
    close_time: float = 0.5  # s, gravity off
    settle_time: float = 0.25  # s with gravity on before shaking
    shake_time: float = 1.0  # s: first half translation, second half rotation
    shake_frequency: float = 2.0  # Hz
    shake_amplitude: float = 0.02  # m (peak acceleration 3.2 m/s^2 at 2 Hz)
    shake_angle: float = 0.35  # rad (about 20 deg)
    max_drift: float = 0.02  # m: the held object point may move this much relative to the hand
    max_rotation: float = 15.0  # deg: the object may turn this much in the hand
    turn_angle: float = 90.0  # deg about the closing axis, each way (0: no turns)
    turn_time: float = 0.4  # s per turn (smooth-step) and per return
    turn_hold: float = 0.3  # s held at each turn
    min_gap: float = 0.001  # m between the pads at the end: less = closed on nothing
    object_friction: float = 0.8
    pad_friction: float = 1.0  # the Panda URDF's lateral friction (Bullet multiplies the two bodies')
    pad_spinning_friction: float = 0.005  # m; the URDF's 0.1 would let a pinch resist any torque
    hand_force: float = 2000.0  # N of the constraint that carries the hand
    couple_fingers: bool = True  # gear constraint: the fingers move together, as the Franka hand's do


@dataclass(frozen=True)
class LiftSettings:
    time_step: float = 1.0 / 240.0
    solver_iterations: int = 50
    finger_force: Optional[float] = None  # as SimSettings
    finger_speed: Optional[float] = None
    close_time: float = 0.5
    lift_height: float = 0.1  # m
    lift_time: float = 1.0  # s (smooth-step profile)
    hold_time: float = 0.5
    min_rise: float = 0.7  # success: the object rose by at least this fraction of the lift
    min_gap: float = 0.001
    table_clearance: float = 0.002  # m: an open hand closer than this to the table is not applicable
    object_friction: float = 0.8
    pad_friction: float = 1.0
    pad_spinning_friction: float = 0.005
    table_friction: float = 0.8
    hand_force: float = 2000.0
    couple_fingers: bool = True
    rest_index: Optional[int] = None  # resting pose; None: the most stable one where the hand clears the table
    # m the open hand starts back along its approach axis and moves in before it closes (a plan's
    # standoff approach: a finger that meets the object on the way pushes it); 0: it starts at the grasp
    approach: float = 0.0
    approach_time: float = 0.5  # s


@dataclass(frozen=True)
class TransportSettings(LiftSettings):
    """The lift test's start (table, resting pose, close, lift, hold), then a carry with tilts."""

    raise_height: float = 0.3  # m, after the lift (quintic, so the tilted object clears the table)
    raise_time: float = 1.0  # s: peak acceleration 5.77 * 0.3 / 1.0^2 = 1.7 m/s^2
    carry_distance: float = 0.25  # m along world x
    carry_time: float = 1.0  # s: peak acceleration 1.4 m/s^2
    tilt: float = 60.0  # deg about a horizontal axis through the pads ...
    tilt_time: float = 0.5
    swirl_time: float = 2.0  # ... whose direction then turns once around the vertical
    settle: float = 0.2  # s held still at the end
    max_rotation: float = 15.0  # deg the object may turn in the hand after the lift
    max_slip: float = 0.02  # m its centre of mass may move in the hand after the lift


def shake_test(
    obj, grasp: np.ndarray, seed: int, settings: SimSettings = SimSettings(), gripper: RobotInfo = PANDA
) -> dict:
    """One shake test of a hand pose ``grasp`` (object frame). Returns held, drift (m, the pad
    point), rotation (deg, the object in the hand), gap (m); drift and rotation are the worst
    over the checkpoints run (after the shake, at each turn, back at the start; the test stops
    at the first failing one)."""
    s = settings
    obj = obj if isinstance(obj, SimObject) else SimObject(obj)
    rng = np.random.default_rng(seed)
    T_hand = np.eye(4)
    # approach (the grasp frame's z) pointing down: gravity pulls out of the hand
    T_hand[:3, :3] = np.diag([1.0, -1.0, -1.0]) @ gripper.grasp_frame[:3, :3].T
    T_hand[2, 3] = 0.5
    world = HandWorld(s, obj, T_hand, T_hand @ np.linalg.inv(grasp), gravity=False, gripper=gripper)
    world.close()
    world.step(s.close_time)
    world.gravity(True)
    world.step(s.settle_time)
    # the object point between the pads (in the body frame) and the settled grasp
    pad = gripper.grasp_frame[:, 3]  # the point between the pads, in the hand link
    H0 = world.hand_pose()
    held = InHand(world)
    p_body = np.linalg.inv(held.ref) @ pad
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

    world.step(half, translate)
    world.step(half, lambda u: turned_about(H0, pivot, axis, s.shake_angle * math.sin(w * half * u)))
    world.step(0.1, lambda u: H0)
    drift, rotation = [], []

    def holds() -> bool:
        drift.append(held.moved(p_body))
        rotation.append(held.rotation())
        return world.gap() > s.min_gap and drift[-1] < s.max_drift and rotation[-1] < s.max_rotation

    ok = holds()
    if s.turn_angle:
        closing = H0[:3, :3] @ gripper.grasp_frame[:3, 1]
        for sign in (1.0, -1.0):
            if not ok:
                break  # a failed checkpoint is final: skip the rest
            a = sign * math.radians(s.turn_angle)
            world.step(s.turn_time, lambda u: turned_about(H0, pivot, closing, a * smooth_step(u)))
            world.step(s.turn_hold, lambda u: turned_about(H0, pivot, closing, a))
            ok = holds()
            world.step(s.turn_time, lambda u: turned_about(H0, pivot, closing, a * (1.0 - smooth_step(u))))
        if ok:
            world.step(0.1, lambda u: H0)
            ok = holds()
    return {"held": bool(ok), "drift": max(drift), "rotation": max(rotation), "gap": world.gap()}


def close_on_object(
    model, grasp: np.ndarray, settings: SimSettings = SimSettings(), gripper: RobotInfo = PANDA
) -> dict:
    """Close the hand at ``grasp`` (object frame) on the free object with gravity off: the final
    pad gap (m) and whether each finger ends touching the object ("left", "right")."""
    obj = model if isinstance(model, SimObject) else SimObject(model)
    world = HandWorld(settings, obj, np.eye(4), np.linalg.inv(check_grasps([grasp])[0]), gravity=False, gripper=gripper)
    world.close()
    world.step(settings.close_time)
    touch = [
        bool(world.pb.getContactPoints(world.hand, world.body, j, physicsClientId=world.cid)) for j in world.fingers
    ]
    return {"gap": world.gap(), "left": touch[0], "right": touch[1]}


def _shake_job(job) -> dict:
    """Worker entry point (module level so ``spawn`` can import it)."""
    obj, T, seed, settings, gripper = job
    return shake_test(obj, T, int(seed), settings, gripper)


def _chunksize(n: int, workers: int) -> int:
    """Jobs per worker task: a few per worker and pool, at most 8 (results do not depend on it)."""
    return max(1, min(8, n // (4 * int(workers)) or 1))


def _rests(model, s) -> list:
    return [model.resting_poses[s.rest_index]] if s.rest_index is not None else list(model.resting_poses[:3])


def _table_world(obj: SimObject, rests, T: np.ndarray, s, gripper: RobotInfo = PANDA) -> Optional[HandWorld]:
    """A world with the object resting on the table and the open hand at grasp ``T``, in the first
    resting pose where the hand clears the table; None when there is none (not applicable)."""
    for rest in rests:
        rest = np.asarray(rest, float)
        world = HandWorld(
            s, obj, rest @ T, rest, gravity=True, table=True, table_friction=s.table_friction, gripper=gripper
        )
        if not world.touches(world.table, s.table_clearance):
            return world
    return None


def _close_and_lift(world: HandWorld, s, closed=None) -> Tuple[np.ndarray, bool]:
    """Close on the resting object, lift ``lift_height`` and hold; the lifted hand pose and whether
    the object rose with it (the lift test's success). ``closed()`` is called before the lift."""
    if getattr(s, "approach", 0.0) > 0:
        world.approach(s.approach, s.approach_time)
    if closed is not None:
        closed.approached()
    z0 = world.body_pose()[2, 3]
    H0 = world.hand_pose()
    world.close()
    world.step(s.close_time, lambda u: H0)
    if closed is not None:
        closed.closed()

    def lift(u):
        T_ = H0.copy()
        T_[2, 3] += s.lift_height * smooth_step(u)
        return T_

    world.step(s.lift_time, lift)
    world.step(s.hold_time, lambda u: lift(1.0))
    rise = world.body_pose()[2, 3] - z0
    return lift(1.0), bool(world.gap() > s.min_gap and rise >= s.min_rise * s.lift_height)


def lift_trial(
    obj, rests, grasp: np.ndarray, settings: LiftSettings = LiftSettings(), gripper: RobotInfo = PANDA
) -> dict:
    """One table lift (``lift_test``) with what it did to the object: applicable, lifted, pushed (m its
    centre of mass moved on the table while the open hand came in, ``LiftSettings.approach``), and slip
    (m, its centre of mass) and rotation (deg) in the hand from the closed grasp to the end of the hold
    (nan when not applicable)."""
    obj = obj if isinstance(obj, SimObject) else SimObject(obj)
    world = _table_world(obj, rests, np.asarray(grasp, float), settings, gripper)
    nan = float("nan")
    if world is None:
        return {"applicable": False, "lifted": False, "pushed": nan, "slip": nan, "rotation": nan}
    marks = _Marks(world)
    lifted = _close_and_lift(world, settings, marks)[1]
    return {
        "applicable": True,
        "lifted": lifted,
        "pushed": marks.pushed,
        "slip": marks.held.moved(np.array([0.0, 0.0, 0.0, 1.0])),
        "rotation": marks.held.rotation(),
    }


class _Marks:
    """The object as the lift found it: where it lay before the approach (``pushed``: how far the
    approach moved its centre of mass) and in the hand once the fingers closed (``held``)."""

    def __init__(self, world: HandWorld):
        self.world, self.start, self.pushed, self.held = world, world.body_pose()[:3, 3].copy(), 0.0, None

    def approached(self) -> None:
        self.pushed = float(np.linalg.norm(self.world.body_pose()[:3, 3] - self.start))

    def closed(self) -> None:
        self.held = InHand(self.world)


def lift_test(model, poses, settings: LiftSettings = LiftSettings(), gripper: RobotInfo = PANDA, details: bool = False):
    """Table lift test of hand poses (object frame): (N,) int8, 1 lifted, 0 failed, -1 not
    applicable (the open hand touches the table at the grasp in every resting pose tried: the
    ``rest_index`` one, or by default the three most stable ones, first clear one used); with
    ``details=True`` also the per-grasp dicts of ``lift_trial`` (slip and rotation in the hand).
    Independent of the shake test: table, gravity throughout, lift instead of shaking."""
    poses = check_grasps(poses)
    obj = SimObject(model)
    rests = _rests(model, settings)
    trials = [lift_trial(obj, rests, T, settings, gripper) for T in poses]
    out = np.array([int(t["lifted"]) if t["applicable"] else -1 for t in trials], dtype=np.int8)
    return (out, trials) if details else out


def transport_trial(obj, rests, grasp: np.ndarray, settings: TransportSettings = TransportSettings()) -> dict:
    """One transport test (see the module docstring). Returns applicable, lifted, held, rotation
    (deg) and slip (m) of the object in the hand since the lift (worst checkpoint run; the test
    stops at the first failing one), gap (m), table (the object touches the table at the end) and
    stage (the checkpoint that failed, or "held")."""
    s = settings
    obj = obj if isinstance(obj, SimObject) else SimObject(obj)
    out = {
        "applicable": False,
        "lifted": False,
        "held": False,
        "rotation": float("nan"),
        "slip": float("nan"),
        "gap": float("nan"),
        "table": False,
        "stage": "not applicable",
    }
    world = _table_world(obj, rests, np.asarray(grasp, float), s)
    if world is None:
        return out
    out["applicable"] = True
    H1, lifted = _close_and_lift(world, s)
    out["lifted"] = lifted
    if not lifted:
        out.update(stage="lift", gap=world.gap())
        return out
    held = InHand(world)
    com = np.array([0.0, 0.0, 0.0, 1.0])  # the body frame is the inertial frame
    rotation, slip, stage = [], [], None

    def check(name):
        nonlocal stage
        rotation.append(held.rotation())
        slip.append(held.moved(com))
        if stage is None and (rotation[-1] > s.max_rotation or slip[-1] > s.max_slip):
            stage = name
        return stage is None

    def failed():
        out.update(
            rotation=max(rotation),
            slip=max(slip),
            gap=world.gap(),
            stage=stage,
            table=bool(world.pb.getContactPoints(world.body, world.table, physicsClientId=world.cid)),
        )
        return out

    def up(u):
        T_ = H1.copy()
        T_[2, 3] += s.raise_height * quintic_step(u)
        return T_

    world.step(s.raise_time, up)
    if not check("raise"):
        return failed()  # a failed checkpoint is final: skip the rest
    H2 = up(1.0)

    def carry(u):
        T_ = H2.copy()
        T_[0, 3] += s.carry_distance * quintic_step(u)
        return T_

    world.step(s.carry_time, carry)
    H3 = carry(1.0)
    world.step(0.1, lambda u: H3)
    if not check("carry"):
        return failed()
    pivot = H3 @ PANDA.grasp_frame[:, 3]  # the transport test is the Panda hand's
    tilt = math.radians(s.tilt)

    def tilted(angle, phi):
        return turned_about(H3, pivot, np.array([math.cos(phi), math.sin(phi), 0.0]), angle)

    world.step(s.tilt_time, lambda u: tilted(tilt * smooth_step(u), 0.0))
    if not check("tilt"):
        return failed()
    world.step(s.swirl_time, lambda u: tilted(tilt, 2 * math.pi * u))
    world.step(s.settle, lambda u: tilted(tilt, 0.0))
    check("swirl")
    gap = world.gap()
    table = bool(world.pb.getContactPoints(world.body, world.table, physicsClientId=world.cid))
    if stage is None and (gap <= s.min_gap or table):
        stage = "dropped"
    out.update(held=stage is None, rotation=max(rotation), slip=max(slip), gap=gap, table=table, stage=stage or "held")
    return out


def _transport_job(job) -> dict:
    obj, rests, T, settings = job
    return transport_trial(obj, rests, T, settings)


def transport_test(
    model, poses, settings: TransportSettings = TransportSettings(), workers: int = 1, details: bool = False
):
    """Transport test of hand poses (object frame): (N,) int8 like ``lift_test`` (1 held, 0 failed,
    -1 not applicable); with ``details=True`` also the per-grasp dicts of ``transport_trial``.
    ``workers`` > 1 runs worker processes (spawn); results do not depend on it."""
    poses = check_grasps(poses)
    if int(workers) < 1:
        raise ValueError(f"workers: expected >= 1, got {workers}")
    obj, rests = SimObject(model), [np.asarray(r, float) for r in _rests(model, settings)]
    trials = run_jobs(
        _transport_job,
        [(obj, rests, T, settings) for T in poses],
        int(workers),
        chunksize=_chunksize(len(poses), workers),
    )
    out = np.array([(1 if t["held"] else 0) if t["applicable"] else -1 for t in trials], dtype=np.int8)
    return (out, trials) if details else out


def lift_rate(results: np.ndarray) -> float:
    """Success rate over the applicable grasps (nan when none is)."""
    r = np.asarray(results)
    ok = r >= 0
    return float(r[ok].mean()) if ok.any() else float("nan")


def _shake_transport_job(job):
    obj, rests, T, seed, sim, transport = job
    return shake_test(obj, T, seed, sim), transport_trial(obj, rests, T, transport)


def shake_and_transport(
    model,
    m: int,
    seed: int = 0,
    workers: int = 1,
    sim: "SimSettings" = None,
    transport: TransportSettings = TransportSettings(),
) -> list:
    """The "Simulated" filter against the transport test on the same candidates: round 0 of
    ``simulated_grasps(model, ..., seed)`` (``m`` antipodal candidates, ``shake_candidates``);
    for each candidate applicable on the table (the open hand clears it), its ``shake_test``
    (same seed as ``simulated_grasps``) and its ``transport_trial``. Returns one dict per
    applicable candidate: index, pose, shake (dict), transport (dict). The shake-held ones are
    exactly the "Simulated" grasps of that round. Worker processes (spawn) do not change results."""
    sim = SimSettings() if sim is None else sim
    cand, seeds = shake_candidates(model, m, seed)
    obj = SimObject(model)
    rests = [np.asarray(r, float) for r in _rests(model, transport)]
    idx = [i for i, T in enumerate(cand.poses) if _table_world(obj, rests, T, transport) is not None]
    jobs = [(obj, rests, cand.poses[i], seeds[i], sim, transport) for i in idx]
    res = run_jobs(_shake_transport_job, jobs, int(workers), chunksize=2)
    return [{"index": i, "pose": cand.poses[i], "shake": sh, "transport": tr} for i, (sh, tr) in zip(idx, res)]


def shake_candidates(
    model,
    m: int,
    seed: int = 0,
    round: int = 0,
    antipodal: AntipodalSettings = AntipodalSettings(),
    gripper: RobotInfo = PANDA,
):
    """Round ``round`` of ``simulated_grasps``: its ``m`` antipodal candidates and the shake-test
    seed of each. ``simulated_grasps(model, n, seed)`` keeps, round by round, the candidates whose
    ``shake_test(model, pose, seed_i)`` holds (first ``n``)."""
    rseed = int(np.random.SeedSequence([int(seed), int(round)]).generate_state(1)[0])
    cand = antipodal_grasps(model, m, rseed, settings=antipodal, gripper=gripper)
    seeds = [int(np.random.SeedSequence([int(seed), int(round), i]).generate_state(1)[0]) for i in range(len(cand))]
    return cand, seeds
