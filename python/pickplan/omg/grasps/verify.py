"""Physics verification for what the grasp quality cannot judge: fast enough for a new object, cached.

The quality (``quality``) decides the grasps whose margin is clearly positive (kept) or clearly
negative, or whose pads meet nothing (rejected). Those in between (``VerifySettings.band``), where its
simplifications decide (how the pressure spreads over a patch, whether the object settles in the grip,
the simulator's contact points), are lifted in PyBullet, most uncertain first and at most ``budget`` of
them (``physics.lift_trial``: the object on the table as it lies, the hand closes with the gripper's
force, lifts and holds; held when the object rose and turned and slid less than ``max_rotation`` and
``max_slip`` in the hand). The result depends on the object, the way it lies (gravity in its frame),
the grasps, the gripper and the settings, and is cached on disk under that key
(``$PICKPLAN_CACHE_DIR/verified``); ``Verified.seconds`` is the time it took (0 from the cache).

>>> v = verify_grasps(model, grasps.poses, model.resting_poses[0])
>>> grasps.poses[v.keep], v.simulated.sum(), v.seconds

``lift_grasps`` lifts every grasp it is given, whatever the quality says, and caches each grasp's
verdict apart (``$PICKPLAN_CACHE_DIR/verified/lifts-*``: a goal set's grasps differ from scene to scene
while most of them recur): for a grasp that must carry the object (pick and place), where the model the
quality judges and the physics differ (a pitcher's 2 mm lip, filled solid in its collision model).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import asdict, dataclass, field
from typing import Tuple

import numpy as np

from pickplan.core.description import RobotInfo
from pickplan.core.io import atomic_open, cache_dir
from pickplan.core.panda import PANDA
from pickplan.core.settings import Option
from pickplan.omg.grasps.physics import LiftSettings, SimObject, lift_trial
from pickplan.omg.grasps.quality import GraspFit, QualitySettings, model_quality
from pickplan.omg.grasps.sets import check_grasps

CACHE_VERSION = 1


@dataclass(frozen=True)
class VerifySettings:
    band: Tuple[float, float] = (-1.0, 0.3)  # margins the model is unsure of: simulated
    budget: int = 30  # simulations at most per call, the most uncertain first
    max_rotation: float = 15.0  # deg the object may turn in the hand and still be held
    max_slip: float = 0.02  # m its centre of mass may move in the hand
    # m the hand coming in (``LiftSettings.approach``) may move it before the fingers close: a finger that
    # meets the object on the way (1-2 mm is the object settling on the table)
    max_push: float = 0.005
    lift: LiftSettings = field(default_factory=lambda: LiftSettings(table_clearance=-0.002))  # fingertips may rest
    quality: QualitySettings = field(default_factory=QualitySettings)

    def __post_init__(self):
        if not self.band[0] <= self.band[1] or self.budget < 0:
            raise ValueError(
                f"VerifySettings: expected band low <= high and budget >= 0, got {self.band}, {self.budget}"
            )


@dataclass
class Verified:
    """Per grasp: kept, the quality's margin, whether it was simulated and, if so, whether it held."""

    keep: np.ndarray  # (N,) bool
    margin: np.ndarray  # (N,)
    simulated: np.ndarray  # (N,) bool
    held: np.ndarray  # (N,) bool (False where not simulated)
    seconds: float  # wall time of this call (0 when read from the cache)
    cached: bool = False


def _key(model, down: np.ndarray, gripper: RobotInfo, settings: VerifySettings, *arrays) -> "hashlib._Hash":
    """What a physics verdict depends on: the object (mesh and the physics model), which way is down in
    its frame, the gripper, the settings (and ``arrays``: the grasps, where a result covers a whole set)."""
    h = hashlib.sha256()
    for a in (model.mesh.vertices, model.mesh.faces, *arrays, np.round(down, 6)):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    with open(model.collision_obj_path(), "rb") as f:
        h.update(f.read())
    h.update(
        json.dumps(
            {
                "v": CACHE_VERSION,
                "mass": float(model.mass),
                "friction": model.friction,
                "settings": asdict(settings),
                "gripper": repr(gripper.key),
                "grip": (gripper.grip_force, gripper.grip_speed, gripper.pad_friction),
            },
            sort_keys=True,
            default=str,
        ).encode()
    )
    return h


def _cache_path(kind: str, model, h) -> str:
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in model.name)
    return cache_dir("verified", f"{kind}{safe}-{h.hexdigest()[:24]}.npz")


def _table_rest(object_pose) -> Tuple[np.ndarray, np.ndarray]:
    """The object as it lies, moved to the middle of the simulated table (yaw and height kept), and
    which way is down in its frame."""
    rest = np.array(object_pose, dtype=float)
    rest[:2, 3] = 0.0
    return rest, rest[:3, :3].T @ np.array([0.0, 0.0, -1.0])


def _held(trial: dict, settings: VerifySettings) -> bool:
    return bool(
        trial["applicable"]
        and trial["lifted"]
        and trial["rotation"] < settings.max_rotation
        and trial["slip"] < settings.max_slip
        and trial["pushed"] < settings.max_push
    )


def verify_grasps(
    model,
    poses,
    object_pose,
    gripper: RobotInfo = PANDA,
    settings: VerifySettings = VerifySettings(),
    cache: bool = True,
) -> Verified:
    """Judge ``gripper``'s hand poses (object frame) on ``model`` lying as at ``object_pose`` (a pose
    resting on a table top at z = 0): by the quality, and in PyBullet where it is unsure (see the
    module docstring)."""
    started = time.perf_counter()
    poses = check_grasps(poses)
    rest, down = _table_rest(object_pose)
    path = _cache_path("", model, _key(model, down, gripper, settings, poses)) if cache else None
    if path and os.path.isfile(path):
        with np.load(path) as z:
            return Verified(z["keep"], z["margin"], z["simulated"], z["held"], 0.0, cached=True)
    quality = model_quality(model, poses, rest, gripper, settings.quality)
    margin = quality.margin
    unsure = np.flatnonzero((margin >= settings.band[0]) & (margin < settings.band[1]))
    mid = 0.5 * (settings.band[0] + settings.band[1])
    unsure = unsure[np.argsort(np.abs(margin[unsure] - mid), kind="stable")][: settings.budget]
    keep = quality.holds() & (margin >= settings.band[1])
    simulated, held = np.zeros(len(poses), bool), np.zeros(len(poses), bool)
    obj = SimObject(model)
    for i in unsure:
        if quality.fit[i] is GraspFit.misses:
            continue
        trial = lift_trial(obj, [rest], poses[i], settings.lift, gripper)
        simulated[i] = True
        held[i] = _held(trial, settings)
    keep |= held
    out = Verified(keep, margin, simulated, held, time.perf_counter() - started)
    if path:
        with atomic_open(path, "wb") as f:
            np.savez(f, keep=keep, margin=margin, simulated=simulated, held=held)
    return out


class LiftVerdict(Option):
    """What one lift in PyBullet (``lift_grasps``) said of a grasp."""

    held = "held"  # rose with the hand, turned and slid less than the settings allow
    fell = "fell_in_lift"  # pushed on the approach, did not rise with the hand, or turned or slid in it
    not_applicable = "lift_not_applicable"  # the open hand touches the simulated table at the grasp


def lift_grasps(
    model,
    poses,
    object_pose,
    gripper: RobotInfo = PANDA,
    settings: VerifySettings = VerifySettings(),
    cache: bool = True,
) -> np.ndarray:
    """(N,) ``LiftVerdict`` of each of ``gripper``'s hand poses (object frame) lifting ``model`` lying as
    at ``object_pose`` (see the module docstring); each grasp's verdict cached on disk apart."""
    poses = check_grasps(poses)
    rest, down = _table_rest(object_pose)
    path = _cache_path("lifts-", model, _key(model, down, gripper, settings)) if cache else None
    keys = [hashlib.sha256((np.round(p[:3], 9) + 0.0).tobytes()).hexdigest()[:32] for p in poses]

    def stored() -> dict:
        if not (path and os.path.isfile(path)):
            return {}
        with np.load(path) as z:
            return dict(zip(z["keys"].tolist(), z["verdicts"].tolist()))

    known, new, obj = stored(), {}, None
    for key, pose in zip(keys, poses):
        if key in known or key in new:
            continue
        obj = obj or SimObject(model)
        trial = lift_trial(obj, [rest], pose, settings.lift, gripper)
        verdict = LiftVerdict.not_applicable if not trial["applicable"] else LiftVerdict.fell
        new[key] = (LiftVerdict.held if _held(trial, settings) else verdict).value
    if new and path:
        merged = {**stored(), **new}  # read again: another process may have added its grasps meanwhile
        with atomic_open(path, "wb") as f:
            np.savez(f, keys=np.array(list(merged), dtype=str), verdicts=np.array(list(merged.values()), dtype=str))
    known.update(new)
    return np.array([LiftVerdict(known[key]) for key in keys], dtype=object)
