"""Grasp sets for the Panda hand: loaded (YCB "simulated" / "graspit"), generated ("approach",
"antipodal") and physics-verified ("simulated", in ``grasps_sim``), plus the finger-pad contacts.

Convention for every set pickplan hands out: ``(N, 4, 4)`` poses of the Panda's ``panda_hand``
link in the object (mesh) frame, so the world hand pose is ``T_world_object @ T``. The hand closes
its fingers along its y axis (left finger at +y), approaches along +z, and the finger-pad centre
sits ``PAD_DEPTH`` along +z with the fingers open (0.04 per finger joint). YCB files use a
gripper frame that closes along x: they are post-multiplied by ``YCB_TO_HAND`` (+pi/2 about z).

>>> model = pickplan.objects.library().get("005_tomato_soup_can")
>>> gs = grasp_set(model, "antipodal", n=20, seed=0)      # GraspSet(name, poses, object_name, ...)
>>> world = scene_pose @ gs.poses                          # (20, 4, 4) panda_hand poses in the world
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import tempfile
import warnings
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass, field, replace
from typing import Dict, Optional, Tuple

import numpy as np

from pickplan.core.io import atomic_open
from pickplan.core.panda import PANDA, YCB_TO_HAND, panda_urdf_path

KINDS = ("simulated", "graspit", "approach", "antipodal")
# The hand's facts, named as this module has always named them (their one source: core.panda).
HAND_LINK = PANDA.hand_link
FINGER_LINKS = PANDA.finger_links
FINGER_JOINTS = PANDA.finger_joints
FINGER_OPEN = PANDA.finger_open
PAD_DEPTH = PANDA.pad_depth
CONTACTS_FORMAT = "pickplan.hand_contacts"


# --- grasp sets ------------------------------------------------------------------------------------
def check_grasps(poses, what: str = "grasps", tol: float = 1e-5) -> np.ndarray:
    """``poses`` as a float (N, 4, 4) array of rigid transforms, or ValueError saying what is wrong."""
    arr = np.asarray(poses, dtype=float)
    if arr.ndim != 3 or arr.shape[1:] != (4, 4):
        raise ValueError(f"{what}: expected shape (N, 4, 4), got {arr.shape}")
    if len(arr) == 0:
        return arr
    R = arr[:, :3, :3]
    bad = ~np.all(np.isfinite(arr), axis=(1, 2))
    bad |= np.abs(arr[:, 3] - [0, 0, 0, 1]).max(axis=1) > tol
    bad |= np.abs(R @ R.transpose(0, 2, 1) - np.eye(3)).max(axis=(1, 2)) > tol
    bad |= np.linalg.det(R) < 0
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{what}: pose {i} is not a rigid transform (rotation must be orthonormal with "
                         f"det +1, last row [0, 0, 0, 1]); {int(bad.sum())} of {len(arr)} bad")
    return arr


@dataclass(eq=False)
class GraspSet:
    """A named set of ``panda_hand`` poses in the object frame (see the module docstring)."""

    name: str                      # "simulated" | "graspit" | "approach" | "antipodal"
    poses: np.ndarray              # (N, 4, 4)
    object_name: str
    scores: Optional[np.ndarray] = None       # (N,) higher is better, where the source has one
    info: Dict[str, np.ndarray] = field(default_factory=dict)  # per-grasp extras (contacts, widths...)

    def __post_init__(self):
        self.poses = check_grasps(self.poses, f"grasp set {self.name!r}")
        if self.scores is not None:
            self.scores = np.asarray(self.scores, dtype=float).reshape(-1)
            if len(self.scores) != len(self.poses):
                raise ValueError(f"scores: expected {len(self.poses)} values, got {len(self.scores)}")

    def __len__(self) -> int:
        return len(self.poses)

    def in_world(self, T_world_object) -> np.ndarray:
        """World poses of the hand for an object at ``T_world_object``."""
        return np.asarray(T_world_object, dtype=float) @ self.poses


def _rot_z(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _frame(z: np.ndarray, y_hint: np.ndarray) -> np.ndarray:
    """Rotation with columns (x, y, z): z given, y the part of ``y_hint`` orthogonal to z."""
    z = z / np.linalg.norm(z)
    y = y_hint - np.dot(y_hint, z) * z
    y /= np.linalg.norm(y)
    return np.column_stack([np.cross(y, z), y, z])


def _perpendicular(v: np.ndarray) -> np.ndarray:
    a = np.array([1.0, 0.0, 0.0]) if abs(v[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(v, a)
    return p / np.linalg.norm(p)


def load_grasp_set(model, kind: str) -> GraspSet:
    """A grasp set stored with the object (``grasps_<kind>.npy``), in the pickplan convention."""
    if kind not in model.grasps:
        have = sorted(model.grasps)
        raise ValueError(f"object {model.name!r} has no stored {kind!r} grasps; available: "
                         f"{have if have else 'none'} (generated kinds: 'approach', 'antipodal', 'simulated')")
    poses = check_grasps(model.grasps[kind], f"{model.name} grasps_{kind}.npy")
    return GraspSet(kind, poses @ YCB_TO_HAND, model.name)


def grasp_set(model, kind: str, n: int = 100, seed: int = 0, **kwargs) -> GraspSet:
    """One entry point for the four kinds.

    "graspit" is always the stored set; "simulated" is the stored set when the object has one
    (``n`` and ``seed`` then do not apply; pass ``generate=True`` to simulate anyway), else it
    is generated by ``grasps_sim.simulated_grasps``; "approach" and "antipodal" are generated.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown grasp set kind {kind!r}; expected one of {list(KINDS)}")
    if kind == "graspit":
        return load_grasp_set(model, kind)
    if kind == "simulated":
        if kwargs.pop("generate", False) or "simulated" not in model.grasps:
            from pickplan.omg.grasps_sim import simulated_grasps
            return simulated_grasps(model, n, seed, **kwargs)
        return load_grasp_set(model, kind)
    fn = approach_grasps if kind == "approach" else antipodal_grasps
    return fn(model, n, seed, **kwargs)


def _check_count(n, seed) -> None:
    if int(n) != n or n < 1:
        raise ValueError(f"n: expected a positive number of grasps, got {n!r}")
    if seed is None or int(seed) != seed:
        raise ValueError(f"seed: expected an integer, got {seed!r}")


# --- the hand model: URDF pieces of pybullet_data's Panda -------------------------------------------
def _xyz(el, attr: str = "xyz") -> np.ndarray:
    return np.array([float(v) for v in (el.get(attr) or "0 0 0").split()]) if el is not None else np.zeros(3)


def _rpy_matrix(rpy) -> np.ndarray:
    r, p, y = rpy
    Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    return _rot_z(y) @ Ry @ Rx


@functools.lru_cache(maxsize=2)
def hand_urdf_path(floating: bool = False) -> str:
    """A URDF of the Panda hand + fingers cut out of pybullet_data's panda.urdf (same meshes,
    joints and contact parameters; absolute mesh paths). ``floating=True`` prepends three
    prismatic (x, y, z) and three revolute (z, y, x) joints so that a configuration
    ``(x, y, z, a, b, c, f1, f2)`` places the hand anywhere: this is how the native FCL checker
    (a robot-vs-scene checker) sees a free hand. Written once per content to a temp folder."""
    src = panda_urdf_path()
    root = ET.parse(src).getroot()
    mesh_dir = os.path.dirname(src)
    keep_links, keep_joints = (HAND_LINK,) + FINGER_LINKS, FINGER_JOINTS
    out = ET.Element("robot", name="panda_hand_floating" if floating else "panda_hand")
    if floating:
        axes = ["1 0 0", "0 1 0", "0 0 1", "0 0 1", "0 1 0", "1 0 0"]
        names = ["tx", "ty", "tz", "rz", "ry", "rx"]
        ET.SubElement(out, "link", name="float_base")
        parent = "float_base"
        for k, (nm, ax) in enumerate(zip(names, axes)):
            child = HAND_LINK if k == 5 else f"float_{nm}"
            if k < 5:
                ET.SubElement(out, "link", name=child)
            j = ET.SubElement(out, "joint", name=f"float_{nm}", type="prismatic" if k < 3 else "continuous")
            ET.SubElement(j, "parent", link=parent)
            ET.SubElement(j, "child", link=child)
            ET.SubElement(j, "axis", xyz=ax)
            if k < 3:
                ET.SubElement(j, "limit", lower="-100", upper="100", effort="100", velocity="1")
            parent = child
    for el in root:
        if (el.tag == "link" and el.get("name") in keep_links) or \
                (el.tag == "joint" and el.get("name") in keep_joints):
            el = ET.fromstring(ET.tostring(el))
            for mesh in el.iter("mesh"):
                mesh.set("filename", os.path.join(mesh_dir, mesh.get("filename").replace("package://", "")))
            for vis in el.findall("visual"):
                el.remove(vis)  # DIRECT clients never render; skips loading the visual meshes
            inertia = el.find("inertial/inertia")
            if inertia is not None:  # the URDF's 0.1 kg m^2 placeholders make the fingers sluggish
                small = "0.002" if el.get("name") == HAND_LINK else "0.00002"
                for a in ("ixx", "iyy", "izz"):
                    inertia.set(a, small)
            out.append(el)
    text = ET.tostring(out, encoding="unicode")
    digest = hashlib.sha1(text.encode()).hexdigest()[:16]
    path = os.path.join(tempfile.gettempdir(), f"pickplan-{os.getuid() if hasattr(os, 'getuid') else 0}",
                        "hand", f"{'floating' if floating else 'hand'}-{digest}.urdf")
    if not os.path.isfile(path):
        with atomic_open(path, "w") as f:
            f.write('<?xml version="1.0"?>\n' + text)
    return path


def hand_configurations(poses, opening: float = FINGER_OPEN) -> np.ndarray:
    """Configurations (N, 8) of the floating hand (``hand_urdf_path(True)``) for hand poses."""
    from scipy.spatial.transform import Rotation

    P = check_grasps(poses, "hand poses")
    with warnings.catch_warnings():  # gimbal lock: scipy picks a valid solution and warns
        warnings.simplefilter("ignore")
        zyx = Rotation.from_matrix(P[:, :3, :3]).as_euler("ZYX")  # R = Rz(a) Ry(b) Rx(c)
    Q = np.empty((len(P), 8))
    Q[:, :3], Q[:, 3:6], Q[:, 6:] = P[:, :3, 3], zyx, opening
    return Q


class HandObjectChecker:
    """Exact hand (+ open fingers) vs object-mesh collision through the native FCL checker.

    Why FCL: it tests the real object mesh (the YCB 16k-face scan, not a convex decomposition),
    detects a hand entirely inside the object, runs a batch natively, and is the checker the
    goal-set builder filters with, so a grasp accepted here is not rejected there for touching
    its own target. PyBullet closest points would test convex hulls of the parts instead.
    """

    def __init__(self, model, clearance: float = 0.0):
        from pickplan.core.collision import CollisionChecker, CollisionSettings, SceneMesh
        from pickplan.core.robots import Robot

        self.robot = Robot.from_urdf(hand_urdf_path(True))
        self.checker = CollisionChecker(self.robot, [SceneMesh("object", model.mesh, np.eye(4))], None,
                                        CollisionSettings(margin=float(clearance)))

    def in_collision(self, poses, opening: float = FINGER_OPEN) -> np.ndarray:
        if len(poses) == 0:
            return np.zeros(0, dtype=bool)
        return self.checker.in_collision_batch(hand_configurations(poses, opening)).astype(bool)


# --- hand contact points (for C-Space ISF) ----------------------------------------------------------
@dataclass(frozen=True)
class HandContacts:
    """Finger-pad points and inward normals (towards the other finger) in the ``panda_hand`` frame."""

    points: np.ndarray   # (M, 3) at finger joints = ``opening``
    normals: np.ndarray  # (M, 3) unit, pointing into the grasp (opposite the object's outward normal)
    finger: np.ndarray   # (M,) 0 = panda_leftfinger (joint1), 1 = panda_rightfinger (joint2)
    axes: np.ndarray     # (2, 3) direction each finger moves as its joint value grows (opening)
    opening: float = FINGER_OPEN

    def at(self, opening: float) -> "HandContacts":
        """The same contacts with both finger joints at ``opening`` (0 closed .. 0.04 open)."""
        pts = self.points + self.axes[self.finger] * (float(opening) - self.opening)
        return replace(self, points=pts, opening=float(opening))


@dataclass(frozen=True)
class PadSettings:
    pad_length: float = 0.018   # m of the finger tip that forms the pad (along the approach axis)
    rows: int = 7               # grid along the approach axis
    cols: int = 7               # grid across the finger
    margin: float = 0.0012      # m kept from the pad's edges
    flat_tol: float = 0.0005    # m: hits deeper than this behind the innermost surface are not pad
    max_normal_deg: float = 5.0


def derive_hand_contacts(settings: PadSettings = PadSettings()) -> dict:
    """Pad points from the finger collision mesh and the URDF finger joints (reproducible asset).

    A grid of rays is cast from the grasp's mid-plane outwards onto each finger's inner face; hits
    on near-flat faces (normal within ``max_normal_deg`` of inward) and within ``flat_tol`` of the
    innermost point, in the last ``pad_length`` of the finger, are kept.
    """
    import trimesh

    root = ET.parse(panda_urdf_path()).getroot()
    fingers, pts, nrm, idx = [], [], [], []
    for k, (link, joint) in enumerate(zip(FINGER_LINKS, FINGER_JOINTS)):
        j = root.find(f"joint[@name='{joint}']")
        l = root.find(f"link[@name='{link}']")
        T_joint = np.eye(4)
        T_joint[:3, :3], T_joint[:3, 3] = _rpy_matrix(_xyz(j.find("origin"), "rpy")), _xyz(j.find("origin"))
        axis = T_joint[:3, :3] @ _xyz(j.find("axis"))
        coll = l.find("collision")
        T_coll = np.eye(4)
        T_coll[:3, :3], T_coll[:3, 3] = _rpy_matrix(_xyz(coll.find("origin"), "rpy")), _xyz(coll.find("origin"))
        fname = coll.find("geometry/mesh").get("filename").replace("package://", "")
        mesh = trimesh.load(os.path.join(os.path.dirname(panda_urdf_path()), fname), force="mesh", process=False)
        T_open = np.eye(4)
        T_open[:3, 3] = axis * FINGER_OPEN
        mesh.apply_transform(T_joint @ T_open @ T_coll)  # finger mesh in the hand frame, fingers open
        inward = -axis
        across = np.cross(axis, [0.0, 0.0, 1.0])
        lo, hi = mesh.bounds
        z_top = hi[2]
        zs = np.linspace(z_top - settings.pad_length + settings.margin, z_top - settings.margin, settings.rows)
        w = abs(across) @ (hi - lo) / 2 - settings.margin
        c = across @ (hi + lo) / 2
        us = np.linspace(c - w, c + w, settings.cols)
        # ray origins on the hand's mid-plane (between the fingers), cast outwards onto the pad
        origins = np.array([u * across + np.array([0.0, 0.0, z]) for z in zs for u in us])
        dirs = np.tile(axis, (len(origins), 1))
        loc, ray, tri = mesh.ray.intersects_location(origins, dirs, multiple_hits=False)
        depth = (loc - origins[ray]) @ axis
        good = (mesh.face_normals[tri] @ inward) > np.cos(np.radians(settings.max_normal_deg))
        good &= depth <= depth[good].min() + settings.flat_tol
        order = np.argsort(ray[good])  # grid order, independent of the ray engine's output order
        pts.append(loc[good][order])
        nrm.append(np.tile(inward, (int(good.sum()), 1)))
        idx.append(np.full(int(good.sum()), k))
        fingers.append({"link": link, "joint": joint, "axis": axis.round(12).tolist()})
    return {"format": CONTACTS_FORMAT, "version": 1, "frame": HAND_LINK, "finger_joint_value": FINGER_OPEN,
            "description": "Panda finger-pad contact points and inward normals (towards the other finger) in "
                           "the panda_hand frame with both finger joints at finger_joint_value; a point of "
                           "finger k moves by axis_k * (q_k - finger_joint_value). Generated by "
                           "pickplan.grasps.derive_hand_contacts from pybullet_data franka_panda "
                           "meshes/collision/finger.obj and panda.urdf.",
            "settings": asdict(settings), "fingers": fingers,
            "points": np.concatenate(pts).round(7).tolist(), "normals": (np.concatenate(nrm).round(9) + 0.0).tolist(),
            "finger": np.concatenate(idx).astype(int).tolist()}


def write_hand_contacts(path: str, settings: PadSettings = PadSettings()) -> None:
    """Regenerate the asset: ``write_hand_contacts("assets/panda_hand_contacts.json")``."""
    d = derive_hand_contacts(settings)
    text = json.dumps({k: v for k, v in d.items() if k not in ("points", "normals", "finger")}, indent=1)
    rows = lambda a: "[\n  " + ",\n  ".join(json.dumps(r) for r in a) + "\n ]"  # one point per line
    text = text[:-2] + ',\n "points": ' + rows(d["points"]) + ',\n "normals": ' + rows(d["normals"]) + \
        ',\n "finger": ' + json.dumps(d["finger"]) + "\n}\n"
    with atomic_open(path, "w") as f:
        f.write(text)


def hand_contacts_path() -> str:
    from pickplan.core.robots import assets_dir

    return os.path.join(assets_dir(), "panda_hand_contacts.json")


@functools.lru_cache(maxsize=4)
def _load_contacts(path: str) -> HandContacts:
    with open(path, "r", encoding="utf-8") as f:
        d = json.load(f)
    if d.get("format") != CONTACTS_FORMAT:
        raise ValueError(f"{path}: not a hand contacts file (format {d.get('format')!r})")
    pts, nrm = np.asarray(d["points"], float), np.asarray(d["normals"], float)
    fin = np.asarray(d["finger"], dtype=np.int64)
    if pts.ndim != 2 or pts.shape[1] != 3 or nrm.shape != pts.shape or fin.shape != (len(pts),):
        raise ValueError(f"{path}: points, normals and finger must be (M, 3), (M, 3), (M,)")
    axes = np.asarray([f["axis"] for f in d["fingers"]], float)
    return HandContacts(pts, nrm, fin, axes, float(d["finger_joint_value"]))


def hand_contacts(opening: float = FINGER_OPEN, path: Optional[str] = None) -> HandContacts:
    """The finger-pad contacts (``assets/panda_hand_contacts.json``) with finger joints at ``opening``."""
    if not 0.0 <= opening <= FINGER_OPEN:
        raise ValueError(f"opening: expected a finger joint value in [0, {FINGER_OPEN}], got {opening}")
    return _load_contacts(os.path.abspath(path or hand_contacts_path())).at(opening)


# --- generated sets ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class ApproachSettings:
    clearance: float = 0.002   # m kept between hand and object
    step: float = 0.005        # m between back-off samples, then bisected
    refine: int = 4            # bisection steps (0.3 mm with the default step)


def approach_grasps(model, n: int = 100, seed: int = 0,
                    settings: ApproachSettings = ApproachSettings()) -> GraspSet:
    """The paper's naive "Approach" set: uniformly random approach directions towards the centre of
    the object's bounding box, random roll, the hand backed off along its approach axis until it
    and its open fingers stay clear of the object all the way out (so the approach is free too).

    Starts with the pad centre at the object centre; a hand that fits there collision-free (inside
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
    R = np.stack([_frame(d[i], np.cos(roll[i]) * _perpendicular(d[i]) +
                         np.sin(roll[i]) * np.cross(d[i], _perpendicular(d[i]))) for i in range(n)])

    def poses(R_, s_):  # hand poses with the pad centre at centre - s * approach
        T = np.tile(np.eye(4), (len(s_), 1, 1))
        T[:, :3, :3] = R_
        T[:, :3, 3] = centre - (np.asarray(s_) + PAD_DEPTH)[:, None] * R_[:, :, 2]
        return T

    check = HandObjectChecker(model, settings.clearance)
    hit = check.in_collision(poses(np.repeat(R, len(steps), 0), np.tile(steps, n))).reshape(n, len(steps))
    lo = np.where(hit.any(1), len(steps) - 1 - np.argmax(hit[:, ::-1], axis=1), -1)  # last colliding
    s_free = np.where(lo < 0, 0.0, steps[np.minimum(lo + 1, len(steps) - 1)])
    s_hit = np.where(lo < 0, 0.0, steps[np.maximum(lo, 0)])
    for _ in range(settings.refine if hit.any() else 0):
        mid = 0.5 * (s_free + s_hit)
        c = check.in_collision(poses(R, mid)) & (lo >= 0)
        s_hit, s_free = np.where(c, mid, s_hit), np.where(c | (lo < 0), s_free, mid)
    return GraspSet("approach", poses(R, s_free), model.name, scores=-s_free,
                    info={"approach_distance": s_free, "centre": np.tile(centre, (n, 1))})


@dataclass(frozen=True)
class AntipodalSettings:
    friction: float = 0.3        # Coulomb coefficient: friction cone half-angle atan(0.3) = 16.7 deg
    max_width: float = 0.08      # the Panda's opening
    width_margin: float = 0.005  # pairs must be this much narrower than max_width
    min_width: float = 0.002
    clearance: float = 0.001     # m kept between the open hand and the object
    approach_angles: int = 8     # hand orientations tried about each pair's axis
    per_pair: int = 1            # grasps kept per surface pair (diversity)
    samples_per_round: int = 400
    max_rounds: int = 25


def antipodal_grasps(model, n: int = 100, seed: int = 0, friction: Optional[float] = None,
                     max_width: Optional[float] = None,
                     settings: AntipodalSettings = AntipodalSettings()) -> GraspSet:
    """Antipodal grasps from the mesh: a surface point p (outward normal n_p), a ray from p into
    the object inside the friction cone around -n_p, its exit point q (normal n_q); kept when the
    axis lies in both friction cones and the width fits the opening. The hand closes along the
    axis with the pad centre at the pair midpoint, at ``approach_angles`` rotations about the axis
    (random offset); those whose open hand hits the object are rejected.

    ``info``: "contacts" (N, 2, 3) p and q, "normals" (N, 2, 3) outward object normals, "width".
    ``scores``: cone margin 1 - max angle / cone angle. Fewer than ``n`` (with a warning) if the
    object offers fewer after ``max_rounds`` rounds.
    """
    _check_count(n, seed)
    s = replace(settings, **{k: v for k, v in (("friction", friction), ("max_width", max_width)) if v is not None})
    if s.friction <= 0 or s.max_width <= s.width_margin + s.min_width:
        raise ValueError(f"antipodal: need friction > 0 and max_width > {s.width_margin + s.min_width}, "
                         f"got friction={s.friction}, max_width={s.max_width}")
    import trimesh

    mesh = model.mesh
    cone = np.arctan(s.friction)
    rng = np.random.default_rng(seed)
    check = HandObjectChecker(model, s.clearance)
    out_T, out_c, out_n, out_w, out_s = [], [], [], [], []
    count = 0
    for _ in range(s.max_rounds):
        m = s.samples_per_round
        p, face = trimesh.sample.sample_surface(mesh, m, seed=int(rng.integers(2**31)))
        n_p = mesh.face_normals[face]
        # ray direction uniform in the cone around -n_p
        cos_t = rng.uniform(np.cos(cone), 1.0, m)
        phi = rng.uniform(0, 2 * np.pi, m)
        u = np.array([_perpendicular(v) for v in n_p])
        v = np.cross(n_p, u)
        sin_t = np.sqrt(1 - cos_t ** 2)
        d = -cos_t[:, None] * n_p + sin_t[:, None] * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v)
        loc, ray, tri = mesh.ray.intersects_location(p + 1e-5 * d, d, multiple_hits=False)
        q = np.full((m, 3), np.nan)
        n_q = np.full((m, 3), np.nan)
        q[ray], n_q[ray] = loc, mesh.face_normals[tri]
        w = np.linalg.norm(q - p, axis=1)
        with np.errstate(invalid="ignore"):
            ang_q = np.arccos(np.clip(np.einsum("ij,ij->i", n_q, d), -1, 1))
            ang_p = np.arccos(np.clip(-np.einsum("ij,ij->i", n_p, d), -1, 1))
            ok = (ang_q <= cone) & (w >= s.min_width) & (w <= s.max_width - s.width_margin)
        idx = np.flatnonzero(ok)
        if len(idx) == 0:
            continue
        k = s.approach_angles
        theta = rng.uniform(0, 2 * np.pi, len(idx))[:, None] + 2 * np.pi * np.arange(k) / k
        flip = rng.random(len(idx)) < 0.5  # which finger takes p
        T = np.tile(np.eye(4), (len(idx), k, 1, 1))
        for a, i in enumerate(idx):
            y = -d[i] if flip[a] else d[i]  # +y points from the right finger to the left finger
            z0 = _perpendicular(y)
            for b in range(k):
                z = np.cos(theta[a, b]) * z0 + np.sin(theta[a, b]) * np.cross(y, z0)
                T[a, b, :3, :3] = np.column_stack([np.cross(y, z), y, z])
                T[a, b, :3, 3] = 0.5 * (p[i] + q[i]) - PAD_DEPTH * z
        free = ~check.in_collision(T.reshape(-1, 4, 4)).reshape(len(idx), k)
        for a, i in enumerate(idx):
            choices = np.flatnonzero(free[a])
            if len(choices) == 0:
                continue
            for b in rng.permutation(choices)[:s.per_pair]:
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
        return GraspSet("antipodal", np.zeros((0, 4, 4)), model.name, scores=np.zeros(0))
    return GraspSet("antipodal", np.asarray(out_T)[:n], model.name, scores=np.asarray(out_s)[:n],
                    info={"contacts": np.asarray(out_c)[:n], "normals": np.asarray(out_n)[:n],
                          "width": np.asarray(out_w)[:n]})
