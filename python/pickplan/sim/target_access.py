"""Whether a robot can reach a grasp of a scene's target at all, in the scene as it stands: a hand
pose that holds the target between its pads, with the open hand clear of everything at the grasp,
backed off along its approach, and lifted with the target; and an arm configuration reaching it
clear of everything, with a collision-free straight retreat to the pre-grasp and a straight lift of
the target (the arm by IK, the target carried).

The scene generators ask this of a target before they name it (``sim.layouts``), as MotionBenchMaker's
generator keeps only problems with a valid goal: a target tucked behind a neighbour or under a low
board is a fine scene, but not a grasping problem. The search is independent of the planner's goal
set: its own hand poses (antipodal pairs of the mesh, turned about their axis in fixed steps and tilted
a little off it), the exact FCL checks of the hand and of the whole arm, the native IK from every
seed. It is a sampled search, so a ``reachable`` verdict is a proof (the configuration is returned)
and the other is not.

>>> access = target_access(scene)
>>> access.reachable, access.reason   # (False, "the open hand collides at every pose ...")
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from typing import NamedTuple, Optional

import numpy as np

from pickplan import _core
from pickplan.core import collision, robots
from pickplan.core import objects as objects_mod
from pickplan.core.graspability import antipodal_pairs
from pickplan.core.ik import IkSettings
from pickplan.core.shapes import Shape
from pickplan.sim.execution import ExecutionSettings


@dataclass(frozen=True)
class AccessSettings:
    standoff: float = 0.08  # m the pre-grasp backs off along the approach (the paper's standoff)
    standoff_steps: int = 8  # poses checked along it (hand), IK steps (arm)
    lift: float = ExecutionSettings.min_lift + ExecutionSettings.lift_clearance  # m the hand and target rise
    lift_steps: int = 6
    width_margin: float = 0.005  # m a pair must be narrower than the opening
    max_pairs: int = 300  # antipodal pairs drawn (seeded), before those alike are merged
    pair_spacing: float = 0.015  # m: pairs nearer than this with axes within ~14 deg are one
    turn_deg: float = 15.0  # approach angles about each pair's axis, from the one nearest the robot
    tilt_deg: float = 8.0  # the hand also tilted this far off the axis, both ways about two axes
    depth_fraction: float = 0.4  # the pad centre also moved this fraction of the pad length along the approach
    max_joint_step: float = 0.3  # rad between IK steps of the retreat
    seed: int = 0

    def __post_init__(self):
        for name in ("standoff", "lift", "pair_spacing", "turn_deg", "max_joint_step"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"AccessSettings.{name}: expected a positive number, got {value!r}")
        for name in ("standoff_steps", "lift_steps", "max_pairs"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ValueError(f"AccessSettings.{name}: expected an integer >= 1, got {value!r}")

    def rises(self) -> np.ndarray:
        """m the hand and target rise at each step of the lift."""
        return np.arange(1, self.lift_steps + 1) * self.lift / self.lift_steps


class Access(NamedTuple):
    reachable: bool
    reason: str  # "" when reachable, else the furthest stage any pose reached and what stopped it there
    configuration: Optional[np.ndarray]  # (dof,) the grasp configuration found (fingers open), or None
    hand_pose: Optional[np.ndarray]  # (4, 4) world pose of the hand link at it, or None
    poses: int  # hand poses tried


def _rotation(axis, degrees: float) -> np.ndarray:
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    a = math.radians(degrees)
    return np.eye(3) + math.sin(a) * K + (1.0 - math.cos(a)) * K @ K


def _distinct_pairs(mids: np.ndarray, axes: np.ndarray, spacing: float):
    keep = []
    for i in range(len(mids)):
        if all(np.linalg.norm(mids[i] - mids[j]) > spacing or abs(axes[i] @ axes[j]) < 0.97 for j in keep):
            keep.append(i)
    return mids[keep], axes[keep]


def _candidates(scene, model, robot, s: AccessSettings):
    """World grasp frames (z approach, y closing, origin at the pad centre), (N, 4, 4) per turn, nearest the
    level approach from the robot first: every distinct pair, turned about its axis, both fingers' ways,
    tilted, moved along the approach."""
    T = np.asarray(scene.object(scene.target).pose, float)
    p, q, axes, widths = antipodal_pairs(model.mesh)
    idx = np.flatnonzero(widths <= robot.info.max_opening - s.width_margin)
    np.random.default_rng(s.seed).shuffle(idx)
    idx = idx[: s.max_pairs]
    mids, axes = _distinct_pairs(
        ((p[idx] + q[idx]) / 2) @ T[:3, :3].T + T[:3, 3], axes[idx] @ T[:3, :3].T, s.pair_spacing
    )
    ref = T[:3, 3] - np.asarray(scene.robot_base, float)[:3, 3]
    ref[2] = 0.0
    ref = ref / np.linalg.norm(ref) if np.linalg.norm(ref) > 1e-9 else np.array([1.0, 0.0, 0.0])
    u = ref - (axes @ ref)[:, None] * axes  # the level approach from the robot, square to each axis
    norm = np.linalg.norm(u, axis=1, keepdims=True)
    u = np.where(norm > 1e-6, u / np.maximum(norm, 1e-12), np.cross(axes, [0.0, 0.0, 1.0]))
    w = np.cross(axes, u)
    tilts = np.stack([np.eye(3)] + [_rotation(a, d) for a in np.eye(3)[[0, 2]] for d in (s.tilt_deg, -s.tilt_deg)])
    shifts = np.array([0.0, -1.0, 1.0]) * s.depth_fraction * robot.info.pad_length
    for k in range(int(round(360.0 / s.turn_deg))):  # 0, +-1, +-2, ... steps from the level approach
        angle = math.radians(s.turn_deg) * ((k + 1) // 2) * (1 if k % 2 else -1)
        A = math.cos(angle) * u + math.sin(angle) * w  # (P, 3)
        for y in (axes, -axes):
            R = np.stack([np.cross(y, A), y, A], axis=2)  # (P, 3, 3): columns x, y, z
            R = np.einsum("pij,tjk->ptik", R, tilts).reshape(-1, 3, 3)  # (P * tilts, 3, 3)
            centre = np.repeat(mids, len(tilts), axis=0)
            for d in shifts:
                G = np.tile(np.eye(4), (len(R), 1, 1))
                G[:, :3, :3] = R
                G[:, :3, 3] = centre + d * np.repeat(A, len(tilts), axis=0)
                yield G


class _FloatingHand:
    """The open hand and fingers (FCL) at any world pose: the scene is moved instead (each object posed
    relative to the hand), the target optionally carried along (a lift)."""

    def __init__(self, scene, models, robot, start: np.ndarray, link_meshes: dict):
        self.robot = robot
        self.q = start
        self.home = self.robot.fk(start)[self.robot.link_index(self.robot.hand_link)]
        self.things = [(o.name, models[o.name].mesh, np.asarray(o.pose, float)) for o in scene.objects]
        self.things += [(o.name, o.shape, np.asarray(o.pose, float)) for o in scene.obstacles]
        if scene.table is not None:
            self.things.append(
                ("support", Shape.box(*np.asarray(scene.table.size, float)), np.asarray(scene.table.pose, float))
            )
        links = (self.robot.hand_link,) + tuple(self.robot.finger_links)
        meshes = [collision.SceneMesh(n, m, P) for n, m, P in self.things]
        self.checker = collision.CollisionChecker(
            robot, meshes, None, collision.CollisionSettings(), links=links, link_meshes=link_meshes
        )
        self.target = scene.target

    def free(self, hand_pose: np.ndarray, lift: float = 0.0) -> bool:
        L = np.eye(4)
        L[2, 3] = lift
        W = self.home @ np.linalg.inv(L @ hand_pose)
        for name, _, P in self.things:
            self.checker.set_object_pose(name, W @ (L @ P if name == self.target else P))
        return not self.checker.in_collision(self.q)


_STAGES = (
    "the open hand collides at every pose (at the grasp, backed off or lifted with the target)",
    "no arm configuration reaches a pose where the open hand is free",
    "the arm collides at every configuration reaching a free hand pose",
    "no collision-free straight retreat to the pre-grasp from a free configuration",
    "the arm cannot lift the target straight up clear of everything from any grasp it reaches",
)


def _raised(T: np.ndarray, dz: float) -> np.ndarray:
    out = np.array(T, float)
    out[2, 3] += dz
    return out


def _prepared(scene, models: Optional[dict]):
    if scene.target is None:
        raise ValueError("target_access: the scene has no target")
    models = dict(models or {})
    for o in scene.objects:
        if o.name not in models:
            models[o.name] = objects_mod.model_from_source(o.name, o.source)
    robot = robots.load_robot(scene.robot, np.asarray(scene.robot_base, float))
    start = (
        np.asarray(scene.robot_configuration, float) if len(scene.robot_configuration) else robot.ready_configuration
    )
    return models, robot, robot.with_fingers(start, robot.info.finger_open)


@dataclass
class _Tally:
    tried: int = 0  # candidate hand poses looked at


def _free_hands(scene, models, robot, start, hand: _FloatingHand, s: AccessSettings, count: _Tally):
    """(hand pose, its retreat's poses) of every candidate whose open hand is free at the grasp, along the
    retreat and lifted with the target, in the candidates' order; ``count.tried`` counts the candidates."""
    to_hand = np.linalg.inv(np.asarray(robot.info.grasp_frame, float))
    back = np.arange(1, s.standoff_steps + 1) * s.standoff / s.standoff_steps
    rises = s.rises()
    for batch in _candidates(scene, models[scene.target], robot, s):
        for G in batch:
            count.tried += 1
            H, approach = G @ to_hand, G[:3, 2]
            retreat = [H.copy() for _ in back]
            for R, d in zip(retreat, back):
                R[:3, 3] -= d * approach
            if hand.free(H) and all(hand.free(R) for R in retreat) and all(hand.free(H, z) for z in rises):
                yield H, retreat


def target_access(scene, models: Optional[dict] = None, settings: AccessSettings = AccessSettings()) -> Access:
    """Search for a grasp of ``scene.target`` the scene's robot (``scene.robot``, at ``scene.robot_base``,
    from ``scene.robot_configuration``) can reach clear of everything. ``models``: object name ->
    ``ObjectModel`` (None: each object's from its source)."""
    models, robot, start = _prepared(scene, models)
    link_meshes = {n: robot.collision_meshes(n) for n in robot.link_names}
    hand = _FloatingHand(scene, models, robot, start, link_meshes)
    meshes = [collision.SceneMesh(n, m, P) for n, m, P in hand.things if n != "support"]
    table = (
        None
        if scene.table is None
        else collision.Table(tuple(np.asarray(scene.table.size, float)), np.asarray(scene.table.pose, float))
    )
    arm = collision.CollisionChecker(
        robot,
        meshes,
        table,
        collision.CollisionSettings(allowed_pairs=collision.mounted_pairs(robot)),
        link_meshes=link_meshes,
    )
    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    ik = _core.IkSolver(robot.native, robot.hand_link, IkSettings().to_native(active))
    target_pose = np.asarray(scene.object(scene.target).pose, float)
    rises = settings.rises()
    reached, count = Counter(), _Tally()
    for H, retreat in _free_hands(scene, models, robot, start, hand, settings, count):
        reached[1] += 1
        for solution in (x for x in ik.solve_all(H, start) if x.converged):
            reached[2] += 1
            q = np.asarray(solution.q)
            if arm.in_collision(q):
                continue
            reached[3] += 1
            if not _path_clear(ik, arm, q, retreat, settings.max_joint_step):
                continue
            reached[4] += 1
            lifted, carried = [_raised(H, z) for z in rises], [_raised(target_pose, z) for z in rises]
            clear = _path_clear(ik, arm, q, lifted, settings.max_joint_step, (scene.target, carried))
            arm.set_object_pose(scene.target, target_pose)
            if clear:
                return Access(True, "", q, H, count.tried)
    if not count.tried:
        cm = 100 * robot.info.max_opening
        return Access(False, f"no antipodal pair of the target is narrower than the {cm:.0f} cm opening", None, None, 0)
    stage = max(reached) if reached else 0
    return Access(False, f"{_STAGES[stage]} ({count.tried} hand poses tried)", None, None, count.tried)


def _path_clear(ik, arm, q: np.ndarray, poses, max_step: float, carried=None) -> bool:
    """Whether IK follows the hand ``poses`` from ``q`` (each from the last, a few descents each) in small
    joint steps with every configuration clear; ``carried``: (name, its pose at each of ``poses``), an
    object the hand holds (the target on the lift), moved along."""
    prev = q
    for k, pose in enumerate(poses):
        step = ik.solve(pose, prev)
        for _ in range(3):  # a descent that stalls short of the tolerance, continued
            if step.converged:
                break
            step = ik.solve(pose, np.asarray(step.q))
        nxt = np.asarray(step.q)
        if carried is not None:
            arm.set_object_pose(carried[0], carried[1][k])
        if not step.converged or np.abs(nxt - prev).max() > max_step or arm.in_collision(nxt):
            return False
        prev = nxt
    return True
