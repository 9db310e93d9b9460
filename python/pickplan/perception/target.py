"""The target as the object nearest a point in space (a point clicked in RViz, or given in a request).

In each view the pixels with depth higher above the support plane than ``min_height`` are split into
surface segments wherever neighbouring depths step by more than ``max_step`` (the rule of
``core.observation.grow_target``); the target is, per view, the segment holding the pixel nearest the
point, if that pixel is within ``max_distance`` of it. A view where none is that close does not see
the target (its mask is empty); no view seeing it is an ``ObservationError``.

>>> plane = support_plane(view_points(depth, K, poses, 4))
>>> mask = target_near_point(depth, K, poses, (0.55, 0.02, 0.08), plane)   # (V, H, W) bool
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np
from scipy import ndimage

from pickplan.core.observation import ObservationError
from pickplan.perception.field import backproject


@dataclass(frozen=True)
class TargetSettings:
    max_distance: float = 0.05   # m: the segment's nearest pixel must be this close to the point
    min_height: float = 0.005    # m above the support plane: pixels lower than this are the plane's
    max_step: float = 0.01       # m: a larger depth step between 4-neighbours separates two segments
    min_pixels: int = 20         # smaller segments are speckle, never the target


def _segments(depth: np.ndarray, above: np.ndarray, max_step: float) -> Tuple[np.ndarray, int]:
    """Labels of the 4-connected pixels of ``above`` that no depth step larger than ``max_step``
    separates; pixels on a step belong to no segment (0) but the nearer side's (restored by
    ``_with_rim``)."""
    d = np.where(above, depth, np.nan)
    step = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        dx = np.abs(np.diff(d, axis=1)) > max_step
        dy = np.abs(np.diff(d, axis=0)) > max_step
    step[:, 1:] |= dx
    step[:, :-1] |= dx
    step[1:] |= dy
    step[:-1] |= dy
    return ndimage.label(above & ~step)


def _with_rim(labels: np.ndarray, chosen: int, depth: np.ndarray, above: np.ndarray, max_step: float) -> np.ndarray:
    """The chosen segment grown by the step pixels that continue its surface (depth within ``max_step``
    of a neighbour in the segment)."""
    mask = labels == chosen
    rim = ndimage.binary_dilation(mask) & above & (labels == 0)
    if not rim.any():
        return mask
    near = np.pad(np.where(mask, depth, np.nan), 1, constant_values=np.nan)
    H, W = depth.shape
    grown = mask.copy()
    for dr, dc in ((0, 1), (2, 1), (1, 0), (1, 2)):  # the 4 neighbours in the padded image
        with np.errstate(invalid="ignore"):
            grown |= rim & (np.abs(near[dr:dr + H, dc:dc + W] - depth) <= max_step)
    return grown


def target_near_point(depth: np.ndarray, K: np.ndarray, camera_pose: np.ndarray, point: Sequence[float],
                      plane: Tuple[np.ndarray, float], settings: TargetSettings = TargetSettings(),
                      source: str = "<memory>") -> np.ndarray:
    """(V, H, W) target mask: per view the surface segment nearest ``point`` (world, m) above
    ``plane`` (unit normal n up, offset d: n . x = d); see the module doc."""
    depth = np.asarray(depth, float)
    depth = depth[None] if depth.ndim == 2 else depth
    K, poses = np.asarray(K, float).reshape(-1, 3, 3), np.asarray(camera_pose, float).reshape(-1, 4, 4)
    p = np.asarray(point, float)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ObservationError(f"{source}: target point: expected 3 finite coordinates, got {point!r}")
    n, off = np.asarray(plane[0], float), float(plane[1])
    masks = np.zeros(depth.shape, dtype=bool)
    nearest = np.inf
    for v in range(len(depth)):
        X = backproject(depth[v], K[v], poses[v])
        with np.errstate(invalid="ignore"):
            above = np.isfinite(X[..., 2]) & (X @ n - off > settings.min_height)
        labels, count = _segments(depth[v], above, settings.max_step)
        if count == 0:
            continue
        sizes = np.bincount(labels.ravel(), minlength=count + 1)
        usable = (labels > 0) & (sizes[labels] >= settings.min_pixels)
        if not usable.any():
            continue
        rows, cols = np.nonzero(usable)
        dist = np.linalg.norm(X[rows, cols] - p, axis=1)
        k = int(np.argmin(dist))
        nearest = min(nearest, float(dist[k]))
        if dist[k] <= settings.max_distance:
            masks[v] = _with_rim(labels, labels[rows[k], cols[k]], depth[v], above, settings.max_step)
    if not masks.any():
        what = f"the nearest is {nearest:.3f} m away" if np.isfinite(nearest) else "no view shows an object"
        raise ObservationError(f"{source}: target point: no object within {settings.max_distance} m of "
                               f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) above the support plane ({what})")
    return masks
