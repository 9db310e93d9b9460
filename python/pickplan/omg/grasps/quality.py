"""Grasp quality that knows physics: whether two parallel pads squeezing an object hold it against the
load of lifting and carrying it, and by what margin.

**The load** (``Load``): the object's weight and the force that accelerates it with the hand
(``QualitySettings.acceleration`` in each of the six axis directions of the world, and none: a timed
trajectory's carry), at its centre of mass, as a wrench about the grasp's centre.

**The grip** (``Grip``, from the robot description): each pad presses with the gripper's force N; the
fingers are coupled, so a load along the closing axis moves force from one pad to the other
(N -+ F_y / 2). A pad touches the object on a patch: the surface within ``compliance`` of where the pad
first meets it as it closes, found on surface points (the pad's rectangle swept along the closing axis;
``pad_patches``). A patch gives

- tangential friction up to mu N_i (mu: the pad's friction times the object's, as the simulator
  combines them), none where the patch's surface stays turned from the pad by more than the friction
  cone (a pad's edge on a steep slope, a rim's lip: the squeeze pushes the object out);
- torsional friction about the closing axis up to mu N_i rho_i, rho_i the patch's mean distance from
  its centre (a soft finger with uniform pressure; the limit surface taken as the ellipse
  (|t| / mu N)^2 + (m / mu N rho)^2 <= 1, Howe and Cutkosky 1996);
- a moment about the pads' in-plane axes by moving its centre of pressure within the patch (up to N_i
  times the patch's half extent).

The in-plane moment left over becomes opposite tangential forces at the two pads, a couple across the
width (the squeeze's own couple, where the patches are not opposite, turns the object until they are:
it settles, and is not a load); torsion is shared in proportion
to the pads' torsional capacity. The margin is 1 - the worst pad's utilisation of its limit surface
over the load cases: >= 0 holds. This split is one feasible distribution of the contact forces, not
the best one, so a grasp it says holds does hold under the model (a lower bound of its capacity).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Optional

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from pickplan.core.description import RobotInfo
from pickplan.core.settings import Option


class GraspFit(Option):
    """What the quality says of a grasp (a goal set's rejection reason when it is not ``holds``)."""

    holds = "holds"
    slips = "slips"  # the pads' friction cannot carry the load: margin below ``min_margin``
    misses = "misses"  # a pad meets nothing within its rectangle, or the pads meet each other


@dataclass(frozen=True)
class QualitySettings:
    acceleration: float = 2.5  # m/s^2 the hand may accelerate the object with, any direction (the carry)
    gravity: float = 9.81
    compliance: float = 0.0005  # m: surface this close to a pad's first touch is in contact (pad and object give)
    spacing: float = 0.001  # m, mean distance between the surface samples patches are found on
    max_samples: int = 60000  # ... at most this many per object
    min_radius: float = 0.0005  # m: a point contact's torsional radius (its contact patch is not a point)
    min_gap: float = 0.001  # m: pads closer than this when they stop closed on nothing
    min_margin: float = 0.0  # grasps with a lower margin slip
    align_deg: float = 20.0  # a face turned at most this from a pad turns flat onto it
    object_friction: float = 0.8  # an object's friction when it has none of its own (the simulator's default)
    seed: int = 0  # surface samples
    # Observed points (grasps from depth): their contact band (depth noise left after denoising), and
    # the density a target of unknown mass is taken to have over the volume its points enclose down to
    # the support (household objects' order; the ranking, not the density, tells a pinch at the end of
    # a heavy tool from one at its middle).
    point_compliance: float = 0.002
    point_density: float = 400.0
    # The lightest such a target can be (an empty plastic bottle's or a foam block's order): where no
    # reachable grasp from points holds the estimate, those that hold this lighter load are tried, for the
    # density is a guess and a container's inside is taken as solid; one that slips even so slips.
    point_density_light: float = 25.0

    def __post_init__(self):
        for name in (
            "gravity",
            "compliance",
            "spacing",
            "min_radius",
            "object_friction",
            "point_compliance",
            "point_density",
            "point_density_light",
        ):
            if not getattr(self, name) > 0:
                raise ValueError(f"QualitySettings.{name}: expected a positive value, got {getattr(self, name)}")
        if self.point_density_light > self.point_density:
            raise ValueError("QualitySettings: point_density_light must not exceed point_density")
        if not self.acceleration >= 0 or self.max_samples < 100:
            raise ValueError("QualitySettings: expected acceleration >= 0 and max_samples >= 100")


@dataclass(frozen=True)
class Grip:
    """What the gripper holds with (``of``: from its description)."""

    force: float  # N each pad presses with
    friction: float  # Coulomb coefficient between pad and object
    opening: float  # m between the open pads
    pad_length: float  # m along the approach axis
    pad_width: float  # m across the finger

    @classmethod
    def of(cls, gripper: RobotInfo, object_friction: float) -> "Grip":
        return cls(
            float(gripper.grip_force),
            float(gripper.pad_friction) * float(object_friction),
            float(gripper.max_opening),
            float(gripper.pad_length),
            float(gripper.pad_width),
        )


@dataclass(frozen=True)
class Load:
    """The object the grasp carries, in the frame its grasps are in."""

    mass: float  # kg
    com: np.ndarray  # (3,) centre of mass
    down: np.ndarray  # (3,) unit: gravity's direction

    def forces(self, settings: QualitySettings) -> np.ndarray:
        """(K, 3): the forces the grasp must apply to the object, m (a - g), for the hand at rest and
        accelerating by ``settings.acceleration`` along each of the six axis directions (``down`` one)."""
        down = np.asarray(self.down, float) / np.linalg.norm(self.down)
        e1 = np.cross(down, [1.0, 0.0, 0.0] if abs(down[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        axes = np.array([down, e1, np.cross(down, e1)])
        accelerations = np.vstack([np.zeros(3), settings.acceleration * axes, -settings.acceleration * axes])
        return self.mass * (accelerations - settings.gravity * down)


@dataclass
class Patches:
    """Where two pads touch an object, per grasp frame (grasp-frame coordinates; side 0 the pad at +y)."""

    touch: np.ndarray  # (N, 2) bool: the pad meets the object within its rectangle
    centre: np.ndarray  # (N, 2, 3) patch centres
    half: np.ndarray  # (N, 2, 2) half extents of each patch along x and z
    radius: np.ndarray  # (N, 2) mean distance of a patch's points from its centre
    gap: np.ndarray  # (N,) m between the pads where they stop: the grasped width
    tilt: Optional[np.ndarray] = None  # (N, 2) rad between a patch's surface normal and its pad's (0: flush)

    def __post_init__(self):
        if self.tilt is None:
            self.tilt = np.zeros(self.radius.shape)


def _swept_points(P, tree, frames, half_open: float, hx: float, hz: float, balls: int = 3):
    """The points inside each frame's box (|x| <= hx, |y| <= half_open, |z| <= hz) in that frame:
    (owner frame index, index into ``P``, grasp-frame point). Gathered by ``balls`` k-d tree balls
    strung along the closing axis (a third of one ball's volume), each keeping its own slab of y."""
    slab = 2 * half_open / balls
    radius = float(np.sqrt((slab / 2) ** 2 + hx**2 + hz**2)) * (1 + 1e-9)
    owners, rows, points = [], [], []
    for b in range(balls):
        yc = -half_open + (b + 0.5) * slab
        near = tree.query_ball_point(frames[:, :3, 3] + yc * frames[:, :3, 1], radius)
        k = np.repeat(np.arange(len(frames)), [len(a) for a in near])
        j = np.fromiter(itertools.chain.from_iterable(near), dtype=np.int64, count=len(k))
        local = np.einsum("kji,kj->ki", frames[k, :3, :3], P[j] - frames[k, :3, 3])
        y = local[:, 1] - yc
        inside = (
            (np.abs(local[:, 0]) <= hx)
            & (np.abs(local[:, 2]) <= hz)
            & (y >= -slab / 2)
            & ((y < slab / 2) if b < balls - 1 else (y <= slab / 2))
        )
        owners.append(k[inside])
        rows.append(j[inside])
        points.append(local[inside])
    return np.concatenate(owners), np.concatenate(rows), np.concatenate(points)


def _group_means(k, X, n: int) -> np.ndarray:
    """Per owner 0..n-1: the mean of the rows of X it owns (0 where none)."""
    count = np.maximum(np.bincount(k, minlength=n), 1)
    return np.stack([np.bincount(k, X[:, a], minlength=n) for a in range(X.shape[1])], axis=1) / count[:, None]


def _describe(out: Patches, side: int, k, local, member, n: int) -> None:
    """Fill ``out``'s patch ``side`` from the points ``local[member]`` owned by frames ``k[member]``."""
    kk, pts = k[member], local[member]
    count = np.bincount(kk, minlength=n)
    centre = _group_means(kk, pts, n)
    rel = pts[:, [0, 2]] - centre[kk][:, [0, 2]]
    half = np.zeros((n, 2))
    np.maximum.at(half, kk, np.abs(rel))
    out.touch[:, side], out.centre[:, side], out.half[:, side] = count > 0, centre, half
    out.radius[:, side] = np.bincount(kk, np.linalg.norm(rel, axis=1), minlength=n) / np.maximum(count, 1)


def pad_patches(
    points: np.ndarray,
    frames: np.ndarray,
    grip: Grip,
    settings: QualitySettings,
    tree: Optional[cKDTree] = None,
    mirror: bool = False,
    compliance: Optional[float] = None,
    normals: Optional[np.ndarray] = None,
) -> Patches:
    """The patches two pads close on for each grasp frame (``frames``: (N, 4, 4), z the approach, y
    the closing axis, origin between the open pads) on the surface ``points`` ((M, 3), same frame).
    A pad sweeps its rectangle (``pad_width`` along x, ``pad_length`` along z) from the open position
    towards the other: it first meets the point farthest along its side that lies between the open
    pads, and touches the points within ``compliance`` (None: the settings') of it.

    ``normals`` (outward, with the points): where the first-touch patch lies on a face turned less than
    ``align_deg`` from the pad, the squeeze turns the object until the face lies flat on the pad: the
    patch becomes what lies within the compliance of the face's plane. ``mirror`` (points seen from one side): a side with no point beyond the grasp's
    middle is taken as the mirror image of the other side's patch (a grasp from points is centred on
    the section it closes on)."""
    compliance = settings.compliance if compliance is None else float(compliance)
    P = np.asarray(points, float)
    tree = cKDTree(P) if tree is None else tree
    n = len(frames)
    out = Patches(np.zeros((n, 2), bool), np.zeros((n, 2, 3)), np.zeros((n, 2, 2)), np.zeros((n, 2)), np.zeros(n))
    if n == 0:
        return out
    k, j, local = _swept_points(P, tree, frames, grip.opening / 2, grip.pad_width / 2, grip.pad_length / 2)
    has = np.bincount(k, minlength=n) > 0
    first, static = np.full((n, 2), np.nan), []
    for side, (sign, reduce) in enumerate(((1.0, np.maximum), (-1.0, np.minimum))):
        y0 = np.full(n, -sign * np.inf)
        reduce.at(y0, k, local[:, 1])  # the first point each pad meets
        if mirror:
            y0 = np.where(sign * y0 > 0, y0, np.nan)  # nothing seen beyond the middle on this side
        first[:, side] = np.where(has, y0, np.nan)
        static.append(sign * (local[:, 1] - y0[k]) >= -compliance)  # within the compliance of the first touch
        _describe(out, side, k, local, static[side], n)
    if normals is not None and len(k):
        # A face the pad meets turned by less than align_deg turns flat onto it under the squeeze: the
        # pad then touches what lies within the compliance of the face's plane (the normal of the first
        # touch), not of its own.
        N = np.einsum("kji,kj->ki", frames[k, :3, :3], np.asarray(normals, float)[j])  # grasp-frame normals
        for side, sign in ((0, 1.0), (1, -1.0)):
            face = _group_means(k[static[side]], N[static[side]], n)
            face /= np.maximum(np.linalg.norm(face, axis=1, keepdims=True), 1e-12)
            turns = sign * face[:, 1] >= np.cos(np.radians(settings.align_deg))
            h = np.einsum("ij,ij->i", local, face[k])  # height along the face's normal
            top = np.full(n, -np.inf)
            np.maximum.at(top, k, h)
            flush = h >= top[k] - compliance
            member = np.where(turns[k], flush, static[side])
            _describe(out, side, k, local, member, n)
            # A patch that stays turned (a pad's edge on a slope, a rim's lip) is pressed along the
            # surface's normal, not the pad's: its friction cone is tilted by the angle between them,
            # less the spread of the patch's normals (on an edge or corner of the object the pad's own
            # normal is among them: the mean of unit normals spread by s is cos(s) long).
            normal = _group_means(k[member], N[member], n)
            length = np.maximum(np.linalg.norm(normal, axis=1), 1e-12)
            off = np.arccos(np.clip(sign * normal[:, 1] / length, -1.0, 1.0)) - np.arccos(np.clip(length, 0.0, 1.0))
            out.tilt[:, side] = np.where(turns, 0.0, np.maximum(off, 0.0))
    out.gap[:] = np.nan_to_num(first[:, 0] - first[:, 1])
    if mirror:  # one side seen: the other mirrors it across the grasp's middle
        for seen in (0, 1):
            one = out.touch[:, seen] & ~out.touch[:, 1 - seen]
            out.touch[one, 1 - seen] = True
            out.centre[one, 1 - seen] = out.centre[one, seen] * [1.0, -1.0, 1.0]
            out.half[one, 1 - seen], out.radius[one, 1 - seen] = out.half[one, seen], out.radius[one, seen]
            out.tilt[one, 1 - seen] = out.tilt[one, seen]
            out.gap[one] = 2.0 * np.abs(out.centre[one, seen, 1])
    return out


@dataclass
class Quality:
    """Per grasp: the margin (1 - the worst pad's utilisation; >= 0 holds), what it says, the patches."""

    margin: np.ndarray  # (N,)
    fit: list  # (N,) GraspFit
    patches: Patches

    def holds(self) -> np.ndarray:
        return np.array([f is GraspFit.holds for f in self.fit], dtype=bool)

    def order(self) -> np.ndarray:
        """Grasp indices, best margin first (ties keep their order)."""
        return np.argsort(-self.margin, kind="stable")


def utilisation(patches: Patches, frames: np.ndarray, load: Load, grip: Grip, settings: QualitySettings) -> np.ndarray:
    """(N,): the worst pad's use of its limit surface over the load cases (see the module docstring);
    inf where a pad misses, the pads meet or the load lifts a pad off."""
    R, origin = frames[:, :3, :3], frames[:, :3, 3]
    F = np.einsum("nji,kj->nki", R, load.forces(settings))  # (N, K, 3) in each grasp frame
    c = patches.centre  # (N, 2, 3)
    o = 0.5 * (c[:, 0] + c[:, 1])
    com = np.einsum("nji,nj->ni", R, np.asarray(load.com, float) - origin) - o
    T = np.cross(com[:, None, :], F)  # (N, K, 3) about the grasp's centre
    N0 = grip.force
    Np, Nm = N0 - 0.5 * F[..., 1], N0 + 0.5 * F[..., 1]  # the pads at +y and -y
    # The squeeze's own couple, where the patches are not opposite, turns the object in the grip until
    # they are (it settles): only the load's torque is left to hold.
    Rq = T
    h = patches.half  # (N, 2, [x, z])
    cap_x = Np * h[:, None, 0, 1] + Nm * h[:, None, 1, 1]  # centre of pressure moved along z
    cap_z = Np * h[:, None, 0, 0] + Nm * h[:, None, 1, 0]  # ... along x
    left_x = np.sign(Rq[..., 0]) * np.maximum(np.abs(Rq[..., 0]) - cap_x, 0.0)
    left_z = np.sign(Rq[..., 2]) * np.maximum(np.abs(Rq[..., 2]) - cap_z, 0.0)
    w = np.maximum(c[:, 0, 1] - c[:, 1, 1], 1e-9)[:, None]  # the patch centres' distance
    D = np.stack([-2.0 * left_z / w, 2.0 * left_x / w], axis=-1)  # t_+ - t_- along (x, z)
    Ft = F[..., [0, 2]]
    rho = np.maximum(patches.radius, settings.min_radius)
    # a patch pressed along a surface normal tilted from the pad's beyond the friction cone slides: the
    # squeeze pushes the object out (within the cone the object turns in the grip until it settles)
    mu = np.where(patches.tilt < np.arctan(grip.friction), grip.friction, 0.0)[:, None, :]  # (N, 1, 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        torsion = np.abs(T[..., 1]) / (mu[..., 0] * Np * rho[:, None, 0] + mu[..., 1] * Nm * rho[:, None, 1])
        u = np.maximum(
            np.hypot(np.linalg.norm(0.5 * (Ft + D), axis=-1) / (mu[..., 0] * Np), torsion),
            np.hypot(np.linalg.norm(0.5 * (Ft - D), axis=-1) / (mu[..., 1] * Nm), torsion),
        )
    u = np.where(np.isnan(u), np.inf, u)
    u = np.where((Np > 0) & (Nm > 0), u, np.inf).max(axis=1)
    ok = patches.touch.all(axis=1) & (patches.gap >= settings.min_gap)
    return np.where(ok, u, np.inf)


def grasp_quality(
    points: np.ndarray,
    frames: np.ndarray,
    load: Load,
    grip: Grip,
    settings: QualitySettings = QualitySettings(),
    tree: Optional[cKDTree] = None,
    mirror: bool = False,
    compliance: Optional[float] = None,
    normals: Optional[np.ndarray] = None,
) -> Quality:
    """The quality of grasps given as grasp frames (``frames``: (N, 4, 4), in the frame of the surface
    ``points`` and of ``load``); ``mirror``, ``compliance`` and ``normals`` as ``pad_patches``."""
    frames = np.asarray(frames, float).reshape(-1, 4, 4)
    patches = pad_patches(points, frames, grip, settings, tree, mirror, compliance, normals)
    u = utilisation(patches, frames, load, grip, settings) if len(frames) else np.zeros(0)
    margin = 1.0 - u
    fit = [
        GraspFit.misses
        if not np.isfinite(x) and not (t.all() and g >= settings.min_gap)
        else GraspFit.holds
        if m >= settings.min_margin
        else GraspFit.slips
        for x, t, g, m in zip(u, patches.touch, patches.gap, margin)
    ]
    return Quality(np.where(np.isfinite(margin), margin, -np.inf), fit, patches)


def surface_points(mesh, settings: QualitySettings = QualitySettings()):
    """Seeded surface samples about ``spacing`` apart (at most ``max_samples``) and their outward
    normals: what patches are found on."""
    count = int(np.clip(mesh.area / settings.spacing**2, 2000, settings.max_samples))
    points, face = trimesh.sample.sample_surface(mesh, count, seed=settings.seed)
    return np.asarray(points), np.asarray(mesh.face_normals[face])


def surface_tree(mesh, settings: QualitySettings = QualitySettings()):
    """(surface points, their normals, their k-d tree): what a model's quality is computed on, built
    once per mesh."""
    points, normals = surface_points(mesh, settings)
    return points, normals, cKDTree(points)


def model_load(model, object_pose: np.ndarray) -> Load:
    """An object model's load as it lies at ``object_pose`` (world): its mass and centre of mass, gravity
    along the world's -z in its frame."""
    down = np.asarray(object_pose, float)[:3, :3].T @ np.array([0.0, 0.0, -1.0])
    return Load(float(model.mass), np.asarray(model.com, float), down)


def model_quality(
    model,
    hand_poses: np.ndarray,
    object_pose: np.ndarray,
    gripper: RobotInfo,
    settings: QualitySettings = QualitySettings(),
    surface=None,
) -> Quality:
    """The quality of ``gripper``'s hand poses (object frame) on ``model`` lying at ``object_pose``.
    ``surface``: its ``surface_tree`` (None: sampled here)."""
    points, normals, tree = surface_tree(model.mesh, settings) if surface is None else surface
    friction = model.friction if getattr(model, "friction", None) is not None else settings.object_friction
    frames = np.asarray(hand_poses, float).reshape(-1, 4, 4) @ gripper.grasp_frame
    return grasp_quality(
        points, frames, model_load(model, object_pose), Grip.of(gripper, friction), settings, tree, normals=normals
    )
