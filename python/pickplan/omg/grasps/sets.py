"""Grasp sets: the ``GraspSet`` type, pose checks, and the sets stored with an object.

Convention for every set pickplan hands out: ``(N, 4, 4)`` poses of the Panda's ``panda_hand``
link in the object (mesh) frame, so the world hand pose is ``T_world_object @ T``. YCB files use a
gripper frame that closes along x: they are post-multiplied by ``YCB_TO_HAND`` (+pi/2 about z).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

from pickplan.core.panda import YCB_TO_HAND
from pickplan.core.settings import Option
from pickplan.core.poses import RIGID_CLEAN_TOLERANCE, clean_poses


class GraspKind(Option):
    """The grasp set kinds (``grasp_set``): stored with YCB objects, or generated."""

    simulated = "simulated"  # stored, else physics-verified (physics.simulated_grasps)
    graspit = "graspit"      # stored only
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

    name: str                      # "simulated" | "graspit" | "approach" | "antipodal"
    poses: np.ndarray              # (N, 4, 4)
    object_name: str
    scores: Optional[np.ndarray] = None       # (N,) higher is better, where the source has one
    info: Dict[str, np.ndarray] = field(default_factory=dict)  # per-grasp extras (contacts, widths...)

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


def load_grasp_set(model, kind: str) -> GraspSet:
    """A grasp set stored with the object (``grasps_<kind>.npy``), in the pickplan convention."""
    if kind not in model.grasps:
        have = sorted(model.grasps)
        raise ValueError(f"object {model.name!r} has no stored {kind!r} grasps; available: "
                         f"{have if have else 'none'} (generated kinds: 'approach', 'antipodal', 'simulated')")
    poses = check_grasps(model.grasps[kind], f"{model.name} grasps_{kind}.npy")
    return GraspSet(kind, poses @ YCB_TO_HAND, model.name)


def _check_count(n, seed) -> None:
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive number of grasps, got {n!r}")
    if seed is None or int(seed) != seed:
        raise ValueError(f"seed: expected an integer, got {seed!r}")
