"""Grasps from what a depth camera sees of the target: observed surface points with normals, the
support plane, and the rest of the scene as a field. No mesh and no stored grasp is read.

Three kinds of candidates, all in the world frame (a ``GraspSet`` whose object frame is the world):

- antipodal pairs: a point p and a point q seen on the opposite side (q - p within the friction cone
  of -n_p and of n_q, the width within the opening), the pads centred on their midpoint, the hand
  turned about the closing axis;
- footprint grasps: the target's points projected onto the support plane give its width across each
  closing direction even when one side is hidden. From above (tilted up to ``max_tilt`` off
  vertical), the width and the pads' centre come from the cross-section the pads close on (the points
  from the pads' lower edge up: a bottle's cap, not its body); from the side (approach horizontal),
  from a section at half the height and one a pad under the top, the pads a depth in from its edge;
- rim pinches of open containers (one pad inside the wall, the pads lying on it as it leans, the
  inner finger stopping above a floor);
- local grasps from above across a part of the footprint (a blade, a handle, a loop: thin targets
  whose whole footprint is wider than the opening), the fingertips resting on the support.

Every candidate is kept only if its fingertips stay above the support plane (less a contact
tolerance: resting on the table is fine), no observed target point (and, if given, no sample of the
target's visibility hull, ``perception.hull``) lies inside the open hand (``hand_sdf``), and the hand
is clear of the other obstacles (``scene_distance``). Scores from points: antipodal margin, how much
of the pads the points fill, the spare opening, and gravity's lever arm about the closing axis from a
centre of mass estimated from the points (a pinch beside the mass turns the target out of the pads).
Candidates are checked in score order until enough pass.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Optional

import numpy as np
from scipy.spatial import cKDTree

from pickplan import _core
from pickplan.core.description import RobotInfo
from pickplan.core.panda import PANDA
from pickplan.omg.grasps.hull_pinches import hull_pinch_candidates
from pickplan.omg.grasps.point_geometry import (
    _neighbourhoods,
    _unit_means,
    denoised,
    fitted_normals,
    gravity_lever,
    thinned,
    turned_frames,
)
from pickplan.omg.grasps.sets import GraspSet, _check_count, _perpendicular


@dataclass(frozen=True)
class PointGraspSettings:
    friction: float = 0.3  # Coulomb coefficient: the friction cone's half-angle atan(0.3)
    max_width: Optional[float] = None  # m; None: the gripper's opening
    width_margin: Optional[float] = None  # m widths must stay below the opening; None: twice ``clearance``
    #                                   (the open hand must clear the points by ``clearance`` on each side; the
    #                                   open-hand check decides, and noise only widens observed extents)
    min_width: float = 0.004
    pad_length: Optional[float] = None  # m of finger along the approach axis that grips; None: the gripper's
    pad_width: Optional[float] = None  # m across the finger; None: the gripper's
    table_contact: float = 0.003  # m the fingertips may press into the support plane
    clearance: float = 0.003  # m kept between the open hand and observed target points
    obstacle_clearance: float = 0.005  # m kept between hand sample points and the other obstacles
    approach_angles: int = 8  # turns about the closing axis tried per antipodal pair
    yaw_steps: int = 12  # closing directions tried for footprint grasps
    max_tilt: float = 0.6  # rad off vertical for footprint grasps' approaches
    grasp_depths: tuple = (0.012, 0.025, 0.04)  # m below the target's top for the pads' centre
    samples: int = 600  # antipodal seed points
    hand_reach: float = 0.15  # m from the hand frame's origin that bounds the open hand
    max_candidates: int = 2000  # antipodal candidates (pairs x turns) checked: a seeded subset beyond
    rim_band: float = 0.01  # m below the target's top where rim pinches are tried
    rim_samples: int = 40  # rim points tried
    rim_wall: float = 0.01  # m, the wall thickness a rim pinch assumes (centred 5 mm inside)
    rim_finger_reach: float = 0.02  # m inwards from the inner pad that the inner finger's body covers
    rim_overlap: float = 1 / 3  # of the pads' length at least on a pinched wall, under its top's points
    patch_radius: float = 0.008  # m, an antipodal contact's patch (about half a pad)
    patch_coherence: float = 0.9  # the patch's normals' mean length an antipodal contact needs
    denoise: bool = True  # points moved onto their patch's mean plane, normals fitted (``denoised``)
    section_trim: float = 0.01  # fraction of a cross-section's points beyond each end of its width (noise)
    spare_weight: float = 0.5  # score per spare opening (fraction of the opening)
    lever_scale: float = 0.05  # m of gravity's lever arm about the closing axis that costs one score point
    local_samples: int = 40  # footprint points local grasps from above are centred at (``local_candidates``)
    max_face_turn: float = 0.35  # rad a section's end may turn from the pads (``quality``'s align_deg, 20 deg)
    # rad the closing axis of a pinch bounded by the visibility hull may rise from the support plane: the
    # cameras look down on it, so the hull is carved beside a seen face but fills the shadow under it
    hull_pinch_slope: float = 0.785


def _frames(y: np.ndarray, z: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Grasp-frame poses: closing axis y, approach z, the pad centre at ``centre``."""
    (y0, y1, y2), (z0, z1, z2), (c0, c1, c2) = y.tolist(), z.tolist(), centre.tolist()
    # y x z written out: np.cross's per-call overhead dominated the candidate loops (the same products)
    return np.array(
        [
            [y1 * z2 - y2 * z1, y0, z0, c0],
            [y2 * z0 - y0 * z2, y1, z1, c1],
            [y0 * z1 - y1 * z0, y2, z2, c2],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _frames_many(y: np.ndarray, z: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """``_frames`` of (K, 3) rows at once (elementwise: the same values)."""
    F = np.zeros((len(y), 4, 4))
    F[:, :3, 0] = np.column_stack(
        [
            y[:, 1] * z[:, 2] - y[:, 2] * z[:, 1],
            y[:, 2] * z[:, 0] - y[:, 0] * z[:, 2],
            y[:, 0] * z[:, 1] - y[:, 1] * z[:, 0],
        ]
    )
    F[:, :3, 1], F[:, :3, 2], F[:, :3, 3], F[:, 3, 3] = y, z, centre, 1.0
    return F


def antipodal_candidates(P, N, s: PointGraspSettings, rng, near=None) -> list:
    """Pairs whose contact patches (``patch_normals`` over ``patch_radius``) are coherent and within
    each other's friction cone: a pair across a box's edges, whose noisy point normals lean towards
    each other, is not a pinch. ``near``: P's patch neighbourhoods (``_neighbourhoods``) if known."""
    cone = np.cos(np.arctan(s.friction))
    N, coherence = _unit_means(*(near or _neighbourhoods(P, s.patch_radius)), N, len(P))
    seeds = rng.choice(len(P), min(s.samples, len(P)), replace=False)
    # only coherent patches pair up: the others are dropped before the pairs are formed (same pairs, in
    # the same order, as testing coherence after the cone)
    coherent = coherence >= s.patch_coherence
    seeds = seeds[coherent[seeds]]
    # each seed's coherent partners within the opening that pass the width and friction-cone tests,
    # found natively among 10^5-10^6 with a cone a hair wider, in the order of a k-d tree's unsorted
    # ball query (its leaf order: the seeded subset below draws from the pairs in that order), then
    # measured here as numpy measures them (einsum's sums differ in the last bit)
    i, j, _, _ = _core.antipodal_partners(
        P, N, seeds, s.max_width - s.width_margin, coherent, cKDTree(P).indices, s.min_width, cone - 1e-9
    )
    widths = np.linalg.norm(P[j] - P[i], axis=1)
    axes = (P[j] - P[i]) / widths[:, None]
    margins = np.minimum(-np.einsum("ij,ij->i", axes, N[i]), np.einsum("ij,ij->i", N[j], axes))
    ok = margins >= cone
    # (i, j, margin, width) of the pairs that pass the width and friction-cone tests
    pairs = np.column_stack([i[ok], j[ok], margins[ok], widths[ok]])
    most = max(1, s.max_candidates // s.approach_angles)
    if len(pairs) > most:  # dense clouds (3 views) pass 10^4-10^5 pairs: a seeded subset
        pairs = pairs[np.sort(rng.choice(len(pairs), most, replace=False))]
    if len(pairs) == 0:
        return []
    i, j, margin, w = pairs[:, 0].astype(int), pairs[:, 1].astype(int), pairs[:, 2], pairs[:, 3]
    axis = (P[j] - P[i]) / w[:, None]
    theta = (
        rng.uniform(0, 2 * np.pi, len(pairs))[:, None] + 2 * np.pi * np.arange(s.approach_angles) / s.approach_angles
    )
    F = turned_frames(axis, 0.5 * (P[i] + P[j]), theta)
    return [
        (f, m, wk)
        for f, m, wk in zip(F.reshape(-1, 4, 4), np.repeat(margin, s.approach_angles), np.repeat(w, s.approach_angles))
    ]


def _section(rel, sel, y, x, trim: float):
    """The points ``rel[sel]`` (footprint-relative, flattened): their width across ``y`` and the
    middle of their extents along ``y`` and ``x`` (None when fewer than 3). The width runs between
    the ``trim`` and ``1 - trim`` quantiles: the extremes of noisy points overstate it by a few
    standard deviations, while a face the pads close on holds far more than ``trim`` of the points
    (and a curved side's ``trim`` quantile lies microns inside it)."""
    if sel.sum() < 3:
        return None, None
    py, px = rel[sel] @ y, rel[sel] @ x
    lo, hi = _core.sorted_quantiles(np.sort(py), (trim, 1.0 - trim))
    return float(hi - lo), 0.5 * (hi + lo) * y + 0.5 * (px.max() + px.min()) * x


def footprint_candidates(P, plane, s: PointGraspSettings) -> list:
    """Grasps from above (and from the side, ``_side_candidates``) across the target's cross-section:
    at each pad depth, the points from the pads' lower edge up (what passes between the fingers)
    give the width and the middle the pads are centred on (a bottle's cap, not its footprint)."""
    n, d = plane
    lo_h = P @ n - d  # heights above the plane
    top = float(lo_h.max())
    flat = P - np.outer(lo_h, n)
    centre_flat = flat.mean(axis=0)
    rel = flat - centre_flat
    e1 = _perpendicular(n)
    e2 = np.cross(n, e1)
    out = []
    # the coarse steps miss the narrow side of an elongated footprint (a box 6 x 16 cm seen 7.5
    # degrees off is 8 cm wide), so the narrowest of 180 directions joins them
    fine = np.pi * np.arange(180) / 180
    spans = np.ptp(rel @ np.column_stack([e1, e2]) @ np.vstack([np.cos(fine), np.sin(fine)]), axis=0)
    fits = lambda w: w is not None and s.min_width <= w <= s.max_width - s.width_margin  # noqa: E731
    for a in np.append(np.pi * np.arange(s.yaw_steps) / s.yaw_steps, fine[np.argmin(spans)]):
        y = np.cos(a) * e1 + np.sin(a) * e2
        x = np.cross(y, n)
        sections = {}  # per pad height: the tilts share most heights (and so their sections)
        for tilt in (0.0, s.max_tilt / 2, -s.max_tilt / 2, s.max_tilt, -s.max_tilt):
            z = -np.cos(tilt) * n + np.sin(tilt) * x  # down, tilted about the closing axis
            # pad centre heights above the plane, from just under the top down as far as the hand
            # reaches (the open-hand check rejects those whose palm meets the object), no lower
            # than the fingertips (half a pad further along the approach) allow
            lowest = s.pad_length / 2 * abs(np.cos(tilt)) - s.table_contact
            for depth in s.grasp_depths:
                height = max(lowest, top - depth)
                if height not in sections:
                    sections[height] = _section(rel, lo_h >= height - s.pad_length / 2, y, x, s.section_trim)
                width, mid = sections[height]
                if fits(width):
                    centre = centre_flat + mid + height * n  # centre_flat lies on the plane
                    out.append((_frames(y, z, centre), 1.0 - abs(tilt) / (np.pi / 2), width))
                if height == lowest:
                    break
        for height in sorted({max(s.pad_length / 2, h) for h in (top / 2, top - s.pad_length)}):
            band = np.abs(lo_h - height) <= s.pad_length / 2
            width, mid = _section(rel, band, y, x, s.section_trim)
            if fits(width):
                out += _side_candidates(rel[band] - mid, centre_flat + mid + height * n, y, x, width, s)
    return out


def local_candidates(P, plane, s: PointGraspSettings, rng) -> list:
    """Grasps from above across a part of the target: at seeded points of its footprint and for each
    closing direction, the points in the band the pads sweep (a pad's width across, the open pads'
    span along) give the width and the middle of the part between them: a blade or a loop of
    scissors, a hammer's handle, a long box anywhere along it (a thin target's whole footprint is
    often wider than the opening in every direction). The part is the run of points through the
    sampled one with no gap wider than twice the clearance (not a neighbouring part beyond a gap:
    whether a finger fits in that gap is the open-hand check's to say); both of its ends must turn at
    most ``max_face_turn`` from the pads across their width (across a part, not diagonally over a
    corner of it, whose two faces would squeeze it out of the pads). The sections are found natively
    (``_core.local_sections``). The pads' centre ``grasp_depths[0]`` under the part's top, as low as
    fingertips resting on the support allow (a thin target's points stand a few noise widths above
    the plane: the fingers go down to it); upright and tilted about the closing axis."""
    n, d = plane
    height = P @ n - d
    flat = P - np.outer(height, n)
    e1 = _perpendicular(n)
    E = np.column_stack([e1, np.cross(n, e1)])
    angles = np.pi * np.arange(s.yaw_steps) / s.yaw_steps
    Y2 = np.column_stack([np.cos(angles), np.sin(angles)])
    X2 = np.column_stack([-Y2[:, 1], Y2[:, 0]])
    F2 = flat @ E
    native = _core.SectionSettings()
    native.pad_width, native.max_width, native.gap = s.pad_width, s.max_width, 2 * s.clearance
    native.trim, native.min_width, native.fit_width = s.section_trim, s.min_width, s.max_width - s.width_margin
    native.face_tolerance = np.tan(s.max_face_turn) * s.pad_width / 2
    tilts = (0.0, s.max_tilt / 2, -s.max_tilt / 2)
    # only points this near the sampled one can lie in a band (|across| <= pad_width / 2, |along| <=
    # max_width; a hair of slack for rounding): the others are left out, the rest keep their order
    reach2 = ((s.pad_width / 2) ** 2 + s.max_width**2) * (1 + 1e-6)
    found = []  # per section: the sampled point, then (yaw, lo, hi, across_min, across_max, top)
    for i in rng.choice(len(P), min(s.local_samples, len(P)), replace=False):
        rel = F2 - F2[i]
        near = np.flatnonzero(np.einsum("ij,ij->i", rel, rel) <= reach2)
        ry, rx = rel[near] @ Y2.T, rel[near] @ X2.T
        found += [(i, *row) for row in _core.local_sections(ry, rx, height[near], native)]
    if not found:
        return []
    # all sections' frames at once: each yaw's axes as one vector product each (as per section before),
    # the rest elementwise (the same values)
    i, a, lo, hi, u_min, u_max, top = np.array(found).T
    i, a = i.astype(int), a.astype(int)
    Yw = np.array([E @ Y2[k] for k in range(s.yaw_steps)])[a]
    Xw = np.array([E @ X2[k] for k in range(s.yaw_steps)])[a]
    mid = flat[i] + (0.5 * (lo + hi))[:, None] * Yw + (0.5 * (u_max + u_min))[:, None] * Xw
    frames, scores = [], []
    for tilt in tilts:
        lowest = s.pad_length / 2 * abs(np.cos(tilt)) - s.table_contact
        centre = mid + np.maximum(lowest, top - s.grasp_depths[0])[:, None] * n
        frames.append(_frames_many(Yw, -np.cos(tilt) * n + np.sin(tilt) * Xw, centre))
        scores.append(0.9 - abs(tilt) / (np.pi / 2))
    F = np.stack(frames, axis=1).reshape(-1, 4, 4)  # per section, its tilts in turn
    return list(zip(F, np.tile(scores, len(found)).tolist(), np.repeat(hi - lo, len(tilts)).tolist()))


def _side_candidates(rel, centre, y, x, width, s: PointGraspSettings) -> list:
    """Grasps from the side across a cross-section at the pads' height (``rel``: its points relative
    to its middle ``centre``): the approach horizontal (along +-x), the pads ``grasp_depths`` in from
    the section's near edge (tall targets whose top alone leaves few grasps: an upright box, a
    bottle's body under its cap). Scored below grasps from above (margin 0.3, not 1: the palm faces
    the scene)."""
    out = []
    for z in (x, -x):
        near = float((rel @ z).min())  # the first the hand meets moving along z
        for depth in s.grasp_depths:
            out.append((_frames(y, z, centre + (near + depth) * z), 0.3, width))
    return out


def _wall_lean(P, N, height, top: float, centre, n, s: PointGraspSettings) -> float:
    """How far the target's wall under its rim leans out from vertical (rad, in the plane of the radius
    and the support's normal ``n``; negative: in, a jar's shoulder): the median over the faces seen
    within half a pad's length under the top (outer faces' normals point out and down, inner ones' in
    and up). One figure for the whole rim: a thin wall's normals are fitted across its lip and a point's
    few neighbours scatter by tens of degrees. 0 when fewer than 20 face points are seen; clipped to
    ``max_tilt``."""
    band = (height <= top - s.clearance) & (height >= top - s.clearance - s.pad_length / 2)
    radial = P[band] - centre
    radial -= np.outer(radial @ n, n)
    r = np.linalg.norm(radial, axis=1)
    c = np.einsum("ij,ij->i", N[band], radial) / np.maximum(r, 1e-12)
    v = N[band] @ n
    side = (np.abs(c) >= np.abs(v)) & (r > 0)  # faces of the wall (not the lip's top, nor a floor's corner)
    if side.sum() < 20:
        return 0.0
    lean = np.arctan2(-np.sign(c[side]) * v[side], np.abs(c[side]))
    return float(np.clip(np.median(lean), -s.max_tilt, s.max_tilt))


def _floor_depth(P, rim_point, inner, y, x, u, s: PointGraspSettings) -> float:
    """The highest point under the inner finger of a rim pinch (its pad's inner face at ``inner``, the
    finger's body ``rim_finger_reach`` further in along -``y``, a pad wide along ``x``), as its height
    along the fingers' ``u`` (the approach reversed) over ``rim_point``: a plate's or a bowl's floor,
    which the finger stops above. Minus infinity when no point is there."""
    rel = P - inner
    along, across = rel @ -y, np.abs(rel @ x)
    under = (along >= 0.0) & (along <= s.rim_finger_reach) & (across <= s.pad_width / 2 + s.clearance)
    return float(((P[under] - rim_point) @ u).max()) if under.any() else -np.inf


def rim_candidates(P, N, plane, s: PointGraspSettings, rng) -> list:
    """Pinches of the target's top rim from above (bowls, mugs, pitchers, plates): one pad outside
    the wall, the other inside, closing across the wall through a rim point. The pads lie on the wall
    as it leans (``_wall_lean``: a bowl's wall leans out; pads upright on it would touch the lip's edge
    alone, and the lift would turn the wall flat onto them), the approach running down the wall. They
    go ``grasp_depths`` under the top, but the fingertips no lower than the support (the outer
    finger's) and a clearance above the points under the inner finger (a plate's floor: a low rim is
    pinched by the pads' lower part, the inner finger standing on nothing). On a solid top the inner
    finger meets observed points and the open-hand check drops the candidate."""
    n, d = plane
    height = P @ n - d
    top = float(np.percentile(height, 99.0))  # the max is the noisiest point's: mm above a rim's lip
    rim = np.flatnonzero(height > top - s.rim_band)
    centre = (P - np.outer(height, n)).mean(axis=0)
    on_wall = max(s.clearance, s.rim_overlap * s.pad_length)  # of pad under the top
    lean = _wall_lean(P, N, height, top, centre, n, s)
    out = []
    for i in rng.choice(rim, min(s.rim_samples, len(rim)), replace=False):
        radial = P[i] - centre
        radial -= (radial @ n) * n
        r = np.linalg.norm(radial)
        if r < s.max_width / 2:  # a narrow top: the footprint grasps close on all of it
            continue
        x = np.cross(radial / r, -n)
        y = np.cos(lean) * radial / r - np.sin(lean) * n  # across the wall
        down = -np.cos(lean) * n - np.sin(lean) * radial / r  # along it
        for tilt in (0.0, s.max_tilt / 2):
            z = np.cos(tilt) * down + np.sin(tilt) * x
            u, rise = -z, float(-z @ n)  # the fingers' axis, and its rise per metre
            reach = s.pad_length / 2  # the fingertips beyond the pads' centre
            floor = _floor_depth(P, P[i], P[i] - s.rim_wall * y, y, x, u, s)
            # how far the pads' centre may go down the wall from the rim point: the fingertips a
            # clearance above the floor, and the open fingers' (the outer one dips on a leaning wall) at
            # most table_contact into the support
            dip = reach * rise + s.max_width / 2 * abs(float(y @ n))
            deepest = min(-floor - reach - s.clearance - 0.001, (height[i] + s.table_contact - dip) / rise)
            if height[i] - (deepest + reach) * rise > top - on_wall:  # the pads would end on the lip
                continue
            for depth in s.grasp_depths[:2]:  # a low rim (a plate's): as deep as the floor lets the pads go
                go = min(deepest, (height[i] - (top - depth)) / rise)
                out.append((_frames(y, z, P[i] - s.rim_wall / 2 * y - go * u), 0.5, s.rim_wall))
    return out


def _pad_fill(G, P, width, s: PointGraspSettings) -> np.ndarray:
    """Per grasp frame ``G``: how much of the pads the points fill (points in the pad rectangle
    between the fingers, 30 fill it; counted natively, ``_core.points_in_frames``)."""
    half = np.column_stack([np.full(len(G), 0.01), width / 2 + 0.005, np.full(len(G), s.pad_length / 2)])
    return np.minimum(1.0, _core.points_in_frames(G, P, half) / 30.0)


def _open_hand_clear(T, P, coarse, hand_sdf, s: PointGraspSettings) -> np.ndarray:
    """Per hand pose ``T``: no point of ``P`` inside the open hand or within ``clearance`` of it
    (between the pads is outside the hand; only points within ``hand_reach`` of the hand frame can be
    inside it). ``coarse``, a subset of ``P``, is checked first: most rejected hands meet it, and only
    the rest are checked against all of ``P`` (the same verdict). Natively, ``SceneSdf.clear_in_frames``."""
    if len(T) == 0 or len(P) == 0:
        return np.ones(len(T), dtype=bool)
    ok = hand_sdf.clear_in_frames(T, coarse, s.clearance, cutoff=0.05, inverse=True, reach=s.hand_reach)
    ok[ok] = hand_sdf.clear_in_frames(T[ok], P, s.clearance, cutoff=0.05, inverse=True, reach=s.hand_reach)
    return ok


def _scene_clear(T, hand_points, scene_distance, clearance: float) -> np.ndarray:
    """Per hand pose ``T``: every hand sample farther than ``clearance`` from the other obstacles
    (an ``SdfQuery`` answers natively for all poses at once; any other function of points per point)."""
    if hasattr(scene_distance, "clear_in_frames"):
        return scene_distance.clear_in_frames(T, hand_points, clearance)
    world = np.einsum("kij,mj->kmi", T[:, :3, :3], hand_points) + T[:, None, :3, 3]
    return scene_distance(world.reshape(-1, 3)).reshape(len(T), -1).min(axis=1) > clearance


def grasps_from_points(
    points,
    normals,
    plane,
    hand_sdf,
    n: int = 100,
    seed: int = 0,
    scene_distance: Optional[Callable[[np.ndarray], np.ndarray]] = None,
    hand_points: Optional[np.ndarray] = None,
    settings: PointGraspSettings = PointGraspSettings(),
    gripper: RobotInfo = PANDA,
    hull: Optional[np.ndarray] = None,
    denoised_points: Optional[np.ndarray] = None,
    hull_pinches: bool = False,
) -> GraspSet:
    """Up to ``n`` grasps of the observed target (world frame; poses of ``gripper``'s hand link), best
    scores first.

    ``hand_sdf``: the open hand as a ``core.sdf.SceneSdf`` in the hand frame; ``scene_distance`` maps
    world points (M, 3) to their distance from the obstacles (the fused field; a ``core.sdf.SdfQuery``
    is asked natively for all poses at once), checked at
    ``hand_points`` (sample points on the open hand, hand frame) when both are given. ``hull``: (K, 3)
    samples of where the unseen rest of the target may be (``perception.hull.visibility_hull``): the
    open hand must clear them as it clears the observed points. ``denoised_points``: ``denoised(points,
    normals, patch_radius)`` when the caller has it already (a perceived world's quality reads it too).
    ``hull_pinches``: only pinches of parts seen from one side, their far side bounded by ``hull``
    (``hull_pinches.hull_pinch_candidates``), for a caller the seen surface gave too few grasps.

    Candidates are scored first (from the points alone) and checked in score order until ``n`` pass:
    the same grasps as checking all of them, at a fraction of the cost.
    """
    _check_count(n, seed)
    P, N = np.asarray(points, float), np.asarray(normals, float)
    if P.ndim != 2 or P.shape[1] != 3 or N.shape != P.shape or len(P) < 3:
        raise ValueError(f"points and normals: expected two (N, 3) arrays with N >= 3, got {P.shape}, {N.shape}")
    H = np.zeros((0, 3)) if hull is None else np.asarray(hull, float)
    if H.ndim != 2 or H.shape[1] != 3:
        raise ValueError(f"hull: expected an (K, 3) array, got {H.shape}")
    s = replace(
        settings,
        max_width=gripper.max_opening if settings.max_width is None else settings.max_width,
        pad_length=gripper.pad_length if settings.pad_length is None else settings.pad_length,
        pad_width=gripper.pad_width if settings.pad_width is None else settings.pad_width,
        width_margin=2 * settings.clearance if settings.width_margin is None else settings.width_margin,
    )
    rng = np.random.default_rng(seed)
    near = None
    if s.denoise:
        P = denoised(P, N, s.patch_radius) if denoised_points is None else np.asarray(denoised_points, float)
        near = _neighbourhoods(P, s.patch_radius)  # the fitted normals' and the contact patches'
        N = fitted_normals(P, N, s.patch_radius, near)
    if hull_pinches:
        cands = hull_pinch_candidates(
            P, *_unit_means(*(near or _neighbourhoods(P, s.patch_radius)), N, len(P)), H, plane[0], s
        )
    else:
        cands = (
            antipodal_candidates(P, N, s, rng, near)
            + footprint_candidates(P, plane, s)
            + rim_candidates(P, N, plane, s, rng)
            + local_candidates(P, plane, s, rng)
        )
    empty = GraspSet("points", np.zeros((0, 4, 4)), "observed target", scores=np.zeros(0), info={"width": np.zeros(0)})
    if not cands:
        return empty
    G = np.stack([c[0] for c in cands])  # grasp frames
    T = G @ gripper.hand_from_grasp  # hand poses
    margin = np.array([c[1] for c in cands])
    width = np.array([c[2] for c in cands])
    plane_n, plane_d = plane
    # fingertips above the plane: the lowest point of the pads, half a pad beyond their centre
    tips = G[:, :3, 3] + (s.pad_length / 2) * G[:, :3, 2]
    fill = _pad_fill(G, P, width, s)
    lever = gravity_lever(G, P, plane)
    score = margin + 0.5 * fill + s.spare_weight * (s.max_width - width) / s.max_width - lever / s.lever_scale
    order = np.argsort(-score, kind="stable")
    # fingertips resting on the support up to table_contact (footprint grasps of a thin target are
    # placed exactly there: a strict test would drop every one of them)
    order = order[(tips[order] @ plane_n - plane_d) >= -s.table_contact - 1e-9]
    check = np.vstack([P, H])  # the open hand clears the observed points and the hull
    coarse = thinned(check, 0.015)
    kept = []
    for chunk in np.array_split(order, max(1, len(order) // 64)):  # score order, bounded memory
        chunk = chunk[_open_hand_clear(T[chunk], check, coarse, hand_sdf, s)]
        if scene_distance is not None and hand_points is not None and len(chunk):
            chunk = chunk[_scene_clear(T[chunk], hand_points, scene_distance, s.obstacle_clearance)]
        kept.extend(chunk.tolist())
        if len(kept) >= n:
            break
    kept = kept[:n]
    if not kept:
        return empty
    return GraspSet("points", T[kept], "observed target", scores=score[kept], info={"width": width[kept]})
