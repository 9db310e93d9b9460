"""Grasp sets: the ``GraspSet`` type, pose checks, and the sets stored with an object.

Convention for every set pickplan hands out: ``(N, 4, 4)`` poses of the Panda's ``panda_hand``
link in the object (mesh) frame, so the world hand pose is ``T_world_object @ T``. YCB files use a
gripper frame that closes along x: they are post-multiplied by ``YCB_TO_HAND`` (+pi/2 about z).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

import trimesh

from pickplan.core.description import RobotInfo
from pickplan.core.panda import PANDA, YCB_TO_HAND
from pickplan.core.settings import Option
from pickplan.core.poses import RIGID_CLEAN_TOLERANCE, clean_poses


class GraspKind(Option):
    """The grasp set kinds (``grasp_set``): stored with YCB objects, or generated."""

    simulated = "simulated"  # stored, else physics-verified (simulated.simulated_grasps)
    graspit = "graspit"  # stored only
    approach = "approach"
    antipodal = "antipodal"


KINDS = tuple(GraspKind)


# --- grasp sets ------------------------------------------------------------------------------------
def check_grasps(poses, what: str = "grasps", tol: float = RIGID_CLEAN_TOLERANCE) -> np.ndarray:
    """``poses`` as a float (N, 4, 4) array of rigid transforms, cleaned to float precision
    (``core.poses.clean_poses``), or ValueError saying what is wrong."""
    return clean_poses(poses, what, tol)


@dataclass(eq=False)
class GraspSet:
    """A named set of ``panda_hand`` poses in the object frame (see the module docstring)."""

    name: str  # "simulated" | "graspit" | "approach" | "antipodal"
    poses: np.ndarray  # (N, 4, 4)
    object_name: str
    scores: Optional[np.ndarray] = None  # (N,) higher is better, where the source has one
    info: Dict[str, np.ndarray] = field(default_factory=dict)  # per-grasp extras (contacts, widths...)
    rejected: Dict[str, int] = field(default_factory=dict)  # a generator's rejected candidates by reason

    def __post_init__(self):
        self.poses = check_grasps(self.poses, f"grasp set {self.name!r}")
        if self.scores is not None:
            self.scores = np.asarray(self.scores, dtype=float).reshape(-1)
            if len(self.scores) != len(self.poses):
                raise ValueError(f"scores: expected {len(self.poses)} values, got {len(self.scores)}")

    def __len__(self) -> int:
        return len(self.poses)

    def in_world(self, T_world_object) -> np.ndarray:
        """World poses of the hand for an object at ``T_world_object``."""
        return np.asarray(T_world_object, dtype=float) @ self.poses


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _frame(z: np.ndarray, y_hint: np.ndarray) -> np.ndarray:
    """Rotation with columns (x, y, z): z given, y the part of ``y_hint`` orthogonal to z."""
    z = z / np.linalg.norm(z)
    y = y_hint - np.dot(y_hint, z) * z
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])


def _perpendicular(v: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(v, a)
    return p / np.linalg.norm(p)


def load_grasp_set(model, kind: str, gripper: RobotInfo = PANDA, hand_checker=None) -> GraspSet:
    """A grasp set stored with the object (``grasps_<kind>.npy``), in the pickplan convention, for
    ``gripper`` (the stored Panda grasps converted by ``convert_grasps`` for another gripper)."""
    if kind not in model.grasps:
        have = sorted(model.grasps)
        raise ValueError(
            f"object {model.name!r} has no stored {kind!r} grasps; available: "
            f"{have if have else 'none'} (generated kinds: 'approach', 'antipodal', 'simulated')"
        )
    poses = check_grasps(model.grasps[kind], f"{model.name} grasps_{kind}.npy")
    stored = GraspSet(kind, poses @ YCB_TO_HAND, model.name)
    return stored if gripper.key == PANDA.key else convert_grasps(stored, model, gripper, hand_checker=hand_checker)


@dataclass(frozen=True)
class ConversionSettings:
    width_margin: float = 0.005  # m the grasped width must stay below the new gripper's opening
    backoff_step: float = 0.005  # m: a hand that hits the object is backed off along the approach by this ...
    backoff_fraction: float = 0.5  # ... up to this fraction of its pad length (the pads still cover the grasp)
    surface_samples: int = 4000  # object surface points the width is measured on (seeded)


def grasp_widths(
    model,
    grasp_frames: np.ndarray,
    pad_length: float,
    pad_width: float,
    span: float,
    settings: ConversionSettings = ConversionSettings(),
) -> np.ndarray:
    """Width of object material each grasp would close on: the extent along the closing axis (y) of the
    object's surface points inside the pads' box (``pad_length`` along z, ``pad_width`` along x,
    ``span`` along y, centred on the grasp frame). 0 where no point is inside."""
    pts, _ = trimesh.sample.sample_surface(model.mesh, settings.surface_samples, seed=0)
    pts = np.c_[np.asarray(pts), np.ones(len(pts))]
    widths = np.zeros(len(grasp_frames))
    for k, G in enumerate(grasp_frames):
        local = (np.linalg.inv(G) @ pts.T).T
        inside = (
            (np.abs(local[:, 0]) <= pad_width / 2)
            & (np.abs(local[:, 2]) <= pad_length / 2)
            & (np.abs(local[:, 1]) <= span / 2)
        )
        if inside.any():
            widths[k] = local[inside, 1].max() - local[inside, 1].min()
    return widths


def convert_grasps(
    grasps: GraspSet,
    model,
    gripper: RobotInfo,
    source: RobotInfo = PANDA,
    settings: ConversionSettings = ConversionSettings(),
    hand_checker=None,
) -> GraspSet:
    """``source`` hand poses -> the same grasp frames (the point between the pads, the approach and
    closing axes) -> ``gripper``'s hand poses, keeping the grasps whose width (``grasp_widths``,
    measured between the source's open pads) fits ``gripper``'s opening. ``hand_checker(model, gripper)``
    (``hand.HandObjectChecker``, given by ``load_grasp_set``'s callers above this module) backs a hand that
    hits the object off along the approach axis, by at most ``backoff_fraction`` of the pad length. ``info``: "source_index" (row
    in the input set), "width"; the count kept is ``len`` of the result (``grasps`` had ``len(grasps)``)."""
    frames = grasps.poses @ source.grasp_frame
    width = grasp_widths(model, frames, max(gripper.pad_length, 1e-3), max(gripper.pad_width, 1e-3), source.max_opening)
    keep = np.flatnonzero(width <= gripper.max_opening - settings.width_margin)
    poses = frames[keep] @ gripper.hand_from_grasp if len(keep) else np.zeros((0, 4, 4))
    if hand_checker is not None and len(keep):
        # A shallower palm than the source's: back the hand off along the approach until it clears the object.
        check = hand_checker(model, gripper=gripper)
        hits = check.in_collision(poses)
        backed = np.zeros(len(poses))
        for back in np.arange(1, int(settings.backoff_fraction * gripper.pad_length / settings.backoff_step) + 1):
            if not hits.any():
                break
            moved = poses[hits].copy()
            moved[:, :3, 3] -= settings.backoff_step * (moved[:, :3, :3] @ gripper.grasp_frame[:3, 2])
            free = ~check.in_collision(moved)
            idx = np.flatnonzero(hits)[free]
            poses[idx] = moved[free]
            backed[idx] = back * settings.backoff_step
            hits[idx] = False
        # A hand backed off because a finger hit the object now holds that finger over the object (it
        # lands on it and never closes): keep a backed-off grasp only if its fingers still straddle it.
        moved = np.flatnonzero(backed > 0)
        ok = np.ones(len(poses), dtype=bool)
        ok[moved] = fingers_straddle(model, poses[moved] @ gripper.grasp_frame, gripper, backed[moved], settings)
        ok &= ~hits  # never cleared the object within the back-off allowed
        keep, poses = keep[ok], poses[ok]
    scores = None if grasps.scores is None else grasps.scores[keep]
    return GraspSet(
        grasps.name, poses, grasps.object_name, scores=scores, info={"source_index": keep, "width": width[keep]}
    )


def fingers_straddle(
    model, grasp_frames: np.ndarray, gripper: RobotInfo, reach, settings: ConversionSettings = ConversionSettings()
) -> np.ndarray:
    """Per grasp frame: no object surface point lies under a finger, i.e. in the pads' footprint
    (``pad_width`` along x, from the pads' inner faces at the open width outwards by a pad width along
    y) from the pads' centre to ``reach`` (m, per grasp) beyond the finger tips along the approach;
    points between the inner faces (less ``width_margin / 2``) are the grasped material."""
    out = np.ones(len(grasp_frames), dtype=bool)
    if len(grasp_frames) == 0:
        return out
    pts, _ = trimesh.sample.sample_surface(model.mesh, settings.surface_samples, seed=0)
    pts = np.c_[np.asarray(pts), np.ones(len(pts))]
    half, tip = gripper.max_opening / 2, gripper.pad_length / 2
    for k, (G, r) in enumerate(zip(grasp_frames, np.broadcast_to(reach, len(grasp_frames)))):
        local = (np.linalg.inv(G) @ pts.T).T
        under = (
            (np.abs(local[:, 0]) <= gripper.pad_width / 2)
            & (local[:, 2] >= 0)
            & (local[:, 2] <= tip + r)
            & (np.abs(local[:, 1]) > half - settings.width_margin / 2)
            & (np.abs(local[:, 1]) <= half + gripper.pad_width)
        )
        out[k] = not under.any()
    return out


def _check_count(n, seed) -> None:
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive number of grasps, got {n!r}")
    if seed is None or int(seed) != seed:
        raise ValueError(f"seed: expected an integer, got {seed!r}")
