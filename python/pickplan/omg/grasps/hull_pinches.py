"""Pinches of a part seen from one side only: a pitcher's handle, a tool's grip turned from the cameras.

An antipodal pair needs both contact patches observed. Where only one face of a part is seen, the
target's visibility hull (``perception.hull``: the space no camera saw empty) bounds the hidden one:
closing along the seen face's normal, the far pad meets the target no further than the hull reaches
behind the face. When that depth fits the opening, the pinch is a candidate: its pads centred between
the seen face and the hull's far side, turned about the closing axis as antipodal pairs are. The open
hand must then clear the hull as well as the points (``points.grasps_from_points``), and the quality
judges the grip with the unseen side mirroring the seen one. The cameras look down on the support, so
the hull is carved beside a seen face but fills the shadow under it: only closing axes near level are
used (``PointGraspSettings.hull_pinch_slope``).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.spatial import cKDTree

from pickplan.omg.grasps.point_geometry import first_per_voxel, turned_frames

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
    seeds = coherent[first_per_voxel(P[coherent], s.patch_radius)]
    X = np.vstack([P, H])
    opening = s.max_width - s.width_margin
    half_pad = s.pad_width / 2
    # the tube from half a pad in front of the face to half a pad beyond the opening lies in this ball
    # (a target deeper than the opening has samples in that last stretch: 5 mm hull voxels)
    middle = P[seeds] - N[seeds] * opening / 2
    lists = cKDTree(X).query_ball_point(middle, np.hypot(opening / 2 + half_pad, half_pad))
    owner = np.repeat(np.arange(len(seeds)), [len(n) for n in lists])  # flattened (seed, neighbour) pairs
    near = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=len(owner))
    inward = -N[seeds]
    rel = X[near] - P[seeds][owner]
    depth = np.einsum("ij,ij->i", rel, inward[owner])
    lateral = np.linalg.norm(rel - depth[:, None] * inward[owner], axis=1)
    tube = lateral <= half_pad
    front = np.zeros(len(seeds), bool)  # something stands in front of the face: not the target's outside
    front[owner[tube & (depth < -s.clearance)]] = True
    width = np.full(len(seeds), -np.inf)
    np.maximum.at(width, owner[tube], depth[tube])
    ok = ~front & (width >= s.min_width) & (width <= opening)
    if not ok.any():
        return []
    y, w = inward[ok], width[ok]
    turns = np.broadcast_to(2 * np.pi * np.arange(s.approach_angles) / s.approach_angles, (len(y), s.approach_angles))
    frames = turned_frames(y, P[seeds[ok]] + 0.5 * w[:, None] * y, turns)  # the same turns for every seed
    return [(f, HULL_PINCH_MARGIN, wk) for f, wk in zip(frames.reshape(-1, 4, 4), np.repeat(w, s.approach_angles))]
