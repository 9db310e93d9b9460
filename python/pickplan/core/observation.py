"""What a depth camera gives the planner: depth images with intrinsics and poses, and the target.

File format (``.npz``, written by ``Observation.save``, read by ``Observation.load``):

=============== ================ =====================================================================
key             shape, dtype     meaning
=============== ================ =====================================================================
``depth``       (V, H, W) f4     metres along each camera's optical axis; 0 or NaN: no return
``K``           (V, 3, 3) f8     pinhole intrinsics [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]; pixel (r, c)
                                 covers [c, c + 1) x [r, r + 1)
``camera_pose`` (V, 4, 4) f8     camera -> world, OpenCV axes (z forward, x right, y down)
``target_mask`` (V, H, W) u1     nonzero where the target is (or ``target_pixel`` instead)
``target_pixel`` (V, 2) i4       (row, col) on the target in each view, -1 where it is not seen: grown
                                 to the connected surface segment (``grow_target``)
``rgb``         (V, H, W, 3) u1  optional colour
``format``      str              ``"pickplan.observation"``; ``version`` int: 1
=============== ================ =====================================================================
"""
from __future__ import annotations

import io
import os
from collections import deque
from dataclasses import dataclass
from typing import Optional

import numpy as np

from pickplan.core.io import atomic_open

FORMAT = "pickplan.observation"
VERSION = 1
MIN_VALID_FRACTION = 0.1   # a view with fewer depth returns than this is refused
RIGID_TOL = 1e-5


class ObservationError(ValueError):
    """An observation that cannot be used (the file and field are named)."""


@dataclass(eq=False)
class Observation:
    depth: np.ndarray          # (V, H, W) float32
    K: np.ndarray              # (V, 3, 3)
    camera_pose: np.ndarray    # (V, 4, 4)
    target_mask: np.ndarray    # (V, H, W) bool
    rgb: Optional[np.ndarray] = None
    source: str = "<memory>"

    def __post_init__(self):
        self.depth, self.K, self.camera_pose, self.target_mask, self.rgb = _validated(
            self.depth, self.K, self.camera_pose, self.target_mask, self.rgb, self.source)

    @property
    def views(self) -> int:
        return int(self.depth.shape[0])

    def save(self, path) -> None:
        data = {"depth": self.depth, "K": self.K, "camera_pose": self.camera_pose,
                "target_mask": self.target_mask.astype(np.uint8), "format": np.array(FORMAT),
                "version": np.array(VERSION)}
        if self.rgb is not None:
            data["rgb"] = self.rgb
        buf = io.BytesIO()
        np.savez_compressed(buf, **data)
        with atomic_open(os.fspath(path), "wb") as f:
            f.write(buf.getvalue())

    @classmethod
    def load(cls, path) -> "Observation":
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"observation file not found: {path}")
        try:
            with np.load(path, allow_pickle=False) as z:
                data = {k: z[k] for k in z.files}
        except (ValueError, OSError, EOFError) as exc:
            raise ObservationError(f"{path}: not a readable .npz observation ({exc})") from None
        if str(data.get("format", "")) != FORMAT:
            raise ObservationError(f"{path}: format: expected {FORMAT!r}, got {str(data.get('format'))!r}")
        for key in ("depth", "K", "camera_pose"):
            if key not in data:
                raise ObservationError(f"{path}: {key}: missing")
        depth = data["depth"]
        if "target_mask" in data:
            mask = data["target_mask"]
        elif "target_pixel" in data:
            mask = grow_target(np.asarray(depth, float), data["target_pixel"], path)
        else:
            raise ObservationError(f"{path}: target_mask or target_pixel: missing (the target must be given)")
        return cls(depth, data["K"], data["camera_pose"], mask, data.get("rgb"), source=path)


def _validated(depth, K, pose, mask, rgb, source):
    def fail(field, message):
        raise ObservationError(f"{source}: {field}: {message}")

    depth = np.asarray(depth)
    if depth.ndim == 2:
        depth = depth[None]
    if depth.ndim != 3 or min(depth.shape[1:]) < 2 or depth.shape[0] < 1:
        fail("depth", f"expected shape (V, H, W), got {depth.shape}")
    if not np.issubdtype(depth.dtype, np.floating):
        fail("depth", f"expected metres as floats, got {depth.dtype}")
    V, H, W = depth.shape
    depth = depth.astype(np.float32)
    for name, arr, shape in (("K", K, (V, 3, 3)), ("camera_pose", pose, (V, 4, 4))):
        a = np.asarray(arr, dtype=float)
        a = a[None] if a.ndim == len(shape) - 1 else a
        if a.shape != shape:
            fail(name, f"expected shape {shape}, got {np.asarray(arr).shape}")
        if not np.all(np.isfinite(a)):
            fail(name, "not finite")
        if name == "K":
            K = a
        else:
            pose = a
    valid = np.isfinite(depth) & (depth > 0)
    if np.any(np.isinf(depth)) or np.any(depth < 0):
        fail("depth", "negative or infinite values (use 0 or NaN for pixels without a return)")
    for v in range(V):
        if valid[v].mean() < MIN_VALID_FRACTION:
            fail("depth", f"view {v} has depth in only {100 * valid[v].mean():.1f} % of its pixels "
                          f"(need {100 * MIN_VALID_FRACTION:.0f} %): zero, NaN or missing depth")
        k = K[v]
        if not (k[0, 0] > 0 and k[1, 1] > 0 and np.allclose(k[2], [0, 0, 1]) and k[1, 0] == 0):
            fail("K", f"view {v}: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        R = pose[v, :3, :3]
        if (np.abs(R @ R.T - np.eye(3)).max() > RIGID_TOL or np.linalg.det(R) < 0
                or np.abs(pose[v, 3] - [0, 0, 0, 1]).max() > RIGID_TOL):
            fail("camera_pose", f"view {v} is not a rigid transform")
    mask = np.asarray(mask)
    mask = mask[None] if mask.ndim == 2 else mask
    if mask.shape != (V, H, W):
        fail("target_mask", f"expected shape {(V, H, W)} like depth, got {mask.shape}")
    mask = mask.astype(bool)
    if not np.any(mask & valid):
        fail("target_mask", "the target has no pixel with depth in any view")
    if rgb is not None:
        rgb = np.asarray(rgb)
        if rgb.shape != (V, H, W, 3):
            fail("rgb", f"expected shape {(V, H, W, 3)}, got {rgb.shape}")
        rgb = rgb.astype(np.uint8)
    return depth, K, pose, mask, rgb


def grow_target(depth: np.ndarray, pixels, source: str = "<memory>", max_step: float = 0.01) -> np.ndarray:
    """A target mask from one (row, col) per view: the 4-connected pixels reachable through depth
    steps below ``max_step`` m (one surface segment; -1 marks a view that does not see the target)."""
    depth = np.asarray(depth, float)
    depth = depth[None] if depth.ndim == 2 else depth
    pixels = np.asarray(pixels, dtype=int).reshape(-1, 2)
    if len(pixels) != len(depth):
        raise ObservationError(f"{source}: target_pixel: expected {len(depth)} (row, col) pairs, got {len(pixels)}")
    mask = np.zeros(depth.shape, dtype=bool)
    H, W = depth.shape[1:]
    for v, (r, c) in enumerate(pixels):
        if r < 0 or c < 0:
            continue
        if r >= H or c >= W or not np.isfinite(depth[v, r, c]) or depth[v, r, c] <= 0:
            raise ObservationError(f"{source}: target_pixel: view {v} pixel {(r, c)} has no depth or is outside "
                                   f"the {H} x {W} image")
        queue = deque([(r, c)])
        mask[v, r, c] = True
        while queue:
            i, j = queue.popleft()
            for a, b in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)):
                if 0 <= a < H and 0 <= b < W and not mask[v, a, b] and np.isfinite(depth[v, a, b]) \
                        and depth[v, a, b] > 0 and abs(depth[v, a, b] - depth[v, i, j]) < max_step:
                    mask[v, a, b] = True
                    queue.append((a, b))
    return mask
