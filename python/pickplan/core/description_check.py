"""Check a robot description against the robot it describes, naming every problem.

``description.parse_description`` checks the file's form; ``model_problems`` checks it against the
loaded robot model (``robots.check_description`` and ``robots.load_robot`` run both: one path for
every command): every joint named is in the URDF and movable, finger joints are prismatic or
revolute, values lie within the joint limits, the limits themselves are physical (finite, a revolute
joint within +-4 pi, a prismatic one within +-10 m; velocities where the description gives none, the
URDF's, within ``description.VELOCITY``), every movable joint is an arm or finger joint, and the
grasp frame sits between the finger pads with the gripper open, its y axis across the gap the pads
leave (within ``CENTRE_TOL`` of the middle, the gap within ``GAP_TOL`` of ``max_opening``), its
origin within the pads' extent along the approach axis, its z axis the hand link's +z (the goal
set's pre-grasp backs off along it), and the URDF orders the arm joints before the finger joints
(configurations are laid out so). ``skip_collision`` may pair a link with "table".
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Tuple

import numpy as np

from pickplan.core.description import MAX_ANGLE, VELOCITY, RobotDescription
from pickplan.core.fields import FieldReader
from pickplan.core.urdf_xml import joint_efforts, joint_types

CENTRE_TOL = 0.003  # m: the grasp origin from the middle of the gap between the pads
GAP_TOL = 0.006  # m: the measured gap from max_opening
FINGER_TYPES = ("prismatic", "revolute")
MAX_TRAVEL = {"revolute": MAX_ANGLE, "prismatic": 10.0}  # rad, m: a joint limit beyond is not a real joint
EFFORT = (0.1, 1e5)  # N m (N): the arm's motors in execution take the URDF's effort limits
TABLE = "table"  # skip_collision may pair a link with the table the robot stands on


def start_configuration(desc: RobotDescription, robot) -> np.ndarray:
    """All joint values: the arm's start, the fingers open, any other joint at 0."""
    q = np.zeros(robot.dof)
    names = robot.joint_names
    for name, value in zip(desc.arm_joints, desc.start):
        if name in names:
            q[names.index(name)] = value
    for f in desc.gripper.finger_joints:
        if f.name in names:
            q[names.index(f.name)] = f.open
    return q


def _pad_gap(desc: RobotDescription, robot, q: np.ndarray) -> Tuple[float, float, Tuple[float, float]]:
    """(centre offset along y, gap width, z range common to both pads) in the grasp frame."""
    g = desc.gripper
    poses = robot.fk(q)
    G = poses[robot.link_index(g.hand_link)] @ g.grasp_frame
    G_inv = np.linalg.inv(G)
    spans = []
    for link in g.finger_links:
        mesh = robot.collision_meshes(link)
        if mesh is None:
            raise ValueError(f"finger link {link!r} has no collision geometry to find its pad with")
        v = np.c_[np.asarray(mesh.vertices), np.ones(len(mesh.vertices))]
        spans.append((G_inv @ poses[robot.link_index(link)] @ v.T).T[:, :3])
    spans.sort(key=lambda p: p[:, 1].mean())  # the finger at -y first
    inner_minus, inner_plus = spans[0][:, 1].max(), spans[-1][:, 1].min()
    z_lo = max(s[:, 2].min() for s in spans)
    z_hi = min(s[:, 2].max() for s in spans)
    return 0.5 * (inner_plus + inner_minus), inner_plus - inner_minus, (z_lo, z_hi)


def model_problems(r: FieldReader, desc: RobotDescription, robot) -> None:
    """Record in ``r`` every problem of ``desc`` against ``robot`` (its kinematic model, a
    ``robots.Robot`` built from ``desc.urdf``)."""
    root = ET.parse(desc.urdf).getroot()
    names, links, types = robot.joint_names, set(robot.link_names), joint_types(root)
    g = desc.gripper
    _joint_problems(r, desc, robot, types)
    for name, effort in joint_efforts(root).items():
        if name in desc.arm_joints and not EFFORT[0] <= _float(effort) <= EFFORT[1]:
            r.note(
                "urdf",
                f"joint {name}'s effort limit {effort!r} is not within [{EFFORT[0]:g}, {EFFORT[1]:g}] "
                f"(N m or N; execution drives the arm with it)",
            )
    others = set(names) - set(desc.arm_joints) - {f.name for f in g.finger_joints}
    if others:
        r.note("arm_joints", f"movable joints that are neither arm_joints nor gripper.finger_joints: {sorted(others)}")
    for what, link in [("gripper.hand_link", g.hand_link)] + [("gripper.finger_links", l) for l in g.finger_links]:
        if link not in links:
            r.note(what, f"{link!r} is not a link of the URDF")
    for a, b in desc.skip_collision:
        for link in (a, b):
            if link not in links and link != TABLE:
                r.note("skip_collision", f"{link!r} is not a link of the URDF")
    if len(g.finger_links) != 2:
        r.note("gripper.finger_links", f"a parallel gripper has 2 fingers, got {len(g.finger_links)}")
    gripper_named = g.hand_link in links and all(l in links for l in g.finger_links) and len(g.finger_links) == 2
    if not gripper_named or not all(types.get(f.name) in FINGER_TYPES for f in g.finger_joints):
        return  # no pads to measure the grasp frame against
    if g.grasp_frame[:3, 2] @ np.array([0.0, 0.0, 1.0]) < 1.0 - 1e-6:
        r.note(
            "gripper.grasp_frame",
            "its z axis (the approach) must be the hand link's +z: the goal set's "
            "pre-grasp backs off along the hand's z (turn the hand link, or mount a frame that is)",
        )
    if [j for j in names if j in desc.arm_joints or j in {f.name for f in g.finger_joints}] != list(desc.arm_joints) + [
        f.name for f in g.finger_joints
    ] and not others:
        r.note(
            "arm_joints",
            f"configurations are the arm joints then the finger joints (gripper.finger_joints), "
            f"but the URDF orders its movable joints {names}",
        )
    with r.part():
        _grasp_frame_problems(r, desc, robot)


def _float(text) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        return float("nan")


def _joint_problems(r: FieldReader, desc: RobotDescription, robot, types: dict) -> None:
    """Arm and finger joints: movable joints of the URDF with physical limits, values within them."""
    names, lo, hi = robot.joint_names, robot.lower_limits, robot.upper_limits
    for name in desc.arm_joints:
        if name not in names:
            r.note("arm_joints", f"{name!r} is not a movable joint of the URDF")
    for name, value in zip(desc.arm_joints, desc.start):
        if name in names and not lo[names.index(name)] - 1e-9 <= value <= hi[names.index(name)] + 1e-9:
            i = names.index(name)
            r.note("start", f"{name} = {value} outside its limits [{lo[i]:.4g}, {hi[i]:.4g}]")
    for f in desc.gripper.finger_joints:
        if f.name in desc.arm_joints:
            r.note("gripper.finger_joints", f"{f.name!r} is also an arm joint")
        elif types.get(f.name) not in FINGER_TYPES:
            kind = types.get(f.name)
            r.note(
                "gripper.finger_joints",
                f"{f.name!r} "
                + (f"is {kind}, expected prismatic or revolute" if kind else "is not a joint of the URDF"),
            )
        else:
            i = names.index(f.name)
            for what, value in (("open", f.open), ("closed", f.closed)):
                if not lo[i] - 1e-9 <= value <= hi[i] + 1e-9:
                    r.note("gripper.finger_joints", f"{f.name} {what} = {value} outside [{lo[i]:.4g}, {hi[i]:.4g}]")
    for i, name in enumerate(names):
        bound = MAX_TRAVEL.get(types.get(name))
        if bound is not None and not (-bound <= lo[i] <= hi[i] <= bound):
            r.note(
                "urdf",
                f"joint {name}'s limits [{lo[i]:.4g}, {hi[i]:.4g}] are not within "
                f"[{-bound:.4g}, {bound:.4g}] ({types.get(name)}): not a real joint's",
            )
    v = robot.velocity_limits  # the URDF's: the fingers', and the arm's where the description gives none
    from_urdf = [f.name for f in desc.gripper.finger_joints] + (
        list(desc.arm_joints) if desc.velocity_limits is None else []
    )
    for name in from_urdf:
        if name in names and not VELOCITY[0] <= v[names.index(name)] <= VELOCITY[1]:
            field = "urdf" if name not in desc.arm_joints else "limits.velocity"
            r.note(
                field,
                f"the URDF's velocity limit of {name}, {v[names.index(name)]:g}, is outside "
                f"[{VELOCITY[0]:g}, {VELOCITY[1]:g}]"
                + (" (the description gives none)" if field == "limits.velocity" else ""),
            )


def _grasp_frame_problems(r: FieldReader, desc: RobotDescription, robot) -> None:
    g = desc.gripper
    names = robot.joint_names
    q = start_configuration(desc, robot) if all(j in names for j in desc.arm_joints) else np.zeros(robot.dof)
    try:
        centre, gap, (z_lo, z_hi) = _pad_gap(desc, robot, q)
    except ValueError as exc:
        r.fail("gripper.finger_links", str(exc))
    if abs(centre) > CENTRE_TOL:
        r.note(
            "gripper.grasp_frame",
            f"not between the pads at the open width: {1000 * centre:+.1f} mm "
            f"along its y axis from the middle of the gap",
        )
    if abs(gap - g.max_opening) > GAP_TOL:
        r.note(
            "gripper.max_opening",
            f"{g.max_opening} m, but the pads are {gap:.4f} m apart when open "
            f"(or the grasp frame's y axis is not the closing axis)",
        )
    if not z_lo <= 0.0 <= z_hi:
        r.note(
            "gripper.grasp_frame",
            f"its origin is not level with the pads along the approach axis "
            f"(the pads span z in [{1000 * z_lo:.1f}, {1000 * z_hi:.1f}] mm of the grasp frame)",
        )
