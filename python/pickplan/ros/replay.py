"""An observation (``pickplan observe``'s .npz, or a rendered one) played as a camera and a robot
would publish it: per view a depth ``Image`` and its ``CameraInfo``, and a ``JointState``; with the
node parameters that place those cameras (``node_arguments``). The tests and the bench talk to the
node through it; ``pickplan ros replay`` runs it, to try the node without a robot.

>>> replay = ObservationReplay(node, observation, robot, q)      # node: any rclpy node
>>> replay.publish()                                              # once; or every period:
>>> node.create_timer(0.2, replay.publish)
"""

from __future__ import annotations

from typing import List, Optional, Sequence

import numpy as np

from pickplan.ros.extra import require_ros

require_ros()

from geometry_msgs.msg import PointStamped  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, JointState  # noqa: E402

from pickplan.core.observation import Observation  # noqa: E402
from pickplan.ros import convert  # noqa: E402


def camera_names(views: int) -> List[str]:
    return [f"cam{v}" for v in range(views)]


class ObservationReplay:
    """Publishers of ``observation``'s views (``cam0``, ``cam1``, ...: depth in ``encodings``, one per
    view, default 32FC1) and of the joint positions ``q`` of ``robot``, on ``node``."""

    def __init__(
        self,
        node,
        observation: Observation,
        robot,
        q: np.ndarray,
        encodings: Optional[Sequence[str]] = None,
        base_frame: str = "",
    ):
        self.node, self.observation, self.robot = node, observation, robot
        self.names = camera_names(observation.views)
        self.encodings = list(encodings or ["32FC1"] * observation.views)
        self.base_frame = base_frame or robot.link_names[0]
        self.images: List[Image] = []
        self.infos: List[CameraInfo] = []
        for v, name in enumerate(self.names):
            depth = np.where(observation.depth[v] > 0, observation.depth[v], np.nan)
            image = Image(**convert.image_fields(depth, self.encodings[v]))
            image.header.frame_id = f"{name}_optical_frame"
            info = CameraInfo(
                height=image.height,
                width=image.width,
                distortion_model="plumb_bob",
                d=[0.0] * 5,
                k=convert.camera_info_k(observation.K[v]),
            )
            info.header.frame_id = image.header.frame_id
            info.r = np.eye(3).ravel().tolist()
            P = np.zeros((3, 4))
            P[:, :3] = np.asarray(info.k).reshape(3, 3)
            info.p = P.ravel().tolist()
            self.images.append(image)
            self.infos.append(info)
        self.joints = JointState(name=list(robot.joint_names), position=[float(v) for v in q])
        self.image_pubs = [node.create_publisher(Image, f"/{n}/depth/image_rect_raw", 2) for n in self.names]
        self.info_pubs = [node.create_publisher(CameraInfo, f"/{n}/depth/camera_info", 2) for n in self.names]
        self.joint_pub = node.create_publisher(JointState, "/joint_states", 2)
        self.click_pub = node.create_publisher(PointStamped, "/clicked_point", 2)

    def node_arguments(self) -> List[str]:
        """``--ros-args`` entries that tell the pickplan node where these cameras are."""
        args = ["-p", f"cameras:=[{','.join(self.names)}]", "-p", f"base_frame:={self.base_frame}"]
        for name, T in zip(self.names, self.observation.camera_pose):
            args += ["-p", f"{name}.pose:=[{','.join(repr(float(v)) for v in convert.pose_values(T))}]"]
        return args

    def publish(self) -> None:
        stamp = self.node.get_clock().now().to_msg()
        for image, info, image_pub, info_pub in zip(self.images, self.infos, self.image_pubs, self.info_pubs):
            image.header.stamp = info.header.stamp = stamp
            info_pub.publish(info)
            image_pub.publish(image)
        self.joints.header.stamp = stamp
        self.joint_pub.publish(self.joints)

    def click(self, point: Sequence[float], frame: Optional[str] = None) -> None:
        """A point clicked in RViz (``geometry_msgs/PointStamped`` on ``/clicked_point``)."""
        msg = PointStamped()
        msg.header.frame_id = self.base_frame if frame is None else frame
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.point.x, msg.point.y, msg.point.z = (float(v) for v in point)
        self.click_pub.publish(msg)
