"""ROS messages <-> pickplan's arrays, every field checked; no ROS import (messages are read by
their fields, so the checks run and are tested without the extra).

Conventions:
- depth images (REP 118): ``16UC1`` (also ``mono16``) millimetres, 0 = no return; ``32FC1`` metres,
  NaN, +-Inf and 0 = no return; rows ``step`` bytes apart, byte order from ``is_bigendian``. Depth is
  along the optical axis of the camera's optical frame (z forward, x right, y down), as in
  ``core.observation``. Images must be rectified (``image_rect``): ``CameraInfo.k`` is used, no
  distortion model.
- ``CameraInfo.k`` puts pixel centres at integer coordinates (OpenCV, ROS); ``Observation.K`` at
  half-integers (pixel (r, c) covers [c, c + 1)): cx and cy differ by 0.5 (``observation_K``,
  ``camera_info_k``).
- poses are given as 7 numbers (x, y, z, qx, qy, qz, qw: the frame's origin and orientation in the
  planning frame) or 16 (a row-major 4 x 4 matrix).
"""

from __future__ import annotations

import math
from typing import Dict, Sequence, Tuple

import numpy as np

from pickplan.core.errors import InputError
from pickplan.core.timing import TimedTrajectory

DEPTH_ENCODINGS: Dict[str, Tuple[type, float]] = {
    "16UC1": (np.uint16, 0.001),
    "mono16": (np.uint16, 0.001),
    "32FC1": (np.float32, 1.0),
}
RIGID_TOL = 1e-4


class MessageError(InputError):
    """A message that cannot be used: ``field`` names the topic and the field at fault."""

    def __init__(self, where: str, message: str):
        super().__init__(message, field=where)


def depth_image(msg, where: str = "image") -> np.ndarray:
    """(H, W) float32 metres from a ``sensor_msgs/Image``; NaN where there is no return."""
    encoding = str(msg.encoding)
    if encoding not in DEPTH_ENCODINGS:
        raise MessageError(f"{where}.encoding", f"{encoding!r} is not a depth encoding ({', '.join(DEPTH_ENCODINGS)})")
    dtype, scale = DEPTH_ENCODINGS[encoding]
    H, W, step = int(msg.height), int(msg.width), int(msg.step)
    item = np.dtype(dtype).itemsize
    if H < 2 or W < 2:
        raise MessageError(f"{where}.height", f"expected an image of at least 2 x 2 pixels, got {W} x {H}")
    if step < W * item:
        raise MessageError(f"{where}.step", f"{step} bytes per row is less than width {W} x {item} bytes")
    try:
        data = np.frombuffer(msg.data, np.uint8)  # rclpy: an array.array of bytes, no copy
    except TypeError:
        data = np.asarray(msg.data, np.uint8)
    if len(data) != step * H:
        raise MessageError(f"{where}.data", f"{len(data)} bytes, but height {H} x step {step} = {step * H}")
    rows = data.reshape(H, step)[:, : W * item]
    order = ">" if msg.is_bigendian else "<"
    depth = rows.view(np.dtype(dtype).newbyteorder(order)).astype(np.float32) * np.float32(scale)
    depth[~np.isfinite(depth) | (depth <= 0)] = np.nan
    return depth


def observation_K(info, shape: Tuple[int, int], where: str = "camera_info") -> np.ndarray:
    """``Observation.K`` (pixel centres at half-integers) from a ``sensor_msgs/CameraInfo`` of an
    image of ``shape`` (H, W)."""
    k = np.asarray(info.k, float)
    if k.shape != (9,) or not np.all(np.isfinite(k)):
        raise MessageError(f"{where}.k", f"expected 9 finite numbers, got {list(info.k)}")
    K = k.reshape(3, 3)
    if not (K[0, 0] > 0 and K[1, 1] > 0 and K[1, 0] == 0 and np.allclose(K[2], [0, 0, 1])):
        raise MessageError(f"{where}.k", f"expected [fx, s, cx, 0, fy, cy, 0, 0, 1] with fx, fy > 0, got {k.tolist()}")
    H, W = shape
    if (int(info.height), int(info.width)) != (H, W):
        raise MessageError(f"{where}.width", f"camera info is {info.width} x {info.height} but the image is {W} x {H}")
    if max(int(info.binning_x), 1) != 1 or max(int(info.binning_y), 1) != 1:
        raise MessageError(f"{where}.binning_x", "binned images are not supported (binning_x, binning_y: 0 or 1)")
    roi = info.roi
    if int(roi.width) not in (0, W) or int(roi.height) not in (0, H) or int(roi.x_offset) or int(roi.y_offset):
        raise MessageError(f"{where}.roi", "a region of interest is not supported (roi: all zero or the full image)")
    K = K.copy()
    K[0, 2] += 0.5
    K[1, 2] += 0.5
    return K


def camera_info_k(K: np.ndarray) -> list:
    """``CameraInfo.k`` (9 numbers, ROS's pixel centres) from an ``Observation.K``."""
    k = np.array(K, float).reshape(3, 3)
    k[0, 2] -= 0.5
    k[1, 2] -= 0.5
    return k.ravel().tolist()


def pose_matrix(values: Sequence[float], where: str = "pose") -> np.ndarray:
    """A 4 x 4 rigid transform from 7 numbers (x y z qx qy qz qw) or 16 (row-major)."""
    v = np.asarray(list(values), float)
    if not np.all(np.isfinite(v)):
        raise MessageError(where, f"not finite: {v.tolist()}")
    if len(v) == 7:
        q = v[3:]
        norm = np.linalg.norm(q)
        if abs(norm - 1.0) > 1e-3:
            raise MessageError(where, f"quaternion (qx, qy, qz, qw) {q.tolist()} has norm {norm:.4f}, expected 1")
        x, y, z, w = q / norm
        T = np.eye(4)
        T[:3, :3] = [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
        T[:3, 3] = v[:3]
        return T
    if len(v) == 16:
        T = v.reshape(4, 4)
        R = T[:3, :3]
        if (
            np.abs(R @ R.T - np.eye(3)).max() > RIGID_TOL
            or np.linalg.det(R) < 0
            or np.abs(T[3] - [0, 0, 0, 1]).max() > RIGID_TOL
        ):
            raise MessageError(where, "the 4 x 4 matrix is not a rigid transform")
        return T
    raise MessageError(where, f"expected 7 numbers (x y z qx qy qz qw) or 16 (a row-major 4 x 4), got {len(v)}")


def pose_values(T: np.ndarray) -> list:
    """7 numbers (x y z qx qy qz qw) of a rigid transform (``pose_matrix``'s inverse)."""
    R = np.asarray(T, float)[:3, :3]
    w = math.sqrt(max(0.0, 1.0 + np.trace(R))) / 2
    if w > 1e-3:
        q = [(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w]
    else:  # a half turn: the largest diagonal element picks the axis
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(max(0.0, 1.0 + R[i, i] - R[j, j] - R[k, k])) * 2
        q = [0.0, 0.0, 0.0, (R[k, j] - R[j, k]) / s]
        q[i], q[j], q[k] = s / 4, (R[j, i] + R[i, j]) / s, (R[k, i] + R[i, k]) / s
    return list(np.asarray(T, float)[:3, 3]) + list(q)


def joint_positions(
    msg, joint_names: Sequence[str], defaults: Dict[str, float], where: str = "joint_states"
) -> np.ndarray:
    """Positions in ``joint_names`` order from a ``sensor_msgs/JointState`` (its own order, any
    other joints ignored); a joint it lacks takes ``defaults[name]`` (the gripper's, which often
    publishes elsewhere) or is an error."""
    names, positions = list(msg.name), list(msg.position)
    if len(names) != len(positions):
        raise MessageError(f"{where}.position", f"{len(positions)} positions for {len(names)} joint names")
    given = dict(zip(names, positions))
    missing = [j for j in joint_names if j not in given and j not in defaults]
    if missing:
        raise MessageError(f"{where}.name", f"joint {', '.join(missing)} missing (has {', '.join(names) or 'none'})")
    q = np.array([given.get(j, defaults.get(j)) for j in joint_names], float)
    bad = [j for j, v in zip(joint_names, q) if not math.isfinite(v)]
    if bad:
        raise MessageError(f"{where}.position", f"joint {', '.join(bad)} is not finite")
    return q


def point(msg_point, where: str = "point") -> np.ndarray:
    """(3,) from a ``geometry_msgs/Point``, finite."""
    p = np.array([msg_point.x, msg_point.y, msg_point.z], float)
    if not np.all(np.isfinite(p)):
        raise MessageError(where, f"not finite: {p.tolist()}")
    return p


def seconds_to_duration(t: float) -> Tuple[int, int]:
    """(sec, nanosec) of a ``builtin_interfaces/Duration`` for ``t`` >= 0 seconds."""
    ns = int(round(float(t) * 1e9))
    return ns // 1_000_000_000, ns % 1_000_000_000


def image_fields(depth_m: np.ndarray, encoding: str = "32FC1") -> dict:
    """``sensor_msgs/Image`` fields (height, width, encoding, is_bigendian, step, data) of a depth image
    in metres (NaN or 0: no return): what a camera driver publishes, for tests and tools."""
    depth = np.asarray(depth_m, np.float32)
    if encoding not in DEPTH_ENCODINGS:
        raise ValueError(f"encoding: expected one of {', '.join(DEPTH_ENCODINGS)}, got {encoding!r}")
    dtype, scale = DEPTH_ENCODINGS[encoding]
    if dtype is np.uint16:
        mm = np.where(np.isfinite(depth) & (depth > 0), np.round(depth / scale), 0)
        raw = np.clip(mm, 0, 65535).astype("<u2")
    else:
        raw = np.where(np.isfinite(depth) & (depth > 0), depth, np.nan).astype("<f4")
    H, W = raw.shape
    return {
        "height": H,
        "width": W,
        "encoding": encoding,
        "is_bigendian": False,
        "step": W * raw.itemsize,
        "data": raw.tobytes(),
    }


def timed_trajectory(msg, joint_names: Sequence[str], where: str = "trajectory"):
    """A ``TimedTrajectory`` (``core.timing``) in ``joint_names`` order from a ``trajectory_msgs/JointTrajectory``
    with positions, velocities and accelerations at evenly spaced times (as the node publishes)."""
    names = list(msg.joint_names)
    missing = [j for j in joint_names if j not in names]
    if missing:
        raise MessageError(f"{where}.joint_names", f"joint {', '.join(missing)} missing")
    if len(msg.points) < 2:
        raise MessageError(f"{where}.points", f"expected at least 2 points, got {len(msg.points)}")
    index = [names.index(j) for j in joint_names]
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in msg.points])
    arrays = []
    for field in ("positions", "velocities", "accelerations"):
        rows = [list(getattr(p, field)) for p in msg.points]
        if any(len(r) != len(names) for r in rows):
            raise MessageError(f"{where}.points.{field}", f"expected {len(names)} values in every point")
        arrays.append(np.asarray(rows, float)[:, index])
    return TimedTrajectory(t, *arrays, rate=1.0 / (t[1] - t[0]))
