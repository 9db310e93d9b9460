"""Whether the ``ros`` extra (or a sourced ROS 2) is importable, and the transport the tests use.

``require_ros()`` raises ``RosExtraMissing`` (an ImportError: the CLI's exit code 2) naming the
extra and every module that is missing; nothing here imports rclpy. ``Transport.shm`` points Fast
DDS at ``fastdds_shm.xml`` beside this file: shared memory only, so nothing leaves the machine (no
UDP socket is opened at all); both ends of a connection must use it.
"""

from __future__ import annotations

import importlib.util
import os
from typing import MutableMapping

from pickplan.core.settings import Option

EXTRA = "pip install 'pickplan[ros]'"
REQUIRED = (
    "rclpy",
    "sensor_msgs",
    "geometry_msgs",
    "trajectory_msgs",
    "std_srvs",
    "visualization_msgs",
    "diagnostic_msgs",
)
SHM_PROFILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fastdds_shm.xml")
FAST_DDS = "rmw_fastrtps_cpp"


class RosExtraMissing(ImportError):
    """rclpy or a message package cannot be imported."""


class Transport(Option):
    """How the node's DDS participant talks: ROS's default (UDP, discovery on the subnet or as
    ``ROS_AUTOMATIC_DISCOVERY_RANGE`` says), or shared memory only (one machine; Fast DDS)."""

    default = "default"
    shm = "shm"


def available(module: str) -> bool:
    """``module`` can be imported (an optional ROS package: tf2_ros, control_msgs)."""
    try:
        return importlib.util.find_spec(module) is not None
    except (ImportError, ValueError):
        return False


def require_ros() -> None:
    missing = [m for m in REQUIRED if not available(m)]
    if missing:
        raise RosExtraMissing(
            f"the ROS 2 node needs the ros extra ({EXTRA}) or a sourced ROS 2 installation; "
            f"not importable: {', '.join(missing)}"
        )


def configure_transport(transport, env: MutableMapping[str, str]) -> None:
    """Set ``env`` (before rclpy starts) for ``transport``. Shared memory: the Fast DDS profile, and
    no ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (its LOCALHOST setting makes rmw add UDP on loopback)."""
    transport = Transport.parse(transport, "transport")
    if transport is Transport.default:
        return
    rmw = env.get("RMW_IMPLEMENTATION", FAST_DDS)
    if rmw != FAST_DDS:
        raise ValueError(f"transport shm: needs RMW_IMPLEMENTATION={FAST_DDS} (a Fast DDS profile), got {rmw}")
    env["FASTDDS_DEFAULT_PROFILES_FILE"] = SHM_PROFILE
    env.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
    env.pop("ROS_LOCALHOST_ONLY", None)
