"""The held object: after the grasp, the object is part of the robot.

``HeldObject`` is what the hand holds and how: the object's frame in the hand link's frame (the grasp
as executed), its mesh and body points in its own frame. ``attached_robot`` gives the robot one more
link, fixed to the hand at that grasp (``_core.Robot.with_attached_link``): its body points then
follow the hand exactly in CHOMP's obstacle cost, the goal-cost estimates and the success test, and
its mesh in the FCL checks, with no new mechanism. ``HeldWorld`` is a planning world while carrying:
the scene as it was with the held object taken out of it (excluded from the SDF and FCL) and put on
the robot.

>>> held = held_from_plan(world, plan.goal)            # the planned grasp; or held_from_poses(...)
>>> carrying = HeldWorld(world, held)                  # carrying.chomp(...), carrying.checker(...)
"""

from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from typing import Optional, Sequence, Tuple

import numpy as np
import trimesh

from pickplan import _core
from pickplan.core import collision, robots
from pickplan.core.ik import IkSettings
from pickplan.core.meshes import farthest_points
from pickplan.core.poses import rigid_errors
from pickplan.core.settings import Option
from pickplan.omg.chomp import Chomp
from pickplan.omg.perceived_world import PerceivedWorld
from pickplan.omg.world import CheckerKind, World

#: The name of the held object's link on the robot.
HELD_LINK = "held_object"


@dataclass(frozen=True)
class AttachSettings:
    """How the held object becomes part of the robot."""

    # body points on the held object's surface (a link of the paper has 20; an object spans several links' worth of
    # space)
    points: int = 60
    seed: int = 0
    # A target from depth: body points spread evenly about this far apart on the convex hull of its observed
    # points and their feet (what no camera saw closed over), between ``points`` and ``max_points``. A
    # random 60 of the observed points left parts of the true surface 4-7 cm from every body point.
    observed_spacing: float = 0.015  # m
    max_points: int = 400


@dataclass
class HeldObject:
    """An object in the hand: ``hand_T_object`` (4, 4) maps the object frame into the hand link's frame
    (the grasp as executed); ``mesh`` (object frame: FCL and the view; None from depth: no mesh) and
    ``points`` (N, 3) body points in the object frame."""

    name: str
    hand_T_object: np.ndarray
    points: np.ndarray
    mesh: Optional[trimesh.Trimesh] = None

    def __post_init__(self):
        T = np.asarray(self.hand_T_object, dtype=float)
        if T.shape != (4, 4) or not rigid_errors(T[None])[0] <= 1e-6:
            raise ValueError(f"hand_T_object: expected a rigid (4, 4) transform, got shape {T.shape}")
        P = np.asarray(self.points, dtype=float)
        if P.ndim != 2 or P.shape[1] != 3 or len(P) == 0 or not np.all(np.isfinite(P)):
            raise ValueError(f"held object points: expected finite (N, 3) with N >= 1, got shape {P.shape}")
        self.hand_T_object, self.points = T, P

    def object_pose(self, hand_pose: np.ndarray) -> np.ndarray:
        """The object's world pose with the hand at ``hand_pose``."""
        return np.asarray(hand_pose, dtype=float) @ self.hand_T_object

    def hand_pose(self, object_pose: np.ndarray) -> np.ndarray:
        """The hand's world pose(s) that put the object at ``object_pose`` ((4, 4) or (N, 4, 4))."""
        return np.asarray(object_pose, dtype=float) @ np.linalg.inv(self.hand_T_object)

    def to_dict(self) -> dict:
        return {"name": self.name, "hand_T_object": self.hand_T_object.tolist()}


def surface_points(mesh, n: int, seed: int) -> np.ndarray:
    """``n`` seeded samples on a mesh's surface (its own frame)."""
    pts, _ = trimesh.sample.sample_surface(mesh, int(n), seed=int(seed))
    return np.asarray(pts, dtype=float)


def held_from_poses(
    name: str,
    hand_pose: np.ndarray,
    object_pose: np.ndarray,
    mesh=None,
    points: Optional[np.ndarray] = None,
    settings: AttachSettings = AttachSettings(),
) -> HeldObject:
    """The object ``name`` at world pose ``object_pose`` held by a hand at ``hand_pose``; body points
    sampled on ``mesh`` unless ``points`` (object frame) are given."""
    hand_T_object = np.linalg.inv(np.asarray(hand_pose, dtype=float)) @ np.asarray(object_pose, dtype=float)
    if points is None:
        if mesh is None:
            raise ValueError("held object: give its mesh or its points")
        points = surface_points(mesh, settings.points, settings.seed)
    return HeldObject(name, hand_T_object, points, mesh)


def held_from_plan(world, q_grasp: np.ndarray, settings: AttachSettings = AttachSettings()) -> HeldObject:
    """The world's target held as the configuration ``q_grasp`` grasps it (the planned grasp). A
    perceived world (no mesh) holds its observed target points."""
    robot = world.robot
    hand = robot.link_pose(np.asarray(q_grasp, dtype=float), robot.hand_link)
    if isinstance(world, PerceivedWorld):  # observed points are in the world frame: the target's pose is the identity
        return held_from_poses(world.target, hand, world.target_pose, points=observed_points(world, settings))
    model = world.target_model
    points = world.cache.surface(model.mesh, settings.points, settings.seed, surface_points)
    return held_from_poses(world.target, hand, world.target_pose, model.mesh, points)


def observed_points(world: PerceivedWorld, settings: AttachSettings = AttachSettings()) -> np.ndarray:
    """A perceived target as body points (world frame): seeded samples about ``observed_spacing`` apart
    on the convex hull of its observed points and their feet on the support plane (it stands on the
    plane: its unseen underside reaches down to it; its unseen sides are closed over). Kept by the
    world's cache: every grasp a regrasp screens attaches the same points."""
    P = np.asarray(world.perceived.target_points, dtype=float)
    normal, offset = world.support_plane
    normal = np.asarray(normal, dtype=float)
    key = ("observed_points", hashlib.sha256(P.tobytes()).hexdigest(), normal.tobytes(), float(offset), settings)
    return world.cache.derived(key, lambda: _hull_points(P, normal, float(offset), settings))


def _hull_points(P: np.ndarray, normal: np.ndarray, offset: float, settings: AttachSettings) -> np.ndarray:
    feet = P - (P @ normal - offset)[:, None] * normal[None]
    try:
        hull = trimesh.convex.convex_hull(np.vstack([P, feet]))
    except Exception:  # noqa: BLE001 - qhull on degenerate (flat, collinear) points: the points themselves
        return np.vstack([P, feet])[:: max(1, (2 * len(P)) // settings.max_points)]
    n = int(np.clip(hull.area / settings.observed_spacing**2, settings.points, settings.max_points))
    candidates = surface_points(hull, 8 * n, settings.seed)
    return candidates[farthest_points(candidates, n)]  # evenly spread: random samples leave gaps


def attached_robot(robot: robots.DescribedRobot, held: HeldObject) -> robots.DescribedRobot:
    """``robot`` with the held object as a link fixed to its hand (``HELD_LINK``); the same type,
    description and model files, so per-robot caches of its other links still apply."""
    return robot.with_attached_link(HELD_LINK, robot.hand_link, held.hand_T_object)


class HeldCheck(Option):
    """What an FCL checker of a ``HeldWorld`` lets touch."""

    # robot and held object against every other object and the table; the fingers may touch the held object (they hold
    # it)
    carry = "carry"
    # the same, but the held object may touch the table it rests on (lifting off, setting down)
    support = "support"
    hand = "hand"  # the carry rules for the hand, fingers and held object alone (goal-set pre-check)
    support_hand = "support_hand"  # the support rules for the hand, fingers and held object alone


class HeldWorld:
    """The planning view of ``world`` while the robot carries ``held``: ``robot`` (with the held
    link), ``body`` (the robot's points and the held object's), ``sdf`` (the world's: the held object's
    old place is excluded wherever the target is), ``chomp``, ``checker`` and ``clearance_problem`` as
    a ``World`` has them."""

    def __init__(self, world, held: HeldObject):
        if held.name != world.target:
            raise ValueError(f"held object {held.name!r} is not the world's target {world.target!r}")
        self.base, self.held = world, held
        self.scene, self.sdf, self.cache = world.scene, world.sdf, getattr(world, "cache", None)
        self.robot = attached_robot(world.robot, held)
        link = self.robot.link_index(HELD_LINK)
        body = world.body
        self.body = robots.BodyPoints(
            np.concatenate([body.links, np.full(len(held.points), link, np.int32)]),
            np.concatenate([body.points, held.points]),
            np.concatenate([body.normals, np.zeros_like(held.points)]),
        )
        self._chomps: dict = {}
        self._checkers: dict = {}

    target = property(lambda self: self.base.target)
    start = property(lambda self: self.base.start)
    support_plane = property(lambda self: self.base.support_plane)

    def chomp(self, settings, avoid_target: bool = False) -> Chomp:
        """``World.chomp`` with the held object's points; the target's old place is never an obstacle
        (the target is in the hand), whatever ``avoid_target`` asks."""
        return World.chomp(self, settings, avoid_target=False)

    @functools.cached_property
    def clearance_problem(self):
        """Body points (the held object's included) in the scene SDF, the target's old place and the
        table left out: what the success test measures approaches with."""
        return Chomp(self.robot, self.sdf, self.body, exclude=(self.target,)).problem

    def over_support(self, points: np.ndarray) -> np.ndarray:
        return self.base.over_support(points)

    def checker(self, kind=HeldCheck.carry):
        """The FCL checker of a ``HeldCheck`` kind (None for a world without meshes: a perceived one). A
        world's ``CheckerKind`` (what a baseline asks for) reads as ``carry`` (``hand``: the hand's)."""
        if isinstance(kind, CheckerKind) or kind in {k.value for k in CheckerKind}:
            kind = HeldCheck.hand if CheckerKind.parse(kind) is CheckerKind.hand else HeldCheck.carry
        kind = HeldCheck.parse(kind, "held-object checker kind")
        if self.held.mesh is None or not hasattr(self.base, "scene_meshes"):
            return None
        if kind not in self._checkers:
            self._checkers[kind] = self._build_checker(kind)
        return self._checkers[kind]

    def _build_checker(self, kind: HeldCheck) -> collision.CollisionChecker:
        robot, base = self.robot, self.base
        mounted = collision.mounted_pairs(robot)
        holding = tuple((f, HELD_LINK) for f in robot.finger_links) + ((robot.hand_link, HELD_LINK),)
        allowed = mounted + holding
        if kind in (HeldCheck.support, HeldCheck.support_hand):
            allowed += ((HELD_LINK, "table"),) + tuple((f, "table") for f in robot.finger_links)
        links = None
        if kind in (HeldCheck.hand, HeldCheck.support_hand):
            links = (robot.hand_link,) + tuple(robot.finger_links) + (HELD_LINK,)
        meshes = dict(base.cache.link_meshes(base.robot))
        meshes[HELD_LINK] = self.held.mesh
        table = collision.Table(
            size=tuple(np.asarray(self.scene.table.size, dtype=float)),
            pose=np.asarray(self.scene.table.pose, dtype=float),
        )
        settings = collision.CollisionSettings(allowed_pairs=allowed, excluded_objects=(self.target,))
        return collision.CollisionChecker(
            robot, base.scene_meshes(), table, settings, links=links, shapes=base.cache.shapes, link_meshes=meshes
        )


def held_lowest(held: HeldObject, rotation: np.ndarray) -> float:
    """The lowest height of the held object's points (mesh vertices when it has a mesh) for an object
    rotation (3, 3) in the world, relative to its origin."""
    V = np.asarray(held.mesh.vertices if held.mesh is not None else held.points, dtype=float)
    return float((V @ np.asarray(rotation, dtype=float).T)[:, 2].min())


def straight_path(
    robot,
    q0: np.ndarray,
    direction: Sequence[float],
    distance: float,
    steps: int,
    ik: IkSettings = IkSettings(),
    max_joint_jump: float = 0.5,
) -> Tuple[np.ndarray, bool]:
    """Configurations (steps + 1, dof) moving the hand ``distance`` along the world ``direction`` from
    ``q0`` with its orientation held (native IK per step, each from the previous solution; the finger
    joints frozen), and whether every step converged without a jump over ``max_joint_jump``."""
    path, good = straight_path_steps(robot, q0, direction, distance, steps, ik, max_joint_jump)
    return path, bool(np.all(good))


def straight_path_steps(
    robot,
    q0: np.ndarray,
    direction: Sequence[float],
    distance: float,
    steps: int,
    ik: IkSettings = IkSettings(),
    max_joint_jump: float = 0.5,
) -> Tuple[np.ndarray, np.ndarray]:
    """``straight_path`` with each step's verdict: (path (steps + 1, dof), good (steps,))."""
    hand = robot.link_pose(q0, robot.hand_link)
    targets = np.repeat(hand[None], steps, axis=0)
    targets[:, :3, 3] += np.outer(distance * np.arange(1, steps + 1) / steps, np.asarray(direction, dtype=float))
    return hand_pose_path(robot, q0, targets, ik, max_joint_jump)


def hand_pose_path(
    robot, q0: np.ndarray, targets: np.ndarray, ik: IkSettings = IkSettings(), max_joint_jump: float = 0.5
) -> Tuple[np.ndarray, np.ndarray]:
    """Configurations reaching the hand ``targets`` (K, 4, 4) one after the other from ``q0`` (native IK,
    each from the previous solution; the finger joints frozen) and each one's verdict: (path (K + 1,
    dof), good (K,): converged without a jump over ``max_joint_jump``)."""
    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    Q, converged = _core.IkSolver(robot.native, robot.hand_link, ik.to_native(active)).solve_path(targets, q0)
    path = np.vstack([np.asarray(q0, dtype=float)[None], Q])
    return path, np.asarray(converged, bool) & (np.abs(np.diff(path, axis=0)).max(axis=1) <= max_joint_jump)
