"""Robot descriptions: one TOML file says everything pickplan needs of a robot and its gripper.

A description names the URDF (and optionally a gripper URDF mounted on a link of it), the base pose,
the arm joints and start configuration, the gripper (hand link, finger links and joints with their
open and closed values, the largest opening, the pads, and the grasp frame: z the approach axis, y
the closing axis, the origin between the pads), body-point density, link pairs whose collisions are
ignored, and joint velocity / acceleration / jerk limits. ``assets/robots/*.toml`` are the shipped
ones; ``pickplan robots check FILE`` validates a user's (``description_check``).

Paths in a file: ``pybullet_data:REL`` (pybullet_data's folder), ``assets:REL`` (pickplan's assets),
an absolute path, or a path relative to the description file. This module is pure Python: loading a
description does not need the native module; checking it against the robot model does.
"""
from __future__ import annotations

import os
import sys
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from pickplan.core.io import content_file
from pickplan.core.paths import assets_dir

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python < 3.11 reads TOML with the tomli backport
    import tomli as tomllib

ROBOTS_FOLDER = "robots"   # under assets/


class DescriptionError(ValueError):
    """A robot description that cannot be used; ``problems`` lists every one found."""

    def __init__(self, source: str, problems: List[str]):
        self.source, self.problems = source, list(problems)
        super().__init__(f"{source}: " + "; ".join(self.problems))


@dataclass(frozen=True)
class FingerJoint:
    name: str
    open: float     # joint value with the gripper open
    closed: float   # joint value with the gripper closed on nothing


@dataclass(frozen=True)
class GripperSpec:
    hand_link: str
    finger_links: Tuple[str, ...]
    finger_joints: Tuple[FingerJoint, ...]
    max_opening: float         # m between the pads, open
    pad_length: float          # m of finger along the approach axis that touches
    pad_width: float           # m across the finger
    grasp_frame: np.ndarray    # 4x4 in the hand link: z approach, y closing, origin between the pads


@dataclass(frozen=True)
class RobotDescription:
    name: str
    description: str
    source: str                      # the file it was read from
    urdf: str                        # the URDF to load (composed with the gripper where there is a mount)
    package_dirs: Tuple[str, ...]
    base_pose: np.ndarray            # 4x4 world pose of the robot's root link
    arm_joints: Tuple[str, ...]
    start: Tuple[float, ...]         # arm joint values, in arm_joints order
    body_points_per_link: int
    skip_collision: Tuple[Tuple[str, str], ...]
    velocity_limits: Optional[Tuple[float, ...]]      # per arm joint; None: the URDF's
    acceleration_limits: Optional[Tuple[float, ...]]
    jerk_limits: Optional[Tuple[float, ...]]
    finger_acceleration_limit: Optional[float]        # per finger joint (m/s^2 or rad/s^2)
    gripper: GripperSpec

    @property
    def opening_configuration(self) -> Dict[str, float]:
        """Finger joint values with the gripper open."""
        return {f.name: f.open for f in self.gripper.finger_joints}


@dataclass(frozen=True)
class RobotInfo:
    """A described robot's facts as the planner, grasps and execution read them (one per description)."""

    name: str
    urdf: str           # the robot's URDF (with the gripper where the description mounts one)
    hand_link: str
    finger_links: tuple
    finger_joints: tuple
    arm_joints: tuple
    arm_dof: int
    ready: tuple        # the start configuration: arm start, then every finger open (URDF joint order)
    finger_open: float  # joint value of every finger joint with the gripper open
    finger_closed: float  # ... and closed on nothing
    pad_depth: float    # m from the hand link's origin to the grasp frame's (the pad centre)
    max_opening: float  # m between the pads, open
    pad_length: float   # m of finger along the approach axis that touches
    pad_width: float    # m across the finger
    grasp_frame: np.ndarray        # 4x4 in the hand link: z approach, y closing, origin between the pads
    arm_velocity_limits: Optional[tuple]     # rad/s; None: the URDF's
    arm_acceleration_limits: tuple           # rad/s^2
    arm_jerk_limits: Optional[tuple]         # rad/s^3 (stated for controllers; not enforced)
    finger_acceleration_limit: float         # m/s^2 or rad/s^2

    @classmethod
    def from_description(cls, desc: RobotDescription) -> "RobotInfo":
        g = desc.gripper
        opens = {f.open for f in g.finger_joints}
        closes = {f.closed for f in g.finger_joints}
        if len(opens) != 1 or len(closes) != 1:  # one command opens / closes every finger
            raise DescriptionError(desc.source, ["gripper.finger_joints: every finger joint needs the same open and "
                                                 f"the same closed value, got open {sorted(opens)}, closed {sorted(closes)}"])
        acceleration = desc.acceleration_limits or (DEFAULT_ACCELERATION,) * len(desc.arm_joints)
        return cls(name=desc.name, urdf=desc.urdf, hand_link=g.hand_link, finger_links=tuple(g.finger_links),
                   finger_joints=tuple(f.name for f in g.finger_joints), arm_joints=tuple(desc.arm_joints),
                   arm_dof=len(desc.arm_joints), ready=tuple(desc.start) + tuple(f.open for f in g.finger_joints),
                   finger_open=opens.pop(), finger_closed=closes.pop(),
                   pad_depth=float(np.linalg.norm(g.grasp_frame[:3, 3])), max_opening=float(g.max_opening),
                   pad_length=float(g.pad_length), pad_width=float(g.pad_width), grasp_frame=np.array(g.grasp_frame),
                   arm_velocity_limits=desc.velocity_limits, arm_acceleration_limits=tuple(acceleration),
                   arm_jerk_limits=desc.jerk_limits,
                   finger_acceleration_limit=float(desc.finger_acceleration_limit or DEFAULT_FINGER_ACCELERATION))

    @property
    def key(self) -> tuple:
        """What identifies the gripper in caches (the dataclass holds an array, so it does not hash)."""
        return (self.name, self.urdf, self.hand_link, self.finger_joints, self.finger_open, self.max_opening,
                tuple(np.round(self.grasp_frame, 9).ravel()))

    @property
    def hand_from_grasp(self) -> np.ndarray:
        """Grasp-frame pose -> hand-link pose: ``T_hand = T_grasp @ hand_from_grasp``."""
        return np.linalg.inv(self.grasp_frame)

    @property
    def finger_travel(self) -> float:
        """Joint travel of each finger from open to closed (signed)."""
        return self.finger_closed - self.finger_open


def robot_info(name_or_file: str) -> RobotInfo:
    """The facts of a described robot (a shipped name, short name or .toml file), without its model."""
    return RobotInfo.from_description(load_description(name_or_file))


# Where a description states no acceleration limits: conservative values, said in the file's docs.
DEFAULT_ACCELERATION = 3.0          # rad/s^2 per arm joint
DEFAULT_FINGER_ACCELERATION = 1.0   # m/s^2 (or rad/s^2) per finger joint


# --- small parsers that collect problems instead of raising at the first ------------------------------
def pose_matrix(xyz, rpy) -> np.ndarray:
    """xyz + roll-pitch-yaw (URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll)) -> 4x4."""
    r, p, y = (float(v) for v in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    T = np.eye(4)
    T[:3, :3] = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                 [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                 [-sp, cp * sr, cp * cr]]
    T[:3, 3] = [float(v) for v in xyz]
    return T


class _Reader:
    def __init__(self, data: dict, problems: List[str]):
        self.data, self.problems = data, problems

    def get(self, table: dict, key: str, kind, where: str, default=None, required: bool = True):
        if key not in table:
            if required:
                self.problems.append(f"{where}{key}: missing")
            return default
        value = table[key]
        ok = isinstance(value, kind) and not isinstance(value, bool) if kind is not bool else isinstance(value, bool)
        if kind is float:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value)
        if not ok:
            self.problems.append(f"{where}{key}: expected {getattr(kind, '__name__', kind)}, got {value!r}")
            return default
        return float(value) if kind is float else value

    def numbers(self, table: dict, key: str, where: str, n: Optional[int] = None, required: bool = True):
        value = self.get(table, key, list, where, required=required)
        if value is None:
            return None
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value):
            self.problems.append(f"{where}{key}: expected finite numbers, got {value!r}")
            return None
        if n is not None and len(value) != n:
            self.problems.append(f"{where}{key}: expected {n} values, got {len(value)}")
            return None
        return tuple(float(v) for v in value)

    def pose(self, table: dict, key: str, where: str, required: bool = True) -> Optional[np.ndarray]:
        sub = self.get(table, key, dict, where, required=required)
        if sub is None:
            return None if required else np.eye(4)
        xyz = self.numbers(sub, "xyz", f"{where}{key}.", 3)
        rpy = self.numbers(sub, "rpy", f"{where}{key}.", 3)
        self.unknown(sub, ("xyz", "rpy"), f"{where}{key}.")
        return None if xyz is None or rpy is None else pose_matrix(xyz, rpy)

    def unknown(self, table: dict, known, where: str) -> None:
        for key in sorted(set(table) - set(known)):
            self.problems.append(f"{where}{key}: unknown key (expected one of {sorted(known)})")


def resolve_path(text: str, relative_to: str) -> str:
    """``pybullet_data:REL``, ``assets:REL``, absolute, or relative to ``relative_to``'s folder."""
    if text.startswith("pybullet_data:"):
        import pybullet_data  # only when a description asks for its files

        return os.path.join(pybullet_data.getDataPath(), text[len("pybullet_data:"):])
    if text.startswith("assets:"):
        return os.path.join(assets_dir(), text[len("assets:"):])
    return text if os.path.isabs(text) else os.path.join(os.path.dirname(os.path.abspath(relative_to)), text)


# --- the file -------------------------------------------------------------------------------------
TOP_KEYS = ("name", "description", "urdf", "package_dirs", "base", "arm_joints", "start", "body_points_per_link",
            "skip_collision", "mount", "limits", "gripper")


def shipped() -> List[str]:
    """Names of the descriptions pickplan ships (``assets/robots/<name>.toml``)."""
    folder = os.path.join(assets_dir(), ROBOTS_FOLDER)
    return sorted(f[:-5] for f in os.listdir(folder) if f.endswith(".toml"))


def shipped_name(name: str) -> str:
    """A shipped robot's full name from its name or a short name: the part before the first "_"
    of exactly one shipped name ("iiwa" -> "iiwa_wsg50", "ur5" -> "ur5_2f85")."""
    names = shipped()
    if name in names:
        return name
    short = [n for n in names if n.split("_")[0] == name]
    if len(short) != 1:
        raise FileNotFoundError(f"no shipped robot {name!r}; shipped: {names} (short names: "
                                f"{sorted(n.split('_')[0] for n in names)}; or give a .toml file)")
    return short[0]


def description_path(name_or_file: str) -> str:
    """A shipped robot's file by name (or short name, ``shipped_name``), or the file given."""
    if os.path.sep not in name_or_file and not name_or_file.endswith(".toml"):
        return os.path.join(assets_dir(), ROBOTS_FOLDER, shipped_name(name_or_file) + ".toml")
    if not os.path.isfile(name_or_file):
        raise FileNotFoundError(f"robot description not found: {name_or_file}")
    return name_or_file


def load_description(name_or_file: str) -> RobotDescription:
    """Read and check the form of a description (every problem at once, as ``DescriptionError``)."""
    desc, problems = parse_description(name_or_file)
    if problems:
        raise DescriptionError(desc.source if desc else name_or_file, problems)
    return desc


def parse_description(name_or_file: str) -> Tuple[Optional[RobotDescription], List[str]]:
    """The description as far as it can be read (defaults where a value is wrong) and every problem
    of its form; None when the file is not TOML at all."""
    path = description_path(name_or_file)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        return None, [f"not valid TOML: {exc}"]
    problems: List[str] = []
    r = _Reader(data, problems)
    r.unknown(data, TOP_KEYS, "")
    name = r.get(data, "name", str, "", default="?")
    if not isinstance(data.get("description", ""), str):
        problems.append(f"description: expected str, got {data['description']!r}")
    urdf_text = r.get(data, "urdf", str, "", default="")
    urdf = resolve_path(urdf_text, path) if urdf_text else ""
    if urdf and not os.path.isfile(urdf):
        problems.append(f"urdf: file not found: {urdf}")
    package_dirs = r.get(data, "package_dirs", list, "", default=[], required=False)
    package_dirs = tuple(resolve_path(p, path) for p in package_dirs if isinstance(p, str))
    base = r.pose(data, "base", "", required=False)
    base = np.eye(4) if base is None else base
    arm = r.get(data, "arm_joints", list, "", default=[])
    if not all(isinstance(j, str) for j in arm):
        problems.append(f"arm_joints: expected joint names, got {arm!r}")
        arm = []
    start = r.numbers(data, "start", "", len(arm) if arm else None) or (0.0,) * len(arm)
    per_link = r.get(data, "body_points_per_link", int, "", default=20, required=False)
    if per_link is not None and per_link < 1:
        problems.append(f"body_points_per_link: expected a positive count, got {per_link}")
    skip = r.get(data, "skip_collision", list, "", default=[], required=False)
    if not all(isinstance(p, list) and len(p) == 2 and all(isinstance(s, str) for s in p) for p in skip):
        problems.append(f"skip_collision: expected pairs of link names, got {skip!r}")
        skip = []
    limits = r.get(data, "limits", dict, "", default={}, required=False)
    r.unknown(limits, ("velocity", "acceleration", "jerk", "finger_acceleration"), "limits.")
    finger_acc = r.get(limits, "finger_acceleration", float, "limits.", required=False)
    if finger_acc is not None and finger_acc <= 0:
        problems.append(f"limits.finger_acceleration: expected a positive value, got {finger_acc}")
    lim = {k: r.numbers(limits, k, "limits.", len(arm) if arm else None, required=False)
           for k in ("velocity", "acceleration", "jerk")}
    for k, v in lim.items():
        if v is not None and min(v) <= 0:
            problems.append(f"limits.{k}: expected positive values, got {list(v)}")
    gripper = _gripper(r, r.get(data, "gripper", dict, "", default={}))
    mount = r.get(data, "mount", dict, "", required=False)
    if mount is not None and urdf and os.path.isfile(urdf):
        urdf = _compose(r, mount, urdf, path)
    return RobotDescription(name=name, description=str(data.get("description", "")), source=path, urdf=urdf,
                            package_dirs=package_dirs, base_pose=base, arm_joints=tuple(arm), start=start,
                            body_points_per_link=int(per_link or 20), skip_collision=tuple(tuple(p) for p in skip),
                            velocity_limits=lim["velocity"], acceleration_limits=lim["acceleration"],
                            jerk_limits=lim["jerk"], finger_acceleration_limit=finger_acc, gripper=gripper), problems


def _gripper(r: _Reader, g: dict) -> Optional[GripperSpec]:
    w = "gripper."
    r.unknown(g, ("hand_link", "finger_links", "finger_joints", "max_opening", "pad", "grasp_frame"), w)
    hand = r.get(g, "hand_link", str, w, default="")
    links = r.get(g, "finger_links", list, w, default=[])
    joints = []
    for k, j in enumerate(r.get(g, "finger_joints", list, w, default=[])):
        where = f"{w}finger_joints[{k}]."
        if not isinstance(j, dict):
            r.problems.append(f"{where[:-1]}: expected {{name, open, closed}}, got {j!r}")
            continue
        r.unknown(j, ("name", "open", "closed"), where)
        joints.append(FingerJoint(r.get(j, "name", str, where, default=""), r.get(j, "open", float, where, default=0.0),
                                  r.get(j, "closed", float, where, default=0.0)))
    if not joints:
        r.problems.append(f"{w}finger_joints: at least one finger joint is needed")
    opening = r.get(g, "max_opening", float, w, default=0.0)
    if not 0 < opening <= 0.5:
        r.problems.append(f"{w}max_opening: expected metres in (0, 0.5], got {opening}")
    pad = r.get(g, "pad", dict, w, default={}, required=False)
    r.unknown(pad, ("length", "width"), f"{w}pad.")
    frame = r.pose(g, "grasp_frame", w)
    frame = np.eye(4) if frame is None else frame
    return GripperSpec(hand, tuple(links), tuple(joints), opening,
                       r.get(pad, "length", float, f"{w}pad.", default=0.0, required=bool(pad)),
                       r.get(pad, "width", float, f"{w}pad.", default=0.0, required=bool(pad)), frame)


def _absolute_meshes(root: ET.Element, urdf: str) -> None:
    folder = os.path.dirname(os.path.abspath(urdf))
    for mesh in root.iter("mesh"):
        name = mesh.get("filename", "")
        if name.startswith("package://"):
            name = name[len("package://"):]
        if not os.path.isabs(name):
            mesh.set("filename", os.path.join(folder, name))


def _compose(r: _Reader, mount: dict, arm_urdf: str, source: str) -> str:
    """The arm's URDF with the gripper's fixed to ``parent_link``: written once per content."""
    w = "mount."
    r.unknown(mount, ("urdf", "parent_link", "xyz", "rpy"), w)
    gripper_text = r.get(mount, "urdf", str, w, default="")
    parent = r.get(mount, "parent_link", str, w, default="")
    T = pose_matrix(r.numbers(mount, "xyz", w, 3) or (0, 0, 0), r.numbers(mount, "rpy", w, 3) or (0, 0, 0))
    gripper_urdf = resolve_path(gripper_text, source) if gripper_text else ""
    if not os.path.isfile(gripper_urdf):
        r.problems.append(f"{w}urdf: file not found: {gripper_urdf or '(none given)'}")
        return arm_urdf
    arm, hand = ET.parse(arm_urdf).getroot(), ET.parse(gripper_urdf).getroot()
    _absolute_meshes(arm, arm_urdf)
    _absolute_meshes(hand, gripper_urdf)
    arm_links = {l.get("name") for l in arm.iter("link")}
    if parent not in arm_links:
        r.problems.append(f"{w}parent_link: {parent!r} is not a link of {arm_urdf}")
        return arm_urdf
    children = {j.find("child").get("link") for j in hand.iter("joint") if j.find("child") is not None}
    roots = [l.get("name") for l in hand.iter("link") if l.get("name") not in children]
    if len(roots) != 1:
        r.problems.append(f"{w}urdf: expected one root link in {gripper_urdf}, found {roots}")
        return arm_urdf
    for el in list(hand):
        if el.tag in ("link", "joint"):
            arm.append(el)
    joint = ET.SubElement(arm, "joint", name=f"{parent}_to_{roots[0]}", type="fixed")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=roots[0])
    rpy = _rpy_of(T[:3, :3])
    ET.SubElement(joint, "origin", xyz=" ".join(f"{v:.12g}" for v in T[:3, 3]), rpy=" ".join(f"{v:.12g}" for v in rpy))
    return content_file(ET.tostring(arm, encoding="unicode"), "robots", ".urdf",
                        stem=os.path.splitext(os.path.basename(source))[0], header='<?xml version="1.0"?>\n')


def _rpy_of(R: np.ndarray) -> Tuple[float, float, float]:
    """Roll, pitch, yaw of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = float(np.arcsin(np.clip(-R[2, 0], -1, 1)))
    if abs(R[2, 0]) < 1 - 1e-9:
        return float(np.arctan2(R[2, 1], R[2, 2])), pitch, float(np.arctan2(R[1, 0], R[0, 0]))
    return float(np.arctan2(-R[1, 2], R[1, 1])), pitch, 0.0
