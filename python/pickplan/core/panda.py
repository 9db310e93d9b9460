"""Every fact pickplan uses about the Franka Emika Panda and its hand, in one place.

Pure Python (no native module): scene generation and PyBullet execution read these without
building the robot model. ``pickplan.core.robots.panda()`` builds the kinematic model from them.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PandaInfo:
    hand_link: str = "panda_hand"
    finger_links: tuple = ("panda_leftfinger", "panda_rightfinger")
    finger_joints: tuple = ("panda_finger_joint1", "panda_finger_joint2")
    arm_dof: int = 7
    # A comfortable start configuration above the table (fingers open).
    ready: tuple = (0.0, -1.285, 0.0, -2.356, 0.0, 1.571, 0.785, 0.04, 0.04)
    finger_open: float = 0.04   # m per finger joint: the pads are 2 x 0.04 apart when open
    pad_depth: float = 0.1034   # m along the hand's +z: centre of the finger pads (the YCB README's grasp point)
    # Joint-space limits of the arm, Franka Emika's datasheet ("Robot and interface specifications",
    # Franka Control Interface documentation, Panda). Velocity limits are read from the URDF instead
    # (``Robot.velocity_limits``: 2.175 rad/s joints 1-4, 2.61 rad/s joints 5-7, the datasheet's values).
    arm_acceleration_limits: tuple = (15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0)              # rad/s^2
    arm_jerk_limits: tuple = (7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0)     # rad/s^3
    # The datasheet gives no finger acceleration; this reaches the URDF's 0.2 m/s finger speed in 0.2 s.
    finger_acceleration_limit: float = 1.0                                                   # m/s^2


PANDA = PandaInfo()

#: +pi/2 about z: the YCB files' gripper frame (closing along x) -> panda_hand (closing along y).
YCB_TO_HAND = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                        [0.0, 0.0, 0.0, 1.0]])


def panda_urdf_path() -> str:
    """The Panda URDF shipped in pybullet_data."""
    import pybullet_data  # the URDF's package: imported only when the path is asked for

    return os.path.join(pybullet_data.getDataPath(), "franka_panda", "panda.urdf")
