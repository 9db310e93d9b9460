"""Place goal sets: where the held object should go, as a goal set.

A ``PlaceRequest`` (``omg.place_request``, re-exported here) names a region, a box on a support surface,
and an orientation rule: ``upright``, ``stable`` (the object's resting poses, those it stays in first) or
``pose``.

The place goal set is the OMG goal set of a place: resting rotations x yaws x positions in the region
(the object's whole mesh inside the box, its lowest point ``gap`` above the floor), mapped through the
grasp in hand (``HeldObject.hand_pose``) to hand poses, then the native goal-set builder: IK, a
set-down approach straight along gravity (``GoalSetSettings.approach``), FCL for the robot and the
held object, the approach clearance of the held object's and the robot's body points. Every
candidate keeps its reason; an empty set says why (``no_place_goals: region out of reach``, ``...
region too small for the object``, ``... region blocked``).

>>> request = PlaceRequest.load("region.json")
>>> goals = build_place_goal_set(carrying, request, q_lift)   # carrying: attach.HeldWorld
"""

from __future__ import annotations

import hashlib
import math
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from typing import Callable, List, Optional

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from pickplan import _core
from pickplan.core.caches import mesh_content_key
from pickplan.core.ik import IkSettings
from pickplan.core.settings import Option
from pickplan.omg.attach import HeldCheck, HeldWorld
from pickplan.omg.goals import GoalSet, GoalSetSettings, ik_solver
from pickplan.omg.place_request import Orientation, PlaceRequest  # noqa: F401  (the request's home; re-exported)
from pickplan.omg.world import CheckerKind


class PlaceVerdict(Option):
    """Why a place goal set is empty (``PlaceGoalSet.verdict``)."""

    ok = "ok"
    no_support = "region floor not on the support (the table top)"
    too_small = "region too small for the object"
    out_of_reach = "region out of reach"
    blocked = "region blocked"


@dataclass(frozen=True)
class PlaceSettings:
    """How place goal sets are built (the goal set's own settings: ``goals``)."""

    yaws: int = 8  # yaw samples over a full turn when the yaw is free
    position_step: float = 0.02  # m between candidate positions on the region's floor
    # A region where that grid gives no goal is sampled again this many times finer (yaw steps and
    # position steps divided by it): a long box fits a gap among clutter at a few headings and spots only,
    # and the coarse grid's first pass keeps the usual case fast
    refine: int = 2
    max_candidates: int = 600  # a seeded subset when the grid is larger
    gap: float = 0.004  # m: the object's lowest point above the floor at release
    # m kept between the object and the region's sides where the region is wide enough (less where it is
    # not; none when no place keeps it): an object set down at the very edge leaves the region when it
    # shifts in the hand by a little
    margin: float = 0.02
    max_rests: int = 3  # stable resting poses tried (most likely first)
    seed: int = 0
    floor_tolerance: float = 0.01  # m between the region's floor and the support plane
    # The set-down: straight down from standoff above the place. Its first configuration (the pre-place)
    # must keep the transit's clearance (the success test's ``MetricSettings.clearance``, ``preplace_clearance``):
    # the transit arrives there, so a pre-place closer to an object would fail every plan.
    # 10 goals (a grasp's 30): places are many and alike (neighbours 2 cm or a yaw step apart), and the
    # goal set's IK and the transfer's goal-cost estimates scale with the goals kept (20: place planning
    # 24-30 ms median on the bench's first 12 YCB scenes, 10: 12 ms, the same plans succeeding)
    goals: GoalSetSettings = field(
        default_factory=lambda: GoalSetSettings(standoff=0.15, standoff_steps=5, approach_clearance=0.01, max_goals=10)
    )
    preplace_clearance: float = 0.05
    # 8 IK seeds (a grasp's 24): a place out of reach from 8 seeds has neighbours in the grid to try
    ik: IkSettings = field(default_factory=lambda: IkSettings(num_seeds=8))

    def __post_init__(self):
        for name in ("yaws", "refine"):
            if int(getattr(self, name)) != getattr(self, name) or getattr(self, name) < 1:
                raise ValueError(f"place settings {name}: expected a whole number >= 1, got {getattr(self, name)!r}")
        if not self.position_step > 0:
            raise ValueError(f"place settings position_step: expected a length > 0, got {self.position_step!r}")


@dataclass
class PlaceGoalSet:
    """A place goal set: the goal set (its ``grasps`` are the hand poses in the world) and, per
    candidate, the object's world pose; ``verdict`` says why it is empty."""

    goal_set: GoalSet
    object_poses: np.ndarray  # (C, 4, 4) candidate object poses
    verdict: PlaceVerdict
    seconds: float

    def __len__(self) -> int:
        return len(self.goal_set)

    @property
    def reason(self) -> str:
        """ "" for a non-empty set, else ``no_place_goals: <why>``."""
        return "" if self.verdict is PlaceVerdict.ok else f"no_place_goals: {self.verdict.value}"

    def reason_counts(self) -> dict:
        return self.goal_set.reason_counts()


def _yaw(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _tilt(rotation: np.ndarray) -> np.ndarray:
    """The rotation with its yaw removed: only how the object is tilted (its up axis in the object)."""
    R = np.asarray(rotation, float)
    x = R[:, 0] - R[2, 0] * np.array([0, 0, 1.0])
    if np.linalg.norm(x) < 1e-6:  # the object's x points up: use y for the heading
        x = R[:, 1] - R[2, 1] * np.array([0, 0, 1.0])
        return _yaw(-math.atan2(x[1], x[0]) + math.pi / 2) @ R
    return _yaw(-math.atan2(x[1], x[0])) @ R


def resting_rotations(
    request: PlaceRequest,
    current_pose: np.ndarray,
    model=None,
    max_rests: int = 3,
    drop: Optional[Callable[[np.ndarray], float]] = None,
) -> List[np.ndarray]:
    """The object's rotations to place it in, yaw not yet applied: upright = as it stands now; stable =
    its resting poses, those it stays in when let go first, most likely first; pose = the given rotation.

    ``drop(R)`` (m): how far the object falls at the release in rotation ``R``. A rest whose barrier (the
    centre of mass's rise that tips it, ``ObjectModel.resting_barriers``) is lower than the fall can roll
    out of it (the YCB pitcher's likeliest rests, on its side, tip at a 1 mm rise; the release's gap is
    4 mm). Such rests come after the others, the most robust first."""
    if request.orientation is Orientation.pose:
        return [np.asarray(request.rotation, float)]
    if request.orientation is Orientation.upright or model is None:
        return [_tilt(np.asarray(current_pose, float)[:3, :3])]
    poses = [np.asarray(P, float)[:3, :3] for P in model.resting_poses]
    p = list(model.resting_probabilities) if len(model.resting_probabilities) == len(poses) else [1.0] * len(poses)
    b = list(model.resting_barriers) if len(model.resting_barriers) == len(poses) else [math.inf] * len(poses)
    margin = [b[i] - (0.0 if drop is None else drop(poses[i])) for i in range(len(poses))]
    order = sorted(range(len(poses)), key=lambda i: (margin[i] < 0, -p[i] if margin[i] >= 0 else -margin[i]))
    return [poses[i] for i in order[:max_rests]]


def release_drop(vertices: np.ndarray, fingers: Optional[np.ndarray], gap: float) -> Callable[[np.ndarray], float]:
    """``drop(R)``: how far the object (``vertices``, object frame) falls when let go in rotation ``R``:
    ``gap``, and more where the fingers (object frame) reach below it (``candidate_poses`` lifts it)."""

    def drop(R: np.ndarray) -> float:
        low = float((np.asarray(vertices) @ R.T)[:, 2].min())
        finger = low if fingers is None or not len(fingers) else float((np.asarray(fingers) @ R.T)[:, 2].min())
        return gap + max(0.0, low - finger)

    return drop


def _yaws(request: PlaceRequest, settings: PlaceSettings) -> np.ndarray:
    if request.yaw_deg is not None:
        return np.array([math.radians(request.yaw_deg)])
    return 2 * np.pi * np.arange(settings.yaws) / settings.yaws


def candidate_poses(
    request: PlaceRequest,
    vertices: np.ndarray,
    rotations: List[np.ndarray],
    settings: PlaceSettings,
    fingers: Optional[np.ndarray] = None,
) -> np.ndarray:
    """(C, 4, 4) object poses: every rotation x yaw x grid position on the region's floor with the
    object's ``vertices`` (object frame; its hull's, ``hull_vertices``, bound the same extents) all
    inside the box, the lowest ``gap`` above the floor; ``fingers`` (object frame, the hand's fingers
    holding it) ``gap`` above it too: a pinch low on a lying pen reaches below the pen."""
    lo, hi = np.asarray(request.region_min), np.asarray(request.region_max)
    Rs = [_yaw(yaw) @ R0 for R0 in rotations for yaw in _yaws(request, settings)]
    # The vertices turned by every rotation at once, (N, 3 per rotation): their extents in one reduction
    W = np.asarray(vertices, float) @ np.concatenate(Rs).T if Rs else np.zeros((0, 0))
    extents = np.stack([W.min(axis=0), W.max(axis=0)], axis=1).reshape(len(Rs), 3, 2) if Rs else []
    lowest = [e[2, 0] for e in extents]
    if fingers is not None and len(fingers) and Rs:
        F = np.asarray(fingers, float) @ np.concatenate(Rs).T
        lowest = np.minimum(lowest, F.min(axis=0).reshape(len(Rs), 3)[:, 2])
    rotated, places = [], []
    for R, (vmin, vmax), low in zip(Rs, (e.T for e in extents), lowest):
        z = lo[2] + settings.gap - low
        xlo, xhi = lo[:2] - vmin[:2], hi[:2] - vmax[:2]  # the origin's range keeping the object inside
        if z + vmax[2] > hi[2] or np.any(xhi < xlo):
            continue
        keep = np.clip((xhi - xlo) / 2, 0.0, settings.margin)
        xlo, xhi = xlo + keep, xhi - keep
        ax, ay = (
            np.arange(a, b + 1e-9, settings.position_step)
            if b - a >= settings.position_step
            else np.array([(a + b) / 2])
            for a, b in zip(xlo, xhi)
        )
        places.append(np.column_stack([np.repeat(ax, len(ay)), np.tile(ay, len(ax)), np.full(len(ax) * len(ay), z)]))
        rotated.append(np.broadcast_to(R, (len(places[-1]), 3, 3)))
    poses = np.zeros((sum(len(p) for p in places), 4, 4))
    if places:
        poses[:, :3, :3], poses[:, :3, 3], poses[:, 3, 3] = np.concatenate(rotated), np.concatenate(places), 1.0
    if len(poses) > settings.max_candidates:
        keep = np.sort(np.random.default_rng(settings.seed).choice(len(poses), settings.max_candidates, replace=False))
        poses = poses[keep]
    return poses


_REACH = ("unreachable", "standoff_unreachable")


def _verdict(candidates: int, reasons: list, kept: int) -> PlaceVerdict:
    if kept:
        return PlaceVerdict.ok
    if candidates == 0:
        return PlaceVerdict.too_small
    return PlaceVerdict.out_of_reach if all(r in _REACH for r in reasons) else PlaceVerdict.blocked


def build_place_goal_set(
    carrying: HeldWorld,
    request: PlaceRequest,
    start: np.ndarray,
    settings: PlaceSettings = PlaceSettings(),
    model=None,
    clock=time.perf_counter,
) -> PlaceGoalSet:
    """The place goal set of ``request`` for the object ``carrying`` holds, from ``start`` (the lifted
    configuration); ``model`` (the object's ``ObjectModel``) gives the stable resting poses; ``clock``
    times it."""
    t0 = clock()
    normal, offset = carrying.support_plane
    centre = 0.5 * (np.asarray(request.region_min) + np.asarray(request.region_max))
    if abs(normal @ np.array([centre[0], centre[1], request.floor]) - offset) > settings.floor_tolerance:
        empty = GoalSet(
            np.zeros((0, carrying.robot.dof)),
            np.zeros((0, 0, carrying.robot.dof)),
            np.zeros(0, int),
            np.zeros((0, 4, 4)),
            [],
            0.0,
        )
        return PlaceGoalSet(empty, np.zeros((0, 4, 4)), PlaceVerdict.no_support, clock() - t0)
    current = carrying.base.target_pose
    vertices, fingers = _held_hull_vertices(carrying), _finger_vertices(carrying, start)
    drop = release_drop(vertices, fingers, settings.gap)
    rotations = resting_rotations(request, current, model, settings.max_rests, drop)
    poses = candidate_poses(request, vertices, rotations, settings, fingers)
    gs = _released(carrying, _place_goals(carrying, poses, start, settings))
    fine = replace(
        settings, yaws=settings.yaws * settings.refine, position_step=settings.position_step / settings.refine
    )
    # Then finer, then without the margin (a crowded region: its edges too); the finer grid holds the coarse
    for grid in ([fine] if settings.refine > 1 else []) + ([replace(fine, margin=0.0)] if settings.margin > 0 else []):
        if len(gs) or _verdict(len(poses), gs.reasons, 0) is PlaceVerdict.out_of_reach:
            break
        poses = candidate_poses(request, vertices, rotations, grid, fingers)
        gs = _released(carrying, _place_goals(carrying, poses, start, settings))
    return PlaceGoalSet(gs, poses, _verdict(len(poses), gs.reasons, len(gs)), clock() - t0)


def _released(carrying: HeldWorld, gs: GoalSet) -> GoalSet:
    """The goals whose fingers, opened for the release, touch no obstacle (FCL: the object left out, as
    it stays between them; the floor is ``candidate_poses``'s): a finger beside a bin's wall pushed 3.8 mm
    into it as it opened. Candidates dropped here say ``release_in_collision``. A world without meshes
    (perceived) keeps its goals: its field holds the target's own points."""
    base = carrying.base
    if len(gs) == 0 or not hasattr(base, "scene_meshes"):
        return gs
    robot = base.robot
    checker = base.checker(CheckerKind.transit)
    opened = robot.with_fingers(gs.goals, robot.info.finger_open)
    ok = ~np.asarray(checker.in_collision_batch(opened), bool)
    if ok.all():
        return gs
    reasons = list(gs.reasons)
    for k in gs.grasp_index[~ok]:
        reasons[int(k)] = "release_in_collision"
    return replace(gs, goals=gs.goals[ok], tails=gs.tails[ok], grasp_index=gs.grasp_index[ok], reasons=reasons)


def hull_vertices(vertices: np.ndarray) -> np.ndarray:
    """The vertices of the convex hull of ``vertices`` (N, 3) (qhull alone: trimesh's hull also repairs
    the mesh), or all of them when they span no volume."""
    V = np.asarray(vertices, float)
    try:
        return V[ConvexHull(V).vertices] if len(V) > 4 else V
    except QhullError:  # flat or degenerate points (an observed face): every point counts
        return V


def _finger_vertices(carrying: HeldWorld, q: np.ndarray) -> Optional[np.ndarray]:
    """The fingers' hull vertices in the held object's frame, the fingers as at ``q`` and opened for the
    release (None: no fingers). Both: a closing axis the grasp tilts sends one finger down as it opens
    (a pen turned 10 deg in the hand: 6 mm), and the release must not push it into the floor."""
    base = carrying.base
    robot = base.robot
    held = base.cache.finger_geometry(robot, q)
    if held is None:
        return None
    opened = base.cache.finger_geometry(robot, robot.with_fingers(q, robot.info.finger_open))
    T = np.linalg.inv(carrying.held.hand_T_object)  # hand frame -> object frame
    V = np.concatenate([held.vertices, opened.vertices])
    return V @ T[:3, :3].T + T[:3, 3]


def _held_hull_vertices(carrying: HeldWorld) -> np.ndarray:
    """The held object's hull vertices (object frame), from its mesh or its points: once per object and
    cache (a mesh of thousands of vertices takes qhull 5-15 ms), not once per place."""
    held = carrying.held
    V = np.asarray(held.mesh.vertices if held.mesh is not None else held.points, float)
    if carrying.cache is None:
        return hull_vertices(V)
    source = held.mesh if held.mesh is not None else None
    key = ("hull_vertices",) + (
        mesh_content_key(source)
        if source is not None
        else (V.shape, hashlib.blake2b(V.tobytes(), digest_size=16).hexdigest())
    )
    return carrying.cache.derived(key, lambda: hull_vertices(V))


def _place_goals(carrying: HeldWorld, poses: np.ndarray, start: np.ndarray, settings: PlaceSettings) -> GoalSet:
    """The goal set of the held object's candidate ``poses`` (IK, set-down approach, collisions, the
    pre-place's clearance: a goal whose pre-place fails it is "pregrasp_clearance" and leaves its place
    under the cap to another)."""
    hands = carrying.held.hand_pose(poses) if len(poses) else np.zeros((0, 4, 4))
    checker = carrying.checker(HeldCheck.carry)
    hand_checker = carrying.checker(HeldCheck.hand)
    gs_settings = replace(settings.goals, approach=(0.0, 0.0, -1.0))
    out = _core.build_goal_set(
        ik_solver(carrying, settings.ik),
        None if checker is None else checker.native,
        None if hand_checker is None else hand_checker.native,
        hands,
        np.asarray(start, float),
        gs_settings.to_native(),
        carrying.clearance_problem,
        float(settings.goals.approach_clearance),
        pregrasp_clearance=float(settings.preplace_clearance),
    )
    return GoalSet(
        np.asarray(out.goals),
        np.asarray(out.tails),
        np.asarray(out.grasp_index, int),
        hands,
        [r.name for r in out.reasons],
        float(out.seconds),
    )


def reason_summary(place: PlaceGoalSet) -> str:
    """``no_place_goals: <verdict>`` with the candidates' reasons counted."""
    counts = Counter(place.goal_set.reasons)
    detail = ", ".join(f"{k} {v}" for k, v in counts.most_common())
    return place.reason + (f" ({len(place.object_poses)} candidates: {detail})" if detail else "")
