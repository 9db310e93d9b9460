"""URDF files as XML for robot descriptions: read at the door (not XML, malformed XML, a link or
joint named twice, a mesh whose file is named twice: problems naming the description's field and
the URDF), and an arm's URDF composed with a gripper's mounted on one of its links.

Pure Python (no native module), like ``core.description``.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from typing import Optional, Tuple

import numpy as np

from pickplan.core.fields import FieldReader
from pickplan.core.io import content_file

MAX_URDF_BYTES = 50_000_000  # a URDF is a few hundred kB; more is not a robot


def pose_matrix(xyz, rpy) -> np.ndarray:
    """xyz + roll-pitch-yaw (URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)) -> 4x4."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    T = np.eye(4)
    T[:3, :3] = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    T[:3, 3] = [float(v) for v in xyz]
    return T


def rpy_of(R: np.ndarray) -> Tuple[float, float, float]:
    """Roll, pitch, yaw of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1, 1)))
    if abs(R[2, 0]) < 1 - 1e-9:
        return float(np.arctan2(R[2, 1], R[2, 2])), pitch, float(np.arctan2(R[1, 0], R[0, 0]))
    return float(np.arctan2(-R[1, 2], R[1, 1])), pitch, 0.0


def read_urdf(r: FieldReader, path: str, field: str) -> ET.Element:
    """The root ``<robot>`` element of the URDF at ``path`` (named by the description's ``field``);
    a problem, and the part abandoned, when it is not a readable, well-formed URDF."""
    try:
        if os.path.getsize(path) > MAX_URDF_BYTES:
            r.fail(field, f"{path}: {os.path.getsize(path)} bytes, more than a URDF ({MAX_URDF_BYTES})")
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        r.fail(field, f"{path} is not well-formed XML ({exc})")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        r.fail(field, f"{path} cannot be read ({exc})")
    if root.tag != "robot":
        r.fail(field, f"{path} is not a URDF: its root element is <{root.tag}>, expected <robot>")
    for kind in ("link", "joint"):
        names = [el.get("name") for el in root.findall(kind)]
        twice = sorted({n for n in names if names.count(n) > 1}, key=str)
        if twice:
            r.fail(field, f"{path}: {kind} names given more than once: {twice}")
    return root


def joint_types(root: ET.Element) -> dict:
    """Joint name -> URDF joint type."""
    return {j.get("name"): j.get("type") for j in root.iter("joint")}


def joint_efforts(root: ET.Element) -> dict:
    """Joint name -> its ``<limit effort=...>`` as text (None where the URDF states none)."""
    out = {}
    for j in root.iter("joint"):
        limit = j.find("limit")
        out[j.get("name")] = None if limit is None else limit.get("effort")
    return out


def _absolute_meshes(root: ET.Element, urdf: str) -> None:
    folder = os.path.dirname(os.path.abspath(urdf))
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://"):
            name = name[len("package://") :]
        if not os.path.isabs(name):
            mesh.set("filename", os.path.join(folder, name))


def compose_mount(
    r: FieldReader,
    arm: ET.Element,
    arm_urdf: str,
    hand: ET.Element,
    gripper_urdf: str,
    parent: str,
    T: np.ndarray,
    source: str,
) -> Optional[str]:
    """The arm's URDF with the gripper's fixed to ``parent`` at ``T``: written once per content
    (a file of pickplan's, never named in a message: problems name the description's fields)."""
    _absolute_meshes(arm, arm_urdf)
    _absolute_meshes(hand, gripper_urdf)
    if parent not in {link.get("name") for link in arm.iter("link")}:
        r.fail("mount.parent_link", f"{parent!r} is not a link of {arm_urdf}")
    children = {j.find("child").get("link") for j in hand.iter("joint") if j.find("child") is not None}
    roots = [link.get("name") for link in hand.iter("link") if link.get("name") not in children]
    if len(roots) != 1:
        r.fail("mount.urdf", f"expected one root link in {gripper_urdf}, found {roots}")
    both = {link.get("name") for link in arm.iter("link")} & {link.get("name") for link in hand.iter("link")}
    if both:
        r.fail("mount.urdf", f"links {sorted(both)} of {gripper_urdf} are also links of {arm_urdf}")
    for el in list(hand):
        if el.tag in ("link", "joint"):
            arm.append(el)
    joint = ET.SubElement(arm, "joint", name=f"{parent}_to_{roots[0]}", type="fixed")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=roots[0])
    rpy = rpy_of(T[:3, :3])
    ET.SubElement(joint, "origin", xyz=" ".join(f"{v:.12g}" for v in T[:3, 3]), rpy=" ".join(f"{v:.12g}" for v in rpy))
    return content_file(
        ET.tostring(arm, encoding="unicode"),
        "robots",
        ".urdf",
        stem=os.path.splitext(os.path.basename(source))[0],
        header='<?xml version="1.0"?>\n',
    )
