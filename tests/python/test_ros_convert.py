"""ROS messages -> pickplan's arrays (pickplan.ros.convert) on the real message classes, against
independent truth (the pinhole model in OpenCV's pixel convention, scipy's rotations); and the library
without the ros extra: it imports, and the node's commands name the extra."""

import subprocess
import sys

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("rclpy", reason="the ros extra is not installed (make install installs it)")

from sensor_msgs.msg import CameraInfo, Image, JointState  # noqa: E402

from pickplan.core.observation import Observation  # noqa: E402
from pickplan.perception.field import backproject  # noqa: E402
from pickplan.ros import convert  # noqa: E402


def _depth(seed=0):
    d = np.random.default_rng(seed).uniform(0.3, 2.5, (6, 9)).astype(np.float32)
    d[1, 2] = np.nan
    return d


@pytest.mark.parametrize("encoding, tol", [("32FC1", 0.0), ("16UC1", 0.0005)])
def test_depth_images_read_back_in_metres_with_no_return_as_nan(encoding, tol):
    d = _depth()
    msg = Image(**convert.image_fields(d, encoding))
    out = convert.depth_image(msg)
    ok = np.isfinite(d)
    np.testing.assert_allclose(out[ok], d[ok], atol=tol)
    assert np.isnan(out[1, 2])


def test_row_padding_and_big_endian_are_read_as_the_fields_say():
    d = _depth(1)
    raw = d.astype(">f4")
    padded = np.zeros((6, 9 * 4 + 12), np.uint8)
    padded[:, :36] = raw.view(np.uint8).reshape(6, 36)
    msg = Image(height=6, width=9, encoding="32FC1", is_bigendian=True, step=48, data=padded.tobytes())
    out = convert.depth_image(msg)
    np.testing.assert_array_equal(out[np.isfinite(d)], d[np.isfinite(d)])
    mm = np.array([[0, 1000], [65535, 250]], "<u2")
    msg = Image(height=2, width=2, encoding="16UC1", step=4, data=mm.tobytes())
    np.testing.assert_allclose(convert.depth_image(msg), [[np.nan, 1.0], [65.535, 0.25]])
    inf = Image(**convert.image_fields(np.ones((2, 2)), "32FC1"))
    inf.data = np.array([np.inf, -np.inf, 0.0, 1.0], "<f4").tobytes()  # REP 118: too far, too near, none
    assert np.isnan(convert.depth_image(inf)).sum() == 3


@pytest.mark.parametrize(
    "change, field",
    [({"encoding": "rgb8"}, "encoding"), ({"step": 10}, "step"), ({"height": 7}, "data"), ({"width": 1}, "height")],
)
def test_a_malformed_image_names_its_field(change, field):
    msg = Image(**convert.image_fields(_depth(), "32FC1"))
    for k, v in change.items():
        setattr(msg, k, v)
    with pytest.raises(convert.MessageError, match=f"cam0.{field}"):
        convert.depth_image(msg, "cam0")


def test_camera_info_intrinsics_follow_opencv_pixel_centres():
    """A point OpenCV projects to the centre of pixel (r, c) is on that pixel's ray in the observation."""
    fx, fy, cx, cy = 520.0, 515.0, 319.5, 239.5
    info = CameraInfo(height=480, width=640, k=[fx, 0, cx, 0, fy, cy, 0, 0, 1])
    K = convert.observation_K(info, (480, 640))
    X = np.array([0.12, -0.07, 1.3])
    c, r = fx * X[0] / X[2] + cx, fy * X[1] / X[2] + cy  # OpenCV: the centre of pixel c is at u = c
    r, c = int(round(r)), int(round(c))
    X = np.array([(c - cx) / fx, (r - cy) / fy, 1.0]) * 1.3  # exactly on that centre's ray
    depth = np.zeros((480, 640))
    depth[r, c] = 1.3
    np.testing.assert_allclose(backproject(depth, K, np.eye(4))[r, c], X, atol=1e-12)
    np.testing.assert_allclose(convert.camera_info_k(K), info.k)
    for field, change in (("width", {"width": 320}), ("k", {"k": [0.0] * 9}), ("binning_x", {"binning_x": 2})):
        bad = CameraInfo(height=480, width=640, k=[fx, 0, cx, 0, fy, cy, 0, 0, 1])
        for k, v in change.items():
            setattr(bad, k, v)
        with pytest.raises(convert.MessageError, match=f"info.{field}"):
            convert.observation_K(bad, (480, 640), "info")


def test_poses_are_scipys_rotations():
    rng = np.random.default_rng(2)
    for _ in range(20):
        R = Rotation.random(random_state=rng)
        t = rng.normal(size=3)
        qx, qy, qz, qw = R.as_quat()
        T = convert.pose_matrix([*t, qx, qy, qz, qw])
        np.testing.assert_allclose(T[:3, :3], R.as_matrix(), atol=1e-12)
        np.testing.assert_allclose(convert.pose_matrix(convert.pose_values(T)), T, atol=1e-9)
        np.testing.assert_allclose(convert.pose_matrix(T.ravel()), T)
    half = np.diag([1.0, -1.0, -1.0, 1.0])  # a half turn: the quaternion's w is 0
    np.testing.assert_allclose(convert.pose_matrix(convert.pose_values(half)), half, atol=1e-12)
    for bad, match in (([0, 0, 0, 0, 0, 0, 2.0], "norm"), ([1.0] * 5, "7 numbers"), ([np.nan] * 7, "finite")):
        with pytest.raises(convert.MessageError, match=match):
            convert.pose_matrix(bad)


def test_joint_states_in_any_order_and_their_errors():
    names = ["a", "b", "f"]
    msg = JointState(name=["x", "b", "a"], position=[9.0, 2.0, 1.0])
    np.testing.assert_array_equal(convert.joint_positions(msg, names, {"f": 0.04}), [1.0, 2.0, 0.04])
    with pytest.raises(convert.MessageError, match="joint f missing"):
        convert.joint_positions(msg, names, {})
    with pytest.raises(convert.MessageError, match="2 positions for 3 joint names"):
        convert.joint_positions(JointState(name=["a", "b", "f"], position=[1.0, 2.0]), names, {})
    with pytest.raises(convert.MessageError, match="joint b is not finite"):
        convert.joint_positions(JointState(name=["a", "b"], position=[1.0, np.nan]), names, {"f": 0.0})


BLOCK_ROS = """
import sys, importlib.abc
class Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('rclpy', 'sensor_msgs', 'std_srvs', 'trajectory_msgs'):
            raise ModuleNotFoundError(name)
sys.meta_path.insert(0, Block())
"""


def test_the_library_imports_without_the_extra_and_the_node_names_it():
    code = (
        BLOCK_ROS
        + """
import pickplan, pickplan.cli.main, pickplan.ros.pipeline, pickplan.ros.convert
from pickplan.cli.main import main
sys.exit(main(['ros', 'serve', '--robot', 'panda']))
"""
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 2, run.stderr
    assert "pip install 'pickplan[ros]'" in run.stderr and "rclpy" in run.stderr, run.stderr


def test_an_observation_from_messages_is_the_observation():
    """Depth and intrinsics through Image/CameraInfo and back give the observation's own arrays."""
    obs_depth = _depth(3)
    K = np.array([[5.0, 0, 4.5], [0, 5.0, 3.0], [0, 0, 1]])  # a real field of view over 9 x 6 px (84 x 62 deg)
    info = CameraInfo(height=6, width=9, k=convert.camera_info_k(K))
    depth = convert.depth_image(Image(**convert.image_fields(obs_depth)))
    mask = np.zeros((6, 9), bool)
    mask[2, 3] = True
    obs = Observation(depth, convert.observation_K(info, depth.shape), np.eye(4), mask)
    np.testing.assert_allclose(obs.K[0], K)
    np.testing.assert_array_equal(np.isnan(obs.depth[0]), np.isnan(obs_depth))
