"""A robot's hand as the grasp generators see it: a URDF of the hand alone (fixed or floating), an
exact hand-vs-object collision check, and the finger-pad contact points C-Space ISF uses.

Each gripper is a ``RobotInfo`` (``core.description``; default: the Panda's, ``core.panda.PANDA``).
Grasp poses are poses of the hand link; the gripper's grasp frame (z approach, y closing, origin
between the pads) sits at ``info.grasp_frame`` in it. The Panda's hand closes along its y axis (left
finger at +y), approaches along +z, and its pad centre sits ``PAD_DEPTH`` along +z.
"""
from __future__ import annotations

import json
import os
import warnings
import xml.etree.ElementTree as ET
from dataclasses import asdict, dataclass
from typing import Optional

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from pickplan.core.caches import memo
from pickplan.core.collision import CollisionChecker, CollisionSettings, SceneMesh
from pickplan.core.description import RobotInfo, pose_matrix
from pickplan.core.io import atomic_open, content_file
from pickplan.core.panda import PANDA, panda_urdf_path
from pickplan.core.paths import assets_dir
from pickplan.core.robots import Robot
from pickplan.omg.grasps.pads import HandContacts, gripper_contacts
from pickplan.omg.grasps.sets import check_grasps

# The Panda hand's facts, named as this package has always named them (their one source: core.panda).
HAND_LINK = PANDA.hand_link
FINGER_LINKS = PANDA.finger_links
FINGER_JOINTS = PANDA.finger_joints
FINGER_OPEN = PANDA.finger_open
PAD_DEPTH = PANDA.pad_depth
CONTACTS_FORMAT = "pickplan.hand_contacts"


# --- the hand model: the hand link's subtree of the robot's URDF -------------------------------------
def _xyz(el, attr: str = "xyz") -> np.ndarray:
    return np.array([float(v) for v in (el.get(attr) or "0 0 0").split()]) if el is not None else np.zeros(3)


def _rpy_matrix(rpy) -> np.ndarray:
    return pose_matrix((0.0, 0.0, 0.0), rpy)[:3, :3]  # the URDF convention, as robot descriptions read it


def _hand_subtree(root: ET.Element, hand_link: str) -> tuple:
    """Names of the links and joints under ``hand_link`` (itself included), leaving out leaves with no
    collision geometry (markers such as the Panda's grasp target)."""
    joints = [j for j in root.findall("joint")]
    links = {hand_link}
    grew = True
    while grew:
        grew = False
        for j in joints:
            if j.find("parent").get("link") in links and j.find("child").get("link") not in links:
                links.add(j.find("child").get("link"))
                grew = True
    parents = {j.find("parent").get("link") for j in joints}
    geometry = {l.get("name") for l in root.findall("link") if l.find("collision") is not None}
    links = {l for l in links if l == hand_link or l in parents or l in geometry}
    kept_joints = {j.get("name") for j in joints if j.find("child").get("link") in links
                   and j.find("parent").get("link") in links}
    return links, kept_joints


def hand_urdf_path(floating: bool = False, gripper: RobotInfo = PANDA) -> str:
    """A URDF of a robot's hand + fingers cut out of its URDF (``gripper.urdf``: the hand link's subtree,
    same meshes, joints and contact parameters; absolute mesh paths). ``floating=True`` prepends three
    prismatic (x, y, z) and three revolute (z, y, x) joints so that a configuration
    ``(x, y, z, a, b, c, fingers...)`` places the hand anywhere: this is how the native FCL checker
    (a robot-vs-scene checker) sees a free hand. Written once per content to a temp folder."""
    return _hand_urdf(bool(floating), gripper.urdf, gripper.hand_link, tuple(gripper.finger_links))


@memo(8)
def _hand_urdf(floating: bool, src: str, hand_link: str, finger_links: tuple) -> str:
    root = ET.parse(src).getroot()
    mesh_dir = os.path.dirname(src)
    keep_links, keep_joints = _hand_subtree(root, hand_link)
    out = ET.Element("robot", name=f"{hand_link}_floating" if floating else f"{hand_link}_hand")
    if floating:
        axes = ["1 0 0", "0 1 0", "0 0 1", "0 0 1", "0 1 0", "1 0 0"]
        names = ["tx", "ty", "tz", "rz", "ry", "rx"]
        ET.SubElement(out, "link", name="float_base")
        parent = "float_base"
        for k, (nm, ax) in enumerate(zip(names, axes)):
            child = hand_link if k == 5 else f"float_{nm}"
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
                name = mesh.get("filename").replace("package://", "")
                mesh.set("filename", name if os.path.isabs(name) else os.path.join(mesh_dir, name))
            for vis in el.findall("visual"):
                el.remove(vis)  # DIRECT clients never render; skips loading the visual meshes
            inertia = el.find("inertial/inertia")
            if inertia is not None:  # placeholder inertias (the Panda's 0.1 kg m^2) make the fingers sluggish
                small = "0.002" if el.get("name") == hand_link else "0.00002"
                for a in ("ixx", "iyy", "izz"):
                    inertia.set(a, small)
            out.append(el)
    return content_file(ET.tostring(out, encoding="unicode"), "hand", ".urdf",
                        stem="floating" if floating else "hand", header='<?xml version="1.0"?>\n')


def hand_configurations(poses, opening: Optional[float] = None, gripper: RobotInfo = PANDA) -> np.ndarray:
    """Configurations (N, 6 + fingers) of the floating hand (``hand_urdf_path(True, gripper)``) for hand
    poses, every finger joint at ``opening`` (default: open)."""
    P = check_grasps(poses, "hand poses")
    with warnings.catch_warnings():  # gimbal lock: scipy picks a valid solution and warns
        warnings.simplefilter("ignore")
        zyx = Rotation.from_matrix(P[:, :3, :3]).as_euler("ZYX")  # R = Rz(a) Ry(b) Rx(c)
    Q = np.empty((len(P), 6 + len(gripper.finger_joints)))
    Q[:, :3], Q[:, 3:6] = P[:, :3, 3], zyx
    Q[:, 6:] = gripper.finger_open if opening is None else opening
    return Q


class HandObjectChecker:
    """Exact hand (+ open fingers) vs object-mesh collision through the native FCL checker.

    Why FCL: it tests the real object mesh (the YCB 16k-face scan, not a convex decomposition),
    detects a hand entirely inside the object, runs a batch natively, and is the checker the
    goal-set builder filters with, so a grasp accepted here is not rejected there for touching
    its own target. PyBullet closest points would test convex hulls of the parts instead.
    """

    def __init__(self, model, clearance: float = 0.0, gripper: RobotInfo = PANDA):
        self.gripper = gripper
        self.robot = Robot.from_urdf(hand_urdf_path(True, gripper))
        self.checker = CollisionChecker(self.robot, [SceneMesh("object", model.mesh, np.eye(4))], None,
                                        CollisionSettings(margin=float(clearance)))

    def in_collision(self, poses, opening: Optional[float] = None) -> np.ndarray:
        if len(poses) == 0:
            return np.zeros(0, dtype=bool)
        return self.checker.in_collision_batch(hand_configurations(poses, opening, self.gripper)).astype(bool)


# --- hand contact points (for C-Space ISF) ----------------------------------------------------------
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
    return os.path.join(assets_dir(), "panda_hand_contacts.json")


@memo(4)
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


def hand_contacts(opening: Optional[float] = None, path: Optional[str] = None, robot=None) -> HandContacts:
    """The finger-pad contacts in the hand-link frame with finger joints at ``opening`` (default open):
    the Panda's from ``assets/panda_hand_contacts.json`` (or ``path``); another robot's
    (``robot``: a ``robots.DescribedRobot``) from its finger collision geometry (``pads.gripper_contacts``)."""
    info = PANDA if robot is None else robot.info
    opening = info.finger_open if opening is None else float(opening)
    lo, hi = sorted((info.finger_open, info.finger_closed))
    if not lo <= opening <= hi:
        raise ValueError(f"opening: expected a finger joint value in [{lo}, {hi}], got {opening}")
    if info.name == PANDA.name or path is not None:
        return _load_contacts(os.path.abspath(path or hand_contacts_path())).at(opening)
    return gripper_contacts(robot).at(opening)
