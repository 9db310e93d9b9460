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


def _cache_path(model, poses: np.ndarray, down: np.ndarray, gripper: RobotInfo, settings: VerifySettings) -> str:
    h = hashlib.sha256()
    for a in (model.mesh.vertices, model.mesh.faces, poses, np.round(down, 6)):
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
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in model.name)
    return cache_dir("verified", f"{safe}-{h.hexdigest()[:24]}.npz")


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
    rest = np.array(object_pose, dtype=float)
    rest[:2, 3] = 0.0  # on the middle of the simulated table; the yaw and the height are kept
    down = rest[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    path = _cache_path(model, poses, down, gripper, settings) if cache else None
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
        held[i] = (
            trial["applicable"]
            and trial["lifted"]
            and trial["rotation"] < settings.max_rotation
            and trial["slip"] < settings.max_slip
        )
    keep |= held
    out = Verified(keep, margin, simulated, held, time.perf_counter() - started)
    if path:
        with atomic_open(path, "wb") as f:
            np.savez(f, keep=keep, margin=margin, simulated=simulated, held=held)
    return out
