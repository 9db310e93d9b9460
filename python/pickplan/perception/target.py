"""The target as the object nearest a point in space (a point clicked in RViz, or given in a request).

In each view the pixels with depth higher above the support plane than ``min_height`` are joined
into surface segments through 4-neighbours whose depths differ by at most ``max_step`` (the rule of
``core.observation.grow_target``, as connected components of that pixel graph); the target is, per view, the segment holding the pixel nearest the
point, if that pixel is within ``max_distance`` of it. A view where none is that close does not see
the target (its mask is empty); no view seeing it is an ``ObservationError``.

>>> plane = support_plane(view_points(depth, K, poses, 4))
>>> mask = target_near_point(depth, K, poses, (0.55, 0.02, 0.08), plane)   # (V, H, W) bool
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence, Tuple

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from pickplan.core.observation import ObservationError
from pickplan.perception.field import pixel_points


@dataclass(frozen=True)
class TargetSettings:
    max_distance: float = 0.05  # m: the segment's nearest pixel must be this close to the point
    min_height: float = 0.005  # m above the support plane: pixels lower than this are the plane's
    max_step: float = 0.01  # m: a larger depth step between 4-neighbours separates two segments
    min_pixels: int = 20  # smaller segments are speckle, never the target


def _segments(depth: np.ndarray, above: np.ndarray, max_step: float) -> np.ndarray:
    """(H, W) segment labels: pixels of ``above`` joined to their 4-neighbours in ``above`` whose depth
    differs by at most ``max_step`` (connected components of that graph); -1 off ``above``."""
    index = np.full(depth.shape, -1)
    count = int(above.sum())
    index[above] = np.arange(count)  # a node per pixel above the plane: a few percent of the image
    with np.errstate(invalid="ignore"):
        across = above[:, :-1] & above[:, 1:] & (np.abs(np.diff(depth, axis=1)) <= max_step)
        down = above[:-1] & above[1:] & (np.abs(np.diff(depth, axis=0)) <= max_step)
    rows = np.concatenate([index[:, :-1][across], index[:-1][down]])
    cols = np.concatenate([index[:, 1:][across], index[1:][down]])
    graph = coo_matrix((np.ones(len(rows), np.int8), (rows, cols)), shape=(count, count))
    labels = np.full(depth.shape, -1)
    labels[above] = connected_components(graph, directed=False)[1]
    return labels


def _heights(d: np.ndarray, K: np.ndarray, pose: np.ndarray, n: np.ndarray, off: float) -> np.ndarray:
    """(H, W) height of each pixel's point above the plane n . x = off (NaN without depth): linear in
    the depth along each pixel's ray, so no point is formed (``backproject``'s pixel convention)."""
    H, W = d.shape
    m = pose[:3, :3].T @ n  # the plane's normal in the camera frame
    x = (np.arange(W) + 0.5 - K[0, 2]) / K[0, 0]
    y = (np.arange(H) + 0.5 - K[1, 2]) / K[1, 1]
    with np.errstate(invalid="ignore"):
        return d * (m[0] * x[None, :] + m[1] * y[:, None] + m[2]) + (pose[:3, 3] @ n - off)


def target_near_point(
    depth: np.ndarray,
    K: np.ndarray,
    camera_pose: np.ndarray,
    point: Sequence[float],
    plane: Tuple[np.ndarray, float],
    settings: TargetSettings = TargetSettings(),
    source: str = "<memory>",
) -> np.ndarray:
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
        d = np.where(np.isfinite(depth[v]) & (depth[v] > 0), depth[v], np.nan)
        above = _heights(d, K[v], poses[v], n, off) > settings.min_height  # NaN: False
        if not above.any():
            continue
        labels = _segments(d, above, settings.max_step)
        sizes = np.bincount(labels[above])
        rows, cols = np.nonzero(above & (sizes[np.maximum(labels, 0)] >= settings.min_pixels))
        if len(rows) == 0:
            continue
        X = pixel_points(d[rows, cols], rows, cols, K[v], poses[v])
        dist = np.linalg.norm(X - p, axis=1)
        k = int(np.argmin(dist))
        nearest = min(nearest, float(dist[k]))
        if dist[k] <= settings.max_distance:
            masks[v] = labels == labels[rows[k], cols[k]]
    if not masks.any():
        what = f"the nearest is {nearest:.3f} m away" if np.isfinite(nearest) else "no view shows an object"
        raise ObservationError(
            f"{source}: target point: no object within {settings.max_distance} m of "
            f"({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f}) above the support plane ({what})"
        )
    return masks
