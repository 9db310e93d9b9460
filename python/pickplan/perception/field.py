"""From an observation (depth images, intrinsics, poses, target mask) to what the planner needs: a
signed distance field of everything but the target (native space carving + exact distance
transform), the support plane as an analytic table, and the target's observed points with normals.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Optional, Sequence, Tuple

import numpy as np

from pickplan import _core
from pickplan.core.errors import InputError
from pickplan.core.observation import Observation
from pickplan.core.sdf import SceneSdf

OBSTACLES = "observed"  # the object name of the fused field in the SceneSdf


@dataclass(frozen=True)
class FieldSettings:
    resolution: float = 0.01  # m, voxel edge
    lo: Sequence[float] = (-0.1, -0.6, -0.02)  # workspace box (world) the field covers
    hi: Sequence[float] = (1.0, 0.6, 0.6)
    surface_margin: float = 0.003  # m before a measured depth still counted as the surface (noise)
    plane: Optional[Tuple[Sequence[float], float]] = None  # (normal, offset) if known; None: detect it
    plane_margin: float = 0.01  # m above the plane left to the analytic table
    plane_tolerance: float = 0.006  # m: RANSAC inlier distance
    target_stride: int = 2  # every k-th target pixel becomes a point


@dataclass
class PerceivedScene:
    sdf: SceneSdf  # the fused obstacles (object OBSTACLES) + the table below the plane
    target_points: np.ndarray  # (N, 3) world
    target_normals: np.ndarray  # (N, 3) unit, outward (towards the cameras)
    plane: Tuple[np.ndarray, float]  # support plane n . x = d, n up
    counts: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    obstacles: Optional["_core.SdfGrid"] = None  # the fused field alone (world frame), for drawing it


def pixel_points(
    d: np.ndarray, rows: np.ndarray, cols: np.ndarray, K: np.ndarray, camera_pose: np.ndarray
) -> np.ndarray:
    """(N, 3) world points of pixels (rows, cols) at depths d (``Observation``'s conventions: pixel
    (r, c) centred at (c + 0.5, r + 0.5))."""
    P = np.column_stack([(cols + 0.5 - K[0, 2]) / K[0, 0] * d, (rows + 0.5 - K[1, 2]) / K[1, 1] * d, d])
    return P @ camera_pose[:3, :3].T + camera_pose[:3, 3]


def backproject(depth: np.ndarray, K: np.ndarray, camera_pose: np.ndarray, stride: int = 1) -> np.ndarray:
    """(H', W', 3) world points of every stride-th pixel of one view; NaN where there is no depth."""
    d = np.asarray(depth[::stride, ::stride], float)
    rows, cols = np.mgrid[0 : depth.shape[0] : stride, 0 : depth.shape[1] : stride]
    d = np.where(np.isfinite(d) & (d > 0), d, np.nan)
    return pixel_points(d.ravel(), rows.ravel(), cols.ravel(), K, camera_pose).reshape(*d.shape, 3)


def view_points(depth: np.ndarray, K: np.ndarray, camera_pose: np.ndarray, stride: int) -> np.ndarray:
    """(N, 3) world points of every stride-th pixel with depth, over all views ((V, H, W) depth)."""
    out = [backproject(depth[v], K[v], camera_pose[v], stride).reshape(-1, 3) for v in range(len(depth))]
    P = np.vstack(out)
    return P[np.isfinite(P[:, 2])]


def _points(obs: Observation, stride: int) -> np.ndarray:
    """World points of every stride-th pixel with depth, over all views."""
    return view_points(obs.depth, obs.K, obs.camera_pose, stride)


def support_plane(
    points: np.ndarray, tolerance: float = 0.006, iterations: int = 200, seed: int = 0, min_up: float = 0.9
) -> Tuple[np.ndarray, float]:
    """The dominant near-horizontal plane n . x = d (n up) by RANSAC, refit to its inliers."""
    P = np.asarray(points, float)
    if len(P) < 3:
        raise ValueError("support plane: fewer than 3 points")
    rng = np.random.default_rng(seed)
    # the seeded hypotheses (three distinct points each), formed at once: the sums are written out in
    # the order numpy's per-vector norm and dot take them, so the planes are the same to the last bit
    A, B, C = P[np.array([rng.choice(len(P), 3, replace=False) for _ in range(iterations)])].transpose(1, 0, 2)
    normals = np.cross(B - A, C - A)
    length = np.sqrt((normals * normals).sum(axis=1))
    formed = length >= 1e-9
    normals = normals[formed] / length[formed, None]
    normals *= np.where(normals[:, 2] < 0, -1.0, 1.0)[:, None]
    up = normals[:, 2] >= min_up
    if not up.any():
        raise ValueError("support plane: no near-horizontal plane in the points; give the plane explicitly")
    normals, offsets = normals[up], (normals[up] * A[formed][up]).sum(axis=1)
    # natively: the first with the most inliers, as a sequential search keeps it (a hypothesis is left
    # once its uncounted points could not lift it above the best so far)
    best, _ = _core.most_inliers(P, normals, offsets, tolerance)
    n, d = normals[best], float(offsets[best])
    inliers = P[np.abs(P @ n - d) < tolerance]
    centre = inliers.mean(axis=0)
    n = np.linalg.svd(inliers - centre, full_matrices=False)[2][2]  # (M, 3): never the M x M U
    n = -n if n[2] < 0 else n
    return n, float(n @ centre)


def perceive(
    obs: Observation,
    settings: FieldSettings = FieldSettings(),
    seed: int = 0,
    clock: Callable[[], float] = time.perf_counter,
) -> PerceivedScene:
    """The planner's world from ``obs``: fused field, support plane (detected unless given), target;
    ``seconds`` per stage as ``clock`` reads them."""
    t0 = clock()
    if settings.plane is None:
        try:
            n, d = support_plane(_points(obs, 4), settings.plane_tolerance, seed=seed)
        except ValueError as exc:  # the observation's, named: no table in view
            raise InputError(
                f"{exc} (the table the objects stand on must be in view)",
                path=None if obs.source == "<memory>" else obs.source,
                field="depth",
            ) from None
    else:
        n = np.asarray(settings.plane[0], float)
        n, d = n / np.linalg.norm(n), float(settings.plane[1])
    t1 = clock()
    native = _core.DepthFieldSettings()
    native.lo, native.hi = np.asarray(settings.lo, float), np.asarray(settings.hi, float)
    native.resolution, native.surface_margin = float(settings.resolution), float(settings.surface_margin)
    native.has_plane, native.plane_normal, native.plane_offset = True, n, d
    native.plane_margin, native.target_stride = float(settings.plane_margin), int(settings.target_stride)
    built = _core.build_depth_field(
        list(obs.depth), list(obs.K), list(obs.camera_pose), [m.astype(np.uint8) for m in obs.target_mask], native
    )
    t2 = clock()
    # the table: a slab under the plane, as wide as the workspace (its top face is the plane)
    lo, hi = np.asarray(settings.lo, float), np.asarray(settings.hi, float)
    thickness = 0.05
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, n)
    R = np.eye(3)
    if np.linalg.norm(axis) > 1e-9:
        angle = np.arccos(np.clip(n @ z, -1, 1))
        k = axis / np.linalg.norm(axis)
        Kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        R = np.eye(3) + np.sin(angle) * Kx + (1 - np.cos(angle)) * Kx @ Kx
    centre_xy = 0.5 * (lo + hi)
    T = np.eye(4)
    T[:3, :3] = R
    on_plane = np.array([centre_xy[0], centre_xy[1], (d - n[0] * centre_xy[0] - n[1] * centre_xy[1]) / n[2]])
    T[:3, 3] = on_plane - R @ [0, 0, thickness / 2]
    size = (hi - lo) + 1.0
    sdf = SceneSdf([(OBSTACLES, built.obstacles, np.eye(4))], table=((size[0], size[1], thickness), T))
    t3 = clock()
    return PerceivedScene(
        sdf,
        np.asarray(built.target_points),
        np.asarray(built.target_normals),
        (n, d),
        counts={k: int(getattr(built, k)) for k in ("occupied", "target", "free")},
        seconds={"plane": t1 - t0, "field": t2 - t1, "scene": t3 - t2},
        obstacles=built.obstacles,
    )
