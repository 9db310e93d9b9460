"""A robot's hand as the grasp generators see it: a URDF of the hand alone (fixed or floating), an
exact hand-vs-object collision check, and the finger-pad contact points C-Space ISF uses.

Each gripper is a ``RobotInfo`` (``core.description``; default: the Panda's, ``core.panda.PANDA``).
Grasp poses are poses of the hand link; the gripper's grasp frame (z approach, y closing, origin
between the pads) sits at ``info.grasp_frame`` in it. The Panda's hand closes along its y axis (left
finger at +y), approaches along +z, and its pad centre sits ``PAD_DEPTH`` along +z.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from typing import Optional

import numpy as np
from scipy.spatial.transform import Rotation

from pickplan.core.caches import memo
from pickplan.core.collision import CollisionChecker, CollisionSettings, SceneMesh
from pickplan.core.description import RobotInfo
from pickplan.core.io import content_file
from pickplan.core.panda import PANDA
from pickplan.core.robots import Robot, panda
from pickplan.omg.grasps.pads import HandContacts, gripper_contacts
from pickplan.omg.grasps.sets import check_grasps

# The Panda hand's facts, named as this package has always named them (their one source: core.panda).
HAND_LINK = PANDA.hand_link
FINGER_LINKS = PANDA.finger_links
FINGER_JOINTS = PANDA.finger_joints
FINGER_OPEN = PANDA.finger_open
PAD_DEPTH = PANDA.pad_depth


# --- the hand model: the hand link's subtree of the robot's URDF -------------------------------------
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
    kept_joints = {
        j.get("name") for j in joints if j.find("child").get("link") in links and j.find("parent").get("link") in links
    }
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
        if (el.tag == "link" and el.get("name") in keep_links) or (el.tag == "joint" and el.get("name") in keep_joints):
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
    return content_file(
        ET.tostring(out, encoding="unicode"),
        "hand",
        ".urdf",
        stem="floating" if floating else "hand",
        header='<?xml version="1.0"?>\n',
    )


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
        self.checker = CollisionChecker(
            self.robot, [SceneMesh("object", model.mesh, np.eye(4))], None, CollisionSettings(margin=float(clearance))
        )

    def in_collision(self, poses, opening: Optional[float] = None) -> np.ndarray:
        if len(poses) == 0:
            return np.zeros(0, dtype=bool)
        return self.checker.in_collision_batch(hand_configurations(poses, opening, self.gripper)).astype(bool)


# --- hand contact points (for C-Space ISF) ----------------------------------------------------------
def hand_contacts(opening: Optional[float] = None, robot=None) -> HandContacts:
    """The finger-pad contacts in the hand-link frame with finger joints at ``opening`` (default open)
    of ``robot`` (a ``robots.DescribedRobot``; default: the Panda), derived from its finger collision
    geometry (``pads.gripper_contacts``: one derivation for every gripper)."""
    if robot is None:
        robot = panda()
    info = robot.info
    opening = info.finger_open if opening is None else float(opening)
    lo, hi = sorted((info.finger_open, info.finger_closed))
    if not lo <= opening <= hi:
        raise ValueError(f"opening: expected a finger joint value in [{lo}, {hi}], got {opening}")
    return gripper_contacts(robot).at(opening)
