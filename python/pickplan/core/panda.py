"""The Franka Emika Panda's facts as pickplan's Panda-specific code names them, read from its
description file ``assets/robots/panda.toml``, the one place they are written.

Pure Python (no native module): scene generation and PyBullet execution read these without
building the robot model. ``pickplan.core.robots.panda()`` builds the kinematic model from them.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickplan.core.description import RobotDescription, load_description


@dataclass(frozen=True)
class PandaInfo:
    hand_link: str
    finger_links: tuple
    finger_joints: tuple
    arm_dof: int
    ready: tuple        # a comfortable start configuration above the table (fingers open)
    finger_open: float  # m per finger joint with the hand open
    pad_depth: float    # m along the hand's +z: centre of the finger pads (the YCB README's grasp point)
    max_opening: float  # m between the pads, open
    # Joint-space limits of the arm (Franka Emika's datasheet, in panda.toml). Velocity limits are read
    # from the URDF instead (``Robot.velocity_limits``: the datasheet's values).
    arm_acceleration_limits: tuple       # rad/s^2
    arm_jerk_limits: tuple               # rad/s^3
    finger_acceleration_limit: float     # m/s^2 (the datasheet gives none: see panda.toml)

    @classmethod
    def from_description(cls, desc: RobotDescription) -> "PandaInfo":
        g = desc.gripper
        fingers = tuple(f.open for f in g.finger_joints)
        return cls(hand_link=g.hand_link, finger_links=tuple(g.finger_links),
                   finger_joints=tuple(f.name for f in g.finger_joints), arm_dof=len(desc.arm_joints),
                   ready=tuple(desc.start) + fingers, finger_open=fingers[0], pad_depth=float(g.grasp_frame[2, 3]),
                   max_opening=float(g.max_opening),
                   arm_acceleration_limits=tuple(desc.acceleration_limits), arm_jerk_limits=tuple(desc.jerk_limits),
                   finger_acceleration_limit=float(desc.finger_acceleration_limit))


PANDA_DESCRIPTION = load_description("panda")
PANDA = PandaInfo.from_description(PANDA_DESCRIPTION)

#: +pi/2 about z: the YCB files' gripper frame (closing along x) -> panda_hand (closing along y).
YCB_TO_HAND = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                        [0.0, 0.0, 0.0, 1.0]])


def panda_urdf_path() -> str:
    """The Panda URDF shipped in pybullet_data."""
    return PANDA_DESCRIPTION.urdf
