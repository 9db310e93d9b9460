"""Where the target can be, from the depth views alone: its *visibility hull*.

A camera that measures depth d along a pixel's ray has seen the space in front of d empty. Space
behind a target pixel's depth that no camera has seen empty may belong to the target (its hidden
side, its inside). Over a box around the observed target points (reaching ``reach`` beyond them
sideways, from the support plane up to just over their top), a voxel is **possibly target** when

- no view sees it free: in every view it projects onto a pixel without a return, outside the image,
  or at or behind the pixel's depth (less ``surface_margin`` for noise), and
- some view sees it behind a target pixel.

The hull bounds the hidden surface: the object lies inside the observed points' union with it. A
hand whose open fingers stay out of the hull cannot meet the target before it closes, and the
hull's extent across a closing axis is an upper bound of the width the fingers will meet (the
observed points give a lower bound). With one view the hull reaches back along the view rays to
where they meet the table (the object's shadow); more views carve it down to the object.

The hull is returned as the centres of its boundary voxels (those with a 6-neighbour outside it),
enough for both uses: no hand can reach the inside without crossing the boundary, and a set's
extent is its boundary's.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Tuple

import numpy as np
from scipy import ndimage

from pickplan.core.observation import Observation


@dataclass(frozen=True)
class HullSettings:
    resolution: float = 0.005  # m, voxel edge
    reach: float = 0.09  # m beyond the observed points sideways (more than any opening: a hull
    #                               reaching the box's side is wider than the gripper anyway)
    surface_margin: float = 0.003  # m in front of a measured depth still counted at the surface (noise)
    floor: float = 0.004  # m above the plane where the hull starts (below: the table's contact)
    headroom: float = 0.01  # m above the highest observed point the box reaches

    def __post_init__(self):
        for name in ("resolution", "reach", "headroom"):
            if not getattr(self, name) > 0:
                raise ValueError(f"hull {name} must be > 0, got {getattr(self, name)}")
        if self.surface_margin < 0 or self.floor < 0:
            raise ValueError("hull surface_margin and floor must be >= 0")


def _box(points: np.ndarray, plane: Tuple[np.ndarray, float], s: HullSettings):
    """Voxel centres (M, 3) of the box around ``points`` and its dims (nx, ny, nz), in a frame whose
    z is the plane's normal (so the box's floor lies on the plane)."""
    n, d = plane
    e1 = np.cross(n, [1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.cross(n, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    R = np.column_stack([e1, e2, n])
    local = points @ R
    lo = local.min(axis=0) - [s.reach, s.reach, 0.0]
    hi = local.max(axis=0) + [s.reach, s.reach, s.headroom]
    lo[2] = d + s.floor
    if hi[2] <= lo[2]:
        hi[2] = lo[2] + s.resolution
    dims = np.maximum(1, np.ceil((hi - lo) / s.resolution).astype(int))
    axes = [lo[k] + s.resolution * (np.arange(dims[k]) + 0.5) for k in range(3)]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    centres = np.stack([gx, gy, gz], axis=-1).reshape(-1, 3) @ R.T
    return centres, tuple(dims)


def _classify(obs: Observation, X: np.ndarray, margin: float):
    """Per point: seen free by some view, and seen at or behind a target pixel by some view."""
    free = np.zeros(len(X), dtype=bool)
    behind_target = np.zeros(len(X), dtype=bool)
    H, W = obs.depth.shape[1:]
    for v in range(obs.views):
        T, K = obs.camera_pose[v], obs.K[v]
        C = (X - T[:3, 3]) @ T[:3, :3]  # camera frame
        z = C[:, 2]
        front = z > 1e-6
        zs = np.where(front, z, 1.0)
        col = np.floor(K[0, 0] * C[:, 0] / zs + K[0, 2]).astype(np.int64)
        row = np.floor(K[1, 1] * C[:, 1] / zs + K[1, 2]).astype(np.int64)
        inside = front & (col >= 0) & (col < W) & (row >= 0) & (row < H)
        idx = np.flatnonzero(inside)
        depth = obs.depth[v, row[idx], col[idx]].astype(float)
        ret = np.isfinite(depth) & (depth > 0)
        free[idx[ret & (z[idx] < depth - margin)]] = True
        behind_target[idx[ret & (z[idx] >= depth - margin) & obs.target_mask[v, row[idx], col[idx]]]] = True
    return free, behind_target


def hull_voxels(
    obs: Observation, points: np.ndarray, plane: Tuple[np.ndarray, float], settings: HullSettings = HullSettings()
) -> Tuple[np.ndarray, np.ndarray]:
    """Centres (K, 3), world frame, of every voxel the target may fill (module docstring), and
    whether each is on the hull's boundary (K,)."""
    if not isinstance(obs, Observation):
        raise TypeError(f"obs: expected a pickplan Observation, got {type(obs).__name__}")
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) == 0:
        raise ValueError(f"points: expected a non-empty (N, 3) array, got shape {P.shape}")
    n = np.asarray(plane[0], float)
    centres, dims = _box(P, (n / np.linalg.norm(n), float(plane[1])), settings)
    free, behind = _classify(obs, centres, settings.surface_margin)
    hull = (behind & ~free).reshape(dims)
    boundary = (hull & ~ndimage.binary_erosion(hull, border_value=0)).reshape(-1)
    inside = hull.reshape(-1)
    return centres[inside], boundary[inside]


def visibility_hull(
    obs: Observation, points: np.ndarray, plane: Tuple[np.ndarray, float], settings: HullSettings = HullSettings()
) -> np.ndarray:
    """Boundary voxel centres (K, 3), world frame, of the space the target may fill (module docstring)."""
    centres, boundary = hull_voxels(obs, points, plane, settings)
    return centres[boundary]
