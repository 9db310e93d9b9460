"""Check a robot description against the robot it describes, naming every problem.

``load_description`` checks the file's form; this loads the robot (native kinematics) and checks that
the names exist and the geometry is right: every joint named is in the URDF and movable, finger
joints are prismatic or revolute, values lie within the joint limits, every movable joint is an arm or
finger joint, and the grasp frame sits between the finger pads with the gripper open, its y axis
across the gap the pads leave (within ``CENTRE_TOL`` of the middle, the gap within ``GAP_TOL`` of
``max_opening``), its origin within the pads' extent along the approach axis, its z axis the hand
link's +z (the goal set's pre-grasp backs off along it), and the URDF orders the arm joints before the
finger joints (configurations are laid out so). ``skip_collision`` may pair a link with "table".
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import List, Optional, Tuple

import numpy as np

from pickplan.core.description import RobotDescription, parse_description
from pickplan.core.robots import Robot

CENTRE_TOL = 0.003   # m: the grasp origin from the middle of the gap between the pads
GAP_TOL = 0.006      # m: the measured gap from max_opening
FINGER_TYPES = ("prismatic", "revolute")
TABLE = "table"   # skip_collision may pair a link with the table the robot stands on


def _joint_types(urdf: str) -> dict:
    return {j.get("name"): j.get("type") for j in ET.parse(urdf).getroot().iter("joint")}


def robot_for(desc: RobotDescription) -> Robot:
    """The kinematic model a description names, at its base pose."""
    return Robot.from_urdf(desc.urdf, desc.package_dirs).with_base(desc.base_pose)


def start_configuration(desc: RobotDescription, robot: Robot) -> np.ndarray:
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


def _pad_gap(desc: RobotDescription, robot: Robot, q: np.ndarray) -> Tuple[float, float, Tuple[float, float]]:
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


def check_description(name_or_file: str) -> Tuple[Optional[RobotDescription], List[str]]:
    """(the description, []) when it is usable, else (None or the description, every problem found)."""
    desc, problems = parse_description(name_or_file)
    if desc is None or not desc.urdf or any(p.startswith(("urdf:", "mount.")) for p in problems):
        return desc, problems  # no robot to check the rest against
    try:
        robot = robot_for(desc)
    except (ValueError, RuntimeError, FileNotFoundError) as exc:
        return desc, problems + [f"urdf: {exc}"]
    names, links, types = robot.joint_names, set(robot.link_names), _joint_types(desc.urdf)
    lo, hi = robot.lower_limits, robot.upper_limits
    g = desc.gripper
    for name, value in zip(desc.arm_joints, desc.start):
        if name not in names:
            problems.append(f"arm_joints: {name!r} is not a movable joint of the URDF")
        elif not lo[names.index(name)] - 1e-9 <= value <= hi[names.index(name)] + 1e-9:
            i = names.index(name)
            problems.append(f"start: {name} = {value} outside its limits [{lo[i]:.4g}, {hi[i]:.4g}]")
    for f in g.finger_joints:
        if f.name in desc.arm_joints:
            problems.append(f"gripper.finger_joints: {f.name!r} is also an arm joint")
            continue
        if types.get(f.name) not in FINGER_TYPES:
            kind = types.get(f.name)
            problems.append(f"gripper.finger_joints: {f.name!r} " + (f"is {kind}, expected prismatic or revolute"
                                                                       if kind else "is not a joint of the URDF"))
            continue
        i = names.index(f.name)
        for what, value in (("open", f.open), ("closed", f.closed)):
            if not lo[i] - 1e-9 <= value <= hi[i] + 1e-9:
                problems.append(f"gripper.finger_joints: {f.name} {what} = {value} outside [{lo[i]:.4g}, {hi[i]:.4g}]")
    others = set(names) - set(desc.arm_joints) - {f.name for f in g.finger_joints}
    if others:
        problems.append(f"movable joints that are neither arm_joints nor gripper.finger_joints: {sorted(others)}")
    for what, link in [("gripper.hand_link", g.hand_link)] + [("gripper.finger_links", l) for l in g.finger_links]:
        if link not in links:
            problems.append(f"{what}: {link!r} is not a link of the URDF")
    for a, b in desc.skip_collision:
        for link in (a, b):
            if link not in links and link != TABLE:
                problems.append(f"skip_collision: {link!r} is not a link of the URDF")
    if len(g.finger_links) != 2:
        problems.append(f"gripper.finger_links: a parallel gripper has 2 fingers, got {len(g.finger_links)}")
    gripper_named = g.hand_link in links and all(l in links for l in g.finger_links) and len(g.finger_links) == 2
    if not gripper_named or not all(types.get(f.name) in FINGER_TYPES for f in g.finger_joints):
        return desc, problems  # no pads to measure the grasp frame against
    if g.grasp_frame[:3, 2] @ np.array([0.0, 0.0, 1.0]) < 1.0 - 1e-6:
        problems.append("gripper.grasp_frame: its z axis (the approach) must be the hand link's +z: the goal set's "
                        "pre-grasp backs off along the hand's z (turn the hand link, or mount a frame that is)")
    if [j for j in names if j in desc.arm_joints or j in {f.name for f in g.finger_joints}] != \
            list(desc.arm_joints) + [f.name for f in g.finger_joints] and not others:
        problems.append(f"arm_joints, gripper.finger_joints: configurations are the arm joints then the finger "
                        f"joints, but the URDF orders its movable joints {names}")
    q = start_configuration(desc, robot) if all(j in names for j in desc.arm_joints) else np.zeros(robot.dof)
    centre, gap, (z_lo, z_hi) = _pad_gap(desc, robot, q)
    if abs(centre) > CENTRE_TOL:
        problems.append(f"gripper.grasp_frame: not between the pads at the open width: {1000 * centre:+.1f} mm "
                        f"along its y axis from the middle of the gap")
    if abs(gap - g.max_opening) > GAP_TOL:
        problems.append(f"gripper.max_opening: {g.max_opening} m, but the pads are {gap:.4f} m apart when open "
                        f"(or the grasp frame's y axis is not the closing axis)")
    if not z_lo <= 0.0 <= z_hi:
        problems.append(f"gripper.grasp_frame: its origin is not level with the pads along the approach axis "
                        f"(the pads span z in [{1000 * z_lo:.1f}, {1000 * z_hi:.1f}] mm of the grasp frame)")
    return desc, problems
