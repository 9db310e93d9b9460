"""Pinches of a part seen from one side only: a pitcher's handle, a tool's grip turned from the cameras.

An antipodal pair needs both contact patches observed. Where only one face of a part is seen, the
target's visibility hull (``perception.hull``: the space no camera saw empty) bounds the hidden one:
closing along the seen face's normal, the far pad meets the target no further than the hull reaches
behind the face. When that depth fits the opening, the pinch is a candidate: its pads centred between
the seen face and the hull's far side, turned about the closing axis as antipodal pairs are. The open
hand must then clear the hull as well as the points (``points.grasps_from_points``), and the quality
judges the grip with the unseen side mirroring the seen one.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

# Candidates score below observed pairs (margin 0.9-1): one side is a bound, not a measurement.
HULL_PINCH_MARGIN = 0.3


def hull_pinch_candidates(P, N, coherence, H, up, s) -> list:
    """(frame, margin, width) candidates (``points`` candidate tuples) closing along the fitted normals
    ``N`` of coherent patches of ``P`` (one seed per ``patch_radius`` voxel), sized on the points and
    hull samples ``H`` in a pad-wide tube behind each seed. Only normals within ``s.hull_pinch_slope``
    of the support plane (normal ``up``): under a seen face the hull is the face's shadow, not a bound
    anything saw (a pitcher's lip pinched top to bottom closes on 2 mm where the hull promised 7 cm).
    ``s``: resolved ``PointGraspSettings``."""
    if len(H) == 0 or len(P) == 0:
        return []
    level = np.abs(N @ np.asarray(up, float)) <= np.sin(s.hull_pinch_slope)
    coherent = np.flatnonzero((coherence >= s.patch_coherence) & level)
    if len(coherent) == 0:
        return []
    seeds = coherent[_first_per_voxel(P[coherent], s.patch_radius)]
    X = np.vstack([P, H])
    tree = cKDTree(X)
    opening = s.max_width - s.width_margin
    half_pad = s.pad_width / 2
    out = []
    for i, near in zip(seeds, tree.query_ball_point(P[seeds], opening + half_pad)):
        inward = -N[i]
        rel = X[near] - P[i]
        depth = rel @ inward
        lateral = np.linalg.norm(rel - np.outer(depth, inward), axis=1)
        tube = lateral <= half_pad
        if (depth[tube] < -s.clearance).any():  # something stands in front of the face: not its outside
            continue
        width = float(depth[tube].max())
        if not s.min_width <= width <= opening:
            continue
        centre = P[i] + 0.5 * width * inward
        for frame in _turned_frames(inward, centre, s.approach_angles):
            out.append((frame, HULL_PINCH_MARGIN, width))
    return out


def _first_per_voxel(P: np.ndarray, cell: float) -> np.ndarray:
    """Indices, ascending, of the first point of ``P`` in each ``cell``-sized voxel."""
    _, first = np.unique(np.floor(P / cell).astype(np.int64), axis=0, return_index=True)
    return np.sort(first)


def _turned_frames(y: np.ndarray, centre: np.ndarray, turns: int):
    """Grasp frames closing along ``y`` with the pads' centre at ``centre``, approaches ``turns`` even
    steps round ``y`` (the same turns for every seed: no random draw)."""
    ref = np.array([1.0, 0.0, 0.0]) if abs(y[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    z0 = np.cross(y, ref)
    z0 /= np.linalg.norm(z0)
    z1 = np.cross(y, z0)
    for k in range(turns):
        t = 2 * np.pi * k / turns
        z = np.cos(t) * z0 + np.sin(t) * z1
        F = np.eye(4)
        F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = np.cross(y, z), y, z, centre
        yield F
