"""Grasp sets generated from an object's mesh: the paper's naive "Approach" set and antipodal grasps."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np
import trimesh

from pickplan.core import collision
from pickplan.core.description import RobotInfo
from pickplan.core.panda import PANDA
from pickplan.core.robots import panda
from pickplan.omg.grasps.hand import HandObjectChecker
from pickplan.omg.grasps.sets import GraspSet, _check_count, _frame, _perpendicular


@dataclass(frozen=True)
class ApproachSettings:
    clearance: float = 0.002  # m kept between hand and object
    step: float = 0.005  # m between back-off samples, then bisected
    refine: int = 4  # bisection steps (0.3 mm with the default step)


def approach_grasps(
    model, n: int = 100, seed: int = 0, settings: ApproachSettings = ApproachSettings(), gripper: RobotInfo = PANDA
) -> GraspSet:
    """The paper's naive "Approach" set: uniformly random approach directions towards the centre of
    the object's bounding box, random roll, the hand backed off along its approach axis until it
    and its open fingers stay clear of the object all the way out (so the approach is free too).

    Poses of ``gripper``'s hand link. Starts with the pad centre at the object centre; a hand that fits there collision-free (inside
    a bowl) is kept where it is. ``scores`` are the back-off distances (smaller = closer).
    """
    _check_count(n, seed)
    rng = np.random.default_rng(seed)
    centre = np.asarray(model.mesh.bounds, float).mean(axis=0)
    radius = float(np.linalg.norm(np.asarray(model.mesh.vertices) - centre, axis=1).max())
    steps = np.arange(0.0, radius + 0.02 + settings.step, settings.step)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    roll = rng.uniform(-np.pi, np.pi, n)
    R = np.stack(
        [
            _frame(
                d[i], np.cos(roll[i]) * _perpendicular(d[i]) + np.sin(roll[i]) * np.cross(d[i], _perpendicular(d[i]))
            )
            for i in range(n)
        ]
    )

    def poses(R_, s_):  # hand poses with the pad centre (the grasp frame) at centre - s * approach
        T = np.tile(np.eye(4), (len(s_), 1, 1))
        T[:, :3, :3] = R_
        T[:, :3, 3] = centre - np.asarray(s_)[:, None] * R_[:, :, 2]
        return T @ gripper.hand_from_grasp

    check = HandObjectChecker(model, settings.clearance, gripper)
    hit = check.in_collision(poses(np.repeat(R, len(steps), 0), np.tile(steps, n))).reshape(n, len(steps))
    lo = np.where(hit.any(1), len(steps) - 1 - np.argmax(hit[:, ::-1], axis=1), -1)  # last colliding
    s_free = np.where(lo < 0, 0.0, steps[np.minimum(lo + 1, len(steps) - 1)])
    s_hit = np.where(lo < 0, 0.0, steps[np.maximum(lo, 0)])
    for _ in range(settings.refine if hit.any() else 0):
        mid = 0.5 * (s_free + s_hit)
        c = check.in_collision(poses(R, mid)) & (lo >= 0)
        s_hit, s_free = np.where(c, mid, s_hit), np.where(c | (lo < 0), s_free, mid)
    return GraspSet(
        "approach",
        poses(R, s_free),
        model.name,
        scores=-s_free,
        info={"approach_distance": s_free, "centre": np.tile(centre, (n, 1))},
    )


@dataclass(frozen=True)
class AntipodalSettings:
    friction: float = 0.3  # Coulomb coefficient: friction cone half-angle atan(0.3) = 16.7 deg
    max_width: Optional[float] = None  # m; None: the gripper's opening
    width_margin: float = 0.005  # pairs must be this much narrower than max_width
    min_width: float = 0.0005
    clearance: float = 0.001  # m kept between the open hand and the object
    approach_angles: int = 8  # hand orientations tried about each pair's axis
    per_pair: int = 1  # grasps kept per surface pair (diversity)
    samples_per_round: int = 400
    max_rounds: int = 25


class SupportFilter:
    """The support plane in the object's frame (the object as it lies): a hand whose palm reaches
    below it, or whose fingers reach deeper than the gripper's support tolerance plus the half pad
    length the goal set may lift a grasp by (``omg.goals.SupportSettings``), cannot be used.
    ``approach``: the direction (object frame) the generator's fan of approaches is centred on
    (default: down onto the support; into a shelf: level, ``World.open_approach``)."""

    def __init__(self, normal, offset: float, tolerance: Optional[float] = None, robot=None, approach=None):
        robot = robot if robot is not None else panda()  # the gripper's hand and fingers
        q = robot.ready_configuration
        self.normal, self.offset = np.asarray(normal, float) / np.linalg.norm(normal), float(offset)
        self.approach = -self.normal if approach is None else np.asarray(approach, float) / np.linalg.norm(approach)
        self.tolerance = (
            collision.SupportContact(tolerance).resolved(robot) + 0.5 * collision.gripper_spec(robot).pad_length
        )
        self.fingers = collision.HandGeometry(robot, q, robot.hand_link, robot.finger_links)
        self.palm = collision.HandGeometry(robot, q, robot.hand_link, (robot.hand_link,))

    @classmethod
    def under(
        cls, object_pose, tolerance: Optional[float] = None, robot=None, plane=None, approach=None
    ) -> "SupportFilter":
        """A world plane (unit normal, offset: normal . x = offset; default z = 0, the tabletop; a shelf
        board's top: ``World.support_plane``) in the frame of an object at ``object_pose``; ``approach``:
        the fan's centre, a world direction (default: down the plane's normal)."""
        normal, offset = (np.array([0.0, 0.0, 1.0]), 0.0) if plane is None else plane
        T = np.asarray(object_pose, float)
        normal = np.asarray(normal, float) / np.linalg.norm(normal)
        # n.(R x + p) = c  <=>  (R^T n).x = c - n.p
        approach = None if approach is None else T[:3, :3].T @ np.asarray(approach, float)
        return cls(T[:3, :3].T @ normal, float(offset) - float(normal @ T[:3, 3]), tolerance, robot, approach)

    @staticmethod
    def fan(k: int) -> np.ndarray:
        """k approach angles about a grasp axis, from the one nearest the fan's centre outwards: 0, +-15, +-30 deg, ..."""
        steps = (np.arange(k) + 1) // 2
        return np.radians(15.0) * steps * np.where(np.arange(k) % 2 == 1, 1.0, -1.0)

    def allows(self, hand_poses) -> np.ndarray:
        return (self.fingers.penetration(hand_poses, self.normal, self.offset) <= self.tolerance) & (
            self.palm.penetration(hand_poses, self.normal, self.offset) <= 0.0
        )


def _contact_pairs(mesh, rng: np.random.Generator, s: AntipodalSettings, cone: float):
    """One round's ``samples_per_round`` surface points p (outward normals n_p), rays d from them into the
    object uniform in the friction cone around -n_p, their exit points q (normals n_q; NaN without one),
    the widths |q - p| and the angles of d to -n_p and n_q."""
    m = s.samples_per_round
    p, face = trimesh.sample.sample_surface(mesh, m, seed=int(rng.integers(2**31)))
    n_p = mesh.face_normals[face]
    cos_t = rng.uniform(np.cos(cone), 1.0, m)
    phi = rng.uniform(0, 2 * np.pi, m)
    u = np.array([_perpendicular(v) for v in n_p])
    v = np.cross(n_p, u)
    sin_t = np.sqrt(1 - cos_t**2)
    d = -cos_t[:, None] * n_p + sin_t[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
    loc, ray, tri = mesh.ray.intersects_location(p + 1e-5 * d, d, multiple_hits=False)
    q = np.full((m, 3), np.nan)
    n_q = np.full((m, 3), np.nan)
    q[ray], n_q[ray] = loc, mesh.face_normals[tri]
    w = np.linalg.norm(q - p, axis=1)
    with np.errstate(invalid="ignore"):
        ang_q = np.arccos(np.clip(np.einsum("ij,ij->i", n_q, d), -1, 1))
        ang_p = np.arccos(np.clip(-np.einsum("ij,ij->i", n_p, d), -1, 1))
    return p, q, n_p, n_q, d, w, ang_p, ang_q


def _hands_about_axes(
    rng: np.random.Generator, p: np.ndarray, q: np.ndarray, d: np.ndarray, k: int, support: Optional[SupportFilter]
) -> np.ndarray:
    """(pairs, k, 4, 4) grasp frames closing along each pair's axis, pad centre at its midpoint, at k
    turns about the axis (a random offset, or fanned out from the support's approach)."""
    theta = rng.uniform(0, 2 * np.pi, len(p))[:, None] + 2 * np.pi * np.arange(k) / k
    flip = rng.random(len(p)) < 0.5  # which finger takes p
    y = np.where(flip[:, None], -d, d)  # +y points from the right finger to the left finger
    z0 = np.array([_perpendicular(v) for v in y])
    w0 = np.cross(y, z0)
    if support is not None:  # from the approach nearest the centre (top-down) about each axis, fanning out
        down = support.approach
        theta = np.arctan2(w0 @ down, z0 @ down)[:, None] + support.fan(k)
    z = np.cos(theta)[..., None] * z0[:, None] + np.sin(theta)[..., None] * w0[:, None]  # (pairs, k, 3)
    yk = np.broadcast_to(y[:, None], z.shape)
    T = np.tile(np.eye(4), (len(p), k, 1, 1))
    T[..., :3, 0], T[..., :3, 1], T[..., :3, 2] = np.cross(yk, z), yk, z
    T[..., :3, 3] = (0.5 * (p + q))[:, None]
    return T


def antipodal_grasps(
    model,
    n: int = 100,
    seed: int = 0,
    friction: Optional[float] = None,
    max_width: Optional[float] = None,
    settings: AntipodalSettings = AntipodalSettings(),
    gripper: RobotInfo = PANDA,
    support: Optional[SupportFilter] = None,
) -> GraspSet:
    """Antipodal grasps from the mesh: a surface point p (outward normal n_p), a ray from p into
    the object inside the friction cone around -n_p, its exit point q (normal n_q); kept when the
    axis lies in both friction cones and the width fits the opening. The hand closes along the
    axis with the pad centre at the pair midpoint, at ``approach_angles`` rotations about the axis
    (random offset); those whose open hand hits the object are rejected. Poses of ``gripper``'s hand link;
    ``max_width`` None: its opening.

    ``info``: "contacts" (N, 2, 3) p and q, "normals" (N, 2, 3) outward object normals, "width".
    ``scores``: cone margin 1 - max angle / cone angle. Fewer than ``n`` (with a warning) if the
    object offers fewer after ``max_rounds`` rounds. ``support``: only hands the support under the
    object (as it lies) allows. ``info["seconds"]``: the generation time (one value per grasp).
    ``rejected``: surface samples with no pair ("no_pair"), pairs whose every turn of the open hand hits
    the object ("hand_hits_object") or that the support allows none of ("support").
    """
    started = time.perf_counter()
    _check_count(n, seed)
    s = replace(settings, **{k: v for k, v in (("friction", friction), ("max_width", max_width)) if v is not None})
    s = s if s.max_width is not None else replace(s, max_width=gripper.max_opening)
    if s.friction <= 0 or s.max_width <= s.width_margin + s.min_width:
        raise ValueError(
            f"antipodal: need friction > 0 and max_width > {s.width_margin + s.min_width}, "
            f"got friction={s.friction}, max_width={s.max_width}"
        )
    mesh = model.mesh
    cone = np.arctan(s.friction)
    rng = np.random.default_rng(seed)
    check = HandObjectChecker(model, s.clearance, gripper)
    hand_from_grasp = gripper.hand_from_grasp
    out_T, out_c, out_n, out_w, out_s = [], [], [], [], []
    count = 0
    rejected = {"no_pair": 0, "hand_hits_object": 0, "support": 0}  # surface samples, then pairs
    for _ in range(s.max_rounds):
        p, q, n_p, n_q, d, w, ang_p, ang_q = _contact_pairs(mesh, rng, s, cone)
        with np.errstate(invalid="ignore"):  # NaN where a ray found no exit
            idx = np.flatnonzero((ang_q <= cone) & (w >= s.min_width) & (w <= s.max_width - s.width_margin))
        rejected["no_pair"] += len(p) - len(idx)
        if len(idx) == 0:
            continue
        k = s.approach_angles
        T = _hands_about_axes(rng, p[idx], q[idx], d[idx], k, support) @ hand_from_grasp  # grasp frames -> hand link
        free = ~check.in_collision(T.reshape(-1, 4, 4)).reshape(len(idx), k)
        rejected["hand_hits_object"] += int((~free.any(axis=1)).sum())
        if support is not None:
            allowed = free & support.allows(T.reshape(-1, 4, 4)).reshape(len(idx), k)
            rejected["support"] += int((free.any(axis=1) & ~allowed.any(axis=1)).sum())
            free = allowed
        for a, i in enumerate(idx):
            choices = np.flatnonzero(free[a])
            if len(choices) == 0:
                continue
            for b in rng.permutation(choices)[: s.per_pair]:
                out_T.append(T[a, b])
                out_c.append([p[i], q[i]])
                out_n.append([n_p[i], n_q[i]])
                out_w.append(w[i])
                out_s.append(1.0 - max(ang_p[i], ang_q[i]) / cone)
                count += 1
            if count >= n:
                break
        if count >= n:
            break
    if count < n:
        warnings.warn(f"{model.name}: only {count} antipodal grasps found (asked for {n})", stacklevel=2)
    if count == 0:
        return GraspSet("antipodal", np.zeros((0, 4, 4)), model.name, scores=np.zeros(0), rejected=rejected)
    seconds = np.full(min(count, n), time.perf_counter() - started)
    return GraspSet(
        "antipodal",
        np.asarray(out_T)[:n],
        model.name,
        scores=np.asarray(out_s)[:n],
        info={
            "contacts": np.asarray(out_c)[:n],
            "normals": np.asarray(out_n)[:n],
            "width": np.asarray(out_w)[:n],
            "seconds": seconds,
        },
        rejected=rejected,
    )
