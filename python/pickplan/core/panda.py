"""The Franka Emika Panda's facts as pickplan's Panda-specific code names them, read from its
description file ``assets/robots/panda.toml``, the one place they are written.

Pure Python (no native module): scene generation and PyBullet execution read these without
building the robot model. ``pickplan.core.robots.panda()`` builds the kinematic model from them.
"""

from __future__ import annotations

import numpy as np

from pickplan.core.description import RobotInfo, load_description

PANDA_DESCRIPTION = load_description("panda")
PANDA = RobotInfo.from_description(PANDA_DESCRIPTION)

#: +pi/2 about z: the YCB files' gripper frame (closing along x) -> panda_hand (closing along y).
YCB_TO_HAND = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])


def panda_urdf_path() -> str:
    """The Panda URDF shipped in pybullet_data."""
    return PANDA_DESCRIPTION.urdf
