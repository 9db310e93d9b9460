"""Robot descriptions: one TOML file says everything pickplan needs of a robot and its gripper.

A description names the URDF (and optionally a gripper URDF mounted on a link of it), the base pose,
the arm joints and start configuration, the gripper (hand link, finger links and joints with their
open and closed values, the largest opening, the pads, and the grasp frame: z the approach axis, y
the closing axis, the origin between the pads), body-point density, link pairs whose collisions are
ignored, and joint velocity / acceleration / jerk limits. ``assets/robots/*.toml`` are the shipped
ones. This module reads a file's form (types, physical ranges: ``parse_description``, every problem
as a ``Problem``); ``description_check`` checks it against the robot model, and
``robots.check_description`` / ``robots.load_robot`` run both, the one path every command takes.

Paths in a file: ``pybullet_data:REL`` (pybullet_data's folder), ``assets:REL`` (pickplan's assets),
an absolute path, or a path relative to the description file. This module is pure Python: loading a
description does not need the native module; checking it against the robot model does.
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import numpy as np

from pickplan.core.errors import InputError, Problem
from pickplan.core.fields import FieldReader
from pickplan.core.paths import assets_dir
from pickplan.core.urdf_xml import compose_mount, pose_matrix, read_urdf  # noqa: F401  (pose_matrix re-exported)

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python < 3.11 reads TOML with the tomli backport
    import tomli as tomllib

ROBOTS_FOLDER = "robots"  # under assets/
# Where a description states no gripper force, speed or pad friction: a small electric parallel
# gripper's (the Franka Hand's 70 N continuous grasp force, 0.1 m/s), rubber-like pads.
DEFAULT_GRIP_FORCE = 70.0  # N each pad presses an object with
DEFAULT_GRIP_SPEED = 0.1  # m/s per finger
DEFAULT_PAD_FRICTION = 1.0  # Coulomb coefficient (times the object's own, as the simulator combines them)


@dataclass(frozen=True)
class FingerJoint:
    name: str
    open: float  # joint value with the gripper open
    closed: float  # joint value with the gripper closed on nothing


@dataclass(frozen=True)
class GripperSpec:
    hand_link: str
    finger_links: Tuple[str, ...]
    finger_joints: Tuple[FingerJoint, ...]
    max_opening: float  # m between the pads, open
    pad_length: float  # m of finger along the approach axis that touches
    pad_width: float  # m across the finger
    grasp_frame: np.ndarray  # 4x4 in the hand link: z approach, y closing, origin between the pads
    force: float = DEFAULT_GRIP_FORCE  # N each pad presses an object with when the gripper squeezes
    speed: float = DEFAULT_GRIP_SPEED  # m/s each finger closes at
    pad_friction: float = DEFAULT_PAD_FRICTION  # Coulomb coefficient of the pads (times an object's own)


@dataclass(frozen=True)
class RobotDescription:
    name: str
    description: str
    source: str  # the file it was read from
    urdf: str  # the URDF to load (composed with the gripper where there is a mount)
    package_dirs: Tuple[str, ...]
    base_pose: np.ndarray  # 4x4 world pose of the robot's root link
    arm_joints: Tuple[str, ...]
    start: Tuple[float, ...]  # arm joint values, in arm_joints order
    body_points_per_link: int
    skip_collision: Tuple[Tuple[str, str], ...]
    velocity_limits: Optional[Tuple[float, ...]]  # per arm joint; None: the URDF's
    acceleration_limits: Optional[Tuple[float, ...]]
    jerk_limits: Optional[Tuple[float, ...]]
    finger_acceleration_limit: Optional[float]  # per finger joint (m/s^2 or rad/s^2)
    gripper: GripperSpec
    urdf_files: Tuple[str, ...] = ()  # the user's URDF files ``urdf`` was composed from (messages name them)

    @property
    def opening_configuration(self) -> Dict[str, float]:
        """Finger joint values with the gripper open."""
        return {f.name: f.open for f in self.gripper.finger_joints}


@dataclass(frozen=True)
class RobotInfo:
    """A described robot's facts as the planner, grasps and execution read them (one per description)."""

    name: str
    urdf: str  # the robot's URDF (with the gripper where the description mounts one)
    hand_link: str
    finger_links: tuple
    finger_joints: tuple
    arm_joints: tuple
    arm_dof: int
    ready: tuple  # the start configuration: arm start, then every finger open (URDF joint order)
    finger_open: float  # joint value of every finger joint with the gripper open
    finger_closed: float  # ... and closed on nothing
    pad_depth: float  # m from the hand link's origin to the grasp frame's (the pad centre)
    max_opening: float  # m between the pads, open
    pad_length: float  # m of finger along the approach axis that touches
    pad_width: float  # m across the finger
    grasp_frame: np.ndarray  # 4x4 in the hand link: z approach, y closing, origin between the pads
    arm_velocity_limits: Optional[tuple]  # rad/s; None: the URDF's
    arm_acceleration_limits: tuple  # rad/s^2
    arm_jerk_limits: Optional[tuple]  # rad/s^3 (stated for controllers; not enforced)
    finger_acceleration_limit: float  # m/s^2 or rad/s^2
    grip_force: float = 0.0  # N each pad presses with when the gripper squeezes (description's gripper.force)
    grip_speed: float = 0.0  # m/s each finger closes at (gripper.speed)
    pad_friction: float = 0.0  # Coulomb coefficient of the pads (gripper.pad.friction)

    @classmethod
    def from_description(cls, desc: RobotDescription) -> "RobotInfo":
        g = desc.gripper
        acceleration = desc.acceleration_limits or (DEFAULT_ACCELERATION,) * len(desc.arm_joints)
        return cls(
            name=desc.name,
            urdf=desc.urdf,
            hand_link=g.hand_link,
            finger_links=tuple(g.finger_links),
            finger_joints=tuple(f.name for f in g.finger_joints),
            arm_joints=tuple(desc.arm_joints),
            arm_dof=len(desc.arm_joints),
            ready=tuple(desc.start) + tuple(f.open for f in g.finger_joints),
            finger_open=g.finger_joints[0].open,
            finger_closed=g.finger_joints[0].closed,
            pad_depth=float(np.linalg.norm(g.grasp_frame[:3, 3])),
            max_opening=float(g.max_opening),
            pad_length=float(g.pad_length),
            pad_width=float(g.pad_width),
            grasp_frame=np.array(g.grasp_frame),
            arm_velocity_limits=desc.velocity_limits,
            arm_acceleration_limits=tuple(acceleration),
            arm_jerk_limits=desc.jerk_limits,
            finger_acceleration_limit=float(desc.finger_acceleration_limit or DEFAULT_FINGER_ACCELERATION),
            grip_force=float(g.force),
            grip_speed=float(g.speed),
            pad_friction=float(g.pad_friction),
        )

    @property
    def key(self) -> tuple:
        """What identifies the gripper in caches (the dataclass holds an array, so it does not hash)."""
        return (
            self.name,
            self.urdf,
            self.hand_link,
            self.finger_joints,
            self.finger_open,
            self.max_opening,
            tuple(np.round(self.grasp_frame, 9).ravel()),
        )

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
DEFAULT_ACCELERATION = 3.0  # rad/s^2 per arm joint
DEFAULT_FINGER_ACCELERATION = 1.0  # m/s^2 (or rad/s^2) per finger joint


# --- physical ranges a description's values must lie in (beyond them a value is a typo or garbage) -----
VELOCITY = (0.01, 50.0)  # rad/s (m/s for a prismatic joint)
ACCELERATION = (0.01, 1000.0)  # rad/s^2
JERK = (0.1, 1e6)  # rad/s^3
FINGER_ACCELERATION = (0.001, 100.0)  # m/s^2 (or rad/s^2)
PAD = (0.001, 0.2)  # m: a pad's length and its width
MAX_OPENING = 0.5  # m between the pads, open
GRIP_FORCE = 10000.0  # N a gripper's pad presses with, at most
GRIP_SPEED = 5.0  # m/s a finger closes at, at most
PAD_FRICTION = 10.0  # a pad's Coulomb coefficient, at most
BODY_POINTS = (1, 1000)  # per link
MAX_OFFSET = 100.0  # m: a position in a description (base, mount, grasp frame)
MAX_ANGLE = 4 * np.pi  # rad: roll, pitch, yaw
MAX_JOINT_VALUE = 100.0  # rad or m: start and finger values (the URDF's limits bound them further)
LIMITS = {"velocity": VELOCITY, "acceleration": ACCELERATION, "jerk": JERK}


def read_pose(r: FieldReader, value, where: str) -> np.ndarray:
    """A ``{xyz, rpy}`` table as a 4x4 pose."""
    t = r.table(value, where, known=("xyz", "rpy"))
    xyz = r.get(t, "xyz", where, r.vector, n=3, lo=-MAX_OFFSET, hi=MAX_OFFSET)
    rpy = r.get(t, "rpy", where, r.vector, n=3, lo=-MAX_ANGLE, hi=MAX_ANGLE)
    if xyz is None or rpy is None:
        r.skip()
    return pose_matrix(xyz, rpy)


def resolve_path(text: str, relative_to: str) -> str:
    """``pybullet_data:REL``, ``assets:REL``, absolute, or relative to ``relative_to``'s folder."""
    if text.startswith("pybullet_data:"):
        import pybullet_data  # only when a description asks for its files

        return os.path.join(pybullet_data.getDataPath(), text[len("pybullet_data:") :])
    if text.startswith("assets:"):
        return os.path.join(assets_dir(), text[len("assets:") :])
    return text if os.path.isabs(text) else os.path.join(os.path.dirname(os.path.abspath(relative_to)), text)


# --- the file -------------------------------------------------------------------------------------
TOP_KEYS = (
    "name",
    "description",
    "urdf",
    "package_dirs",
    "base",
    "arm_joints",
    "start",
    "body_points_per_link",
    "skip_collision",
    "mount",
    "limits",
    "gripper",
)


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
        raise FileNotFoundError(
            f"no shipped robot {name!r}; shipped: {names} (short names: "
            f"{sorted(n.split('_')[0] for n in names)}; or give a .toml file)"
        )
    return short[0]


def description_path(name_or_file: str) -> str:
    """A shipped robot's file by name (or short name, ``shipped_name``), or the file given."""
    if os.path.sep not in name_or_file and not name_or_file.endswith(".toml"):
        return os.path.join(assets_dir(), ROBOTS_FOLDER, shipped_name(name_or_file) + ".toml")
    if not os.path.isfile(name_or_file):
        raise FileNotFoundError(f"robot description not found: {name_or_file}")
    return name_or_file


def load_description(name_or_file: str) -> RobotDescription:
    """Read and check the form of a description (every problem at once, as one ``InputError``)."""
    desc, problems = parse_description(name_or_file)
    if problems:
        raise InputError(problems=problems)
    return desc


def _read_toml(path: str) -> Tuple[Optional[dict], List[Problem]]:
    try:
        with open(path, "rb") as f:
            return tomllib.load(f), []
    except tomllib.TOMLDecodeError as exc:
        return None, [Problem("", f"not valid TOML: {exc}", path)]
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:  # e.g. an integer of 5,000 digits
        return None, [Problem("", f"not readable TOML: {type(exc).__name__}: {str(exc)[:200]}", path)]
    except IsADirectoryError:
        return None, [Problem("", "expected a robot description (.toml), got a folder", path)]


def parse_description(name_or_file: str) -> Tuple[Optional[RobotDescription], List[Problem]]:
    """The description as far as it can be read (defaults where a value is wrong) and every problem
    of its form; None when the file is not TOML at all."""
    path = description_path(name_or_file)
    data, problems = _read_toml(path)
    if data is None:
        return None, problems
    r = FieldReader(path)
    r.table(data, "", known=TOP_KEYS)
    name = r.get(data, "name", "", r.text, default="?")
    description = r.get(data, "description", "", r.text, default="", required=False, allow_empty=True)
    package_dirs = r.get(data, "package_dirs", "", _paths, default=(), required=False, r=r, source=path)
    base = r.get(data, "base", "", lambda v, w: read_pose(r, v, w), default=np.eye(4), required=False)
    arm = r.get(data, "arm_joints", "", _names, default=(), r=r)
    start = r.get(data, "start", "", r.vector, n=len(arm) if arm else None, lo=-MAX_JOINT_VALUE, hi=MAX_JOINT_VALUE)
    per_link = r.get(
        data, "body_points_per_link", "", r.integer, default=20, required=False, lo=BODY_POINTS[0], hi=BODY_POINTS[1]
    )
    skip = r.get(data, "skip_collision", "", _pairs, default=(), required=False, r=r)
    limits = _limits(r, r.get(data, "limits", "", r.table, default={}, required=False), len(arm))
    gripper = _gripper(r, r.get(data, "gripper", "", r.table, default={}))
    urdf, urdf_files = _urdf(r, data, path)
    desc = RobotDescription(
        name=name,
        description=description,
        source=path,
        urdf=urdf,
        package_dirs=package_dirs,
        base_pose=base,
        arm_joints=tuple(arm),
        start=start or (0.0,) * len(arm),
        body_points_per_link=per_link,
        skip_collision=skip,
        gripper=gripper,
        urdf_files=urdf_files,
        **limits,
    )
    return desc, r.problems


def _paths(value, where: str, r: FieldReader, source: str) -> Tuple[str, ...]:
    return tuple(resolve_path(r.text(p, f), source) for f, p in r.items(value, where))


def _names(value, where: str, r: FieldReader) -> Tuple[str, ...]:
    names = tuple(r.text(v, f) for f, v in r.items(value, where))
    if len(set(names)) != len(names):
        r.fail(where, f"a joint named more than once: {list(names)}")
    return names


def _pairs(value, where: str, r: FieldReader) -> Tuple[Tuple[str, str], ...]:
    pairs = []
    for f, p in r.items(value, where):
        if not isinstance(p, list) or len(p) != 2:
            r.fail(f, f"expected a pair of link names, got {p!r:.60}")
        pairs.append((r.text(p[0], f"{f}[0]"), r.text(p[1], f"{f}[1]")))
    return tuple(pairs)


def _limits(r: FieldReader, limits: dict, arm_dof: int) -> dict:
    r.table(limits, "limits", known=("velocity", "acceleration", "jerk", "finger_acceleration"))
    out = {
        f"{k}_limits": r.get(
            limits,
            k,
            "limits",
            r.vector,
            required=False,
            n=arm_dof or None,
            lo=lo,
            hi=hi,
            unit="rad/s" if k == "velocity" else "",
        )
        for k, (lo, hi) in LIMITS.items()
    }
    out["finger_acceleration_limit"] = r.get(
        limits,
        "finger_acceleration",
        "limits",
        r.number,
        required=False,
        lo=FINGER_ACCELERATION[0],
        hi=FINGER_ACCELERATION[1],
    )
    return out


def _urdf(r: FieldReader, data: dict, path: str) -> Tuple[str, Tuple[str, ...]]:
    """(the URDF to load, the user's URDF files it comes from); the gripper's composed on where
    the description mounts one. Each file must be a well-formed URDF."""
    text = r.get(data, "urdf", "", r.text, default="")
    if not text:
        return "", ()
    urdf = resolve_path(text, path)
    if not os.path.isfile(urdf):
        r.note("urdf", f"file not found: {urdf}")
        return urdf, (urdf,)
    arm = r.attempt(read_urdf, r, urdf, "urdf")
    mount = r.get(data, "mount", "", r.table, required=False, known=("urdf", "parent_link", "xyz", "rpy"))
    if mount is None or arm is None:
        return urdf, (urdf,)
    with r.part():
        gripper_text = r.get(mount, "urdf", "mount", r.text, default="")
        parent = r.get(mount, "parent_link", "mount", r.text, default="")
        xyz = r.get(
            mount, "xyz", "mount", r.vector, default=(0.0, 0.0, 0.0), required=False, n=3, lo=-MAX_OFFSET, hi=MAX_OFFSET
        )
        rpy = r.get(
            mount, "rpy", "mount", r.vector, default=(0.0, 0.0, 0.0), required=False, n=3, lo=-MAX_ANGLE, hi=MAX_ANGLE
        )
        gripper_urdf = resolve_path(gripper_text, path) if gripper_text else ""
        if not os.path.isfile(gripper_urdf):
            r.fail("mount.urdf", f"file not found: {gripper_urdf or '(none given)'}")
        hand = read_urdf(r, gripper_urdf, "mount.urdf")
        return compose_mount(r, arm, urdf, hand, gripper_urdf, parent, pose_matrix(xyz, rpy), path), (
            urdf,
            gripper_urdf,
        )
    return urdf, (urdf,)


def _gripper(r: FieldReader, g: dict) -> GripperSpec:
    w = "gripper"
    r.table(
        g,
        w,
        known=("hand_link", "finger_links", "finger_joints", "max_opening", "pad", "grasp_frame", "force", "speed"),
    )
    hand = r.get(g, "hand_link", w, r.text, default="")
    links = r.get(g, "finger_links", w, lambda v, f: tuple(r.text(x, fx) for fx, x in r.items(v, f)), default=())
    joints = []
    for f, j in r.get(g, "finger_joints", w, r.items, default=[]):
        joints.append(r.attempt(_finger_joint, r, j, f))
    joints = tuple(j for j in joints if j is not None)
    if not joints:
        r.note(f"{w}.finger_joints", "at least one finger joint is needed")
    elif len({f.open for f in joints}) != 1 or len({f.closed for f in joints}) != 1:  # one command moves every finger
        r.note(
            f"{w}.finger_joints",
            "every finger joint needs the same open and the same closed value, got open "
            f"{sorted({f.open for f in joints})}, closed {sorted({f.closed for f in joints})}",
        )
    opening = r.get(g, "max_opening", w, r.number, default=0.0, lo=0.0, hi=MAX_OPENING, low_open=True, unit="m")
    pad = r.get(g, "pad", w, r.table, default={}, known=("length", "width", "friction"))
    pad_length = r.get(pad, "length", f"{w}.pad", r.number, default=0.0, lo=PAD[0], hi=PAD[1], unit="m") if pad else 0.0
    pad_width = r.get(pad, "width", f"{w}.pad", r.number, default=0.0, lo=PAD[0], hi=PAD[1], unit="m") if pad else 0.0
    frame = r.get(g, "grasp_frame", w, lambda v, f: read_pose(r, v, f), default=np.eye(4))
    grip = dict(
        force=r.get(
            g, "force", w, r.number, default=DEFAULT_GRIP_FORCE, required=False, hi=GRIP_FORCE, positive=True, unit="N"
        ),
        speed=r.get(
            g,
            "speed",
            w,
            r.number,
            default=DEFAULT_GRIP_SPEED,
            required=False,
            hi=GRIP_SPEED,
            positive=True,
            unit="m/s",
        ),
        pad_friction=r.get(
            pad,
            "friction",
            f"{w}.pad",
            r.number,
            default=DEFAULT_PAD_FRICTION,
            required=False,
            hi=PAD_FRICTION,
            positive=True,
        ),
    )
    return GripperSpec(hand, links, joints, opening, pad_length, pad_width, frame, **grip)


def _finger_joint(r: FieldReader, j, where: str) -> FingerJoint:
    t = r.table(j, where, known=("name", "open", "closed"))
    bounds = dict(lo=-MAX_JOINT_VALUE, hi=MAX_JOINT_VALUE)
    return FingerJoint(
        r.get(t, "name", where, r.text, default=""),
        r.get(t, "open", where, r.number, default=0.0, **bounds),
        r.get(t, "closed", where, r.number, default=0.0, **bounds),
    )
