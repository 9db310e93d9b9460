"""The one place that checks and cleans rigid transforms read from files or given by callers.

Stored data is rigid only to its float precision (the YCB graspit sets, float32: orthonormality
error ~1.6e-6), so poses within ``RIGID_CLEAN_TOLERANCE`` are projected onto SO(3); poses beyond it
are rejected, not repaired. The native bindings apply the same tolerance (``cleaned_rigid``)."""

from __future__ import annotations

import numpy as np

from pickplan import _core
from pickplan.core.errors import InputError

RIGID_CLEAN_TOLERANCE = float(_core.RIGID_CLEAN_TOLERANCE)
EXACT = 1e-12  # below this a pose is left as it is


def rigid_errors(poses: np.ndarray) -> np.ndarray:
    """Per pose (N, 4, 4): the largest of the orthonormality, determinant and last-row errors (inf
    for non-finite poses)."""
    R = poses[:, :3, :3]
    with np.errstate(invalid="ignore", over="ignore"):
        orth = np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2))
        det = np.abs(np.linalg.det(R) - 1.0) if len(R) else np.zeros(0)
        last = np.abs(poses[:, 3] - [0, 0, 0, 1]).max(axis=1)
    err = np.maximum(np.maximum(orth, det), last)
    err[~np.all(np.isfinite(poses), axis=(1, 2))] = np.inf
    return err


def clean_poses(poses, what: str = "poses", tol: float = RIGID_CLEAN_TOLERANCE) -> np.ndarray:
    """``poses`` (N, 4, 4) as float64 with rotations projected onto SO(3) and last rows exact;
    InputError naming the first pose that is not rigid within ``tol``."""
    try:
        arr = np.array(poses, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected numbers, got {type(poses).__name__}", field=what) from exc
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise InputError(f"expected shape (N, 4, 4), got {arr.shape}", field=what)
    if len(arr) == 0:
        return arr
    err = rigid_errors(arr)
    bad = ~(err <= tol)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(
            f"pose {i} is not a rigid transform (rotation must be orthonormal with det +1, "
            f"last row [0, 0, 0, 1]; error {err[i]:.1e} > {tol:.0e}); {int(bad.sum())} of "
            f"{len(arr)} bad",
            field=what,
        )
    fix = err > EXACT  # poses rigid to double precision stay bit-identical (scene round trips)
    if fix.any():
        u, _, vt = np.linalg.svd(arr[fix, :3, :3])
        arr[fix, :3, :3] = u @ vt
        arr[fix, 3] = [0.0, 0.0, 0.0, 1.0]
    return arr


def clean_pose(pose, what: str = "pose", tol: float = RIGID_CLEAN_TOLERANCE) -> np.ndarray:
    """One 4x4 pose, cleaned as ``clean_poses`` does."""
    try:
        arr = np.array(pose, dtype=float)
    except (TypeError, ValueError) as exc:
        raise InputError(f"expected numbers, got {type(pose).__name__}", field=what) from exc
    if arr.shape != (4, 4):
        raise InputError(f"expected shape (4, 4), got {arr.shape}", field=what)
    err = float(rigid_errors(arr[None])[0])
    if not err <= tol:
        raise InputError(
            f"not a rigid transform (rotation must be orthonormal with det +1, last row "
            f"[0, 0, 0, 1]; error {err:.1e} > {tol:.0e})",
            field=what,
        )
    return clean_poses(arr[None], what, tol)[0]
