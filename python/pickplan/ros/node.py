"""The ROS 2 node: plans a pick from depth cameras and joint states when its service is called.

Started by ``pickplan ros serve --robot NAME`` or the ``pickplan-ros-node`` script (a launch file's
``Node(executable="pickplan-ros-node")``; ROS arguments such as ``--ros-args -p cameras:=[...]`` pass
through). Parameters (read once at start):

================================ ========================================================================
``robot``                        a shipped description's name or a .toml file (``--robot`` sets it)
``base_frame``                   the planning frame: the robot's base (poses, points, markers are in it)
``cameras``                      camera names; per camera ``<name>.image_topic`` (default
                                 ``/<name>/depth/image_rect_raw``, 16UC1 mm or 32FC1 m),
                                 ``<name>.info_topic`` (``/<name>/depth/camera_info``) and
                                 ``<name>.pose`` (x y z qx qy qz qw or 16 numbers: its optical frame in
                                 ``base_frame``; empty: looked up in tf when tf2_ros is importable)
``joint_states_topic``           ``/joint_states``; arm joints must be there, finger joints default open
``clicked_point_topic``          ``/clicked_point`` (RViz's Publish Point): the object nearest the last
                                 point is the target
``target_point``                 x y z in ``base_frame``: the target until a point is clicked; the
                                 ``pickplan ros call --point`` command sets it (SetParameters) per request
``place_region``                 x0 y0 z0 x1 y1 z1 in ``base_frame``: the box the held object is put in by
                                 ``~/pick_and_place`` (its floor on a support: a table area, a shelf
                                 board, a bin's floor); ``pickplan ros call --place`` sets it per request
``place_orientation``            ``upright`` (as it stood) or ``stable`` (any stable resting pose)
``rate``, ``speed_scaling``      samples per second of the trajectory; fraction of the joint limits
``trajectory_joints``            joints in the trajectory (default: every joint of the robot)
``seed``                         the planner's seed
``controller_action``            a FollowJointTrajectory action; when set (and control_msgs imports)
                                 each trajectory is also sent there
================================ ========================================================================

Interface: services ``~/plan`` (the pick) and ``~/pick_and_place`` (the pick, the carry and the place
in ``place_region``; one trajectory whose finger joints close after the approach and open after the
set-down; the parts' times are in the status: ``segment.<name>`` = "start end" seconds, for a gripper
driven apart from the arm), both ``std_srvs/Trigger``: success and a one-line status or reason;
topics ``~/trajectory`` (``trajectory_msgs/JointTrajectory``, timed within the limits),
``~/markers`` (``visualization_msgs/MarkerArray``, published after the response when subscribed)
and ``~/status`` (``diagnostic_msgs/DiagnosticStatus``: level, the status, the reason, timings), the
last three latched (transient local). A message that cannot be used fails that request with its
topic and field named, and the node goes on; it keeps only the latest message of each topic.
"""

from __future__ import annotations

import signal
import sys
import threading
import time
import traceback
from typing import Dict, List, Optional

from pickplan.ros.extra import available, require_ros

require_ros()  # a clear error naming the extra, before any ROS import fails on its own

import numpy as np  # noqa: E402
import rclpy  # noqa: E402
import rclpy.executors  # noqa: E402
import rclpy.time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue  # noqa: E402
from geometry_msgs.msg import PointStamped  # noqa: E402
from rcl_interfaces.msg import SetParametersResult  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402
from rclpy.signals import SignalHandlerOptions  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, JointState  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402
from visualization_msgs.msg import MarkerArray  # noqa: E402

from pickplan.core.errors import InputError  # noqa: E402
from pickplan.omg.place import Orientation, PlaceRequest  # noqa: E402
from pickplan.omg.planner import OMGSettings  # noqa: E402
from pickplan.ros import convert  # noqa: E402
from pickplan.ros.markers import pick_markers  # noqa: E402
from pickplan.ros.pipeline import CameraView, PickOutcome, PickPipeline, PickRequest, PickSettings, PickStatus  # noqa: E402

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
RELIABLE = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
TARGET = "target"  # the key of the last target given in PickNode.latest
STOP_POLL_S = 0.1  # how soon a stop signal is seen while nothing arrives


def trajectory_message(timed, robot, joints: List[str], frame: str) -> JointTrajectory:
    """A ``JointTrajectory`` of the timed trajectory's samples for ``joints`` (stamp 0: start now)."""
    index = [robot.joint_names.index(j) for j in joints]
    msg = JointTrajectory()
    msg.header.frame_id = frame
    msg.joint_names = list(joints)
    q, qd, qdd = timed.q[:, index], timed.qd[:, index], timed.qdd[:, index]
    points = []
    for k, t in enumerate(timed.t):
        p = JointTrajectoryPoint(positions=q[k].tolist(), velocities=qd[k].tolist(), accelerations=qdd[k].tolist())
        p.time_from_start.sec, p.time_from_start.nanosec = convert.seconds_to_duration(t)
        points.append(p)
    msg.points = points
    return msg


class PickNode(Node):
    """See the module doc."""

    def __init__(self, robot: Optional[str] = None, **kwargs):
        super().__init__("pickplan", **kwargs)
        # topic -> its last message, and TARGET -> the last target given: the inputs of the next request
        self.latest: Dict[str, object] = {}
        p = self._declare_parameters(robot)
        self.pipeline = PickPipeline(
            PickSettings(
                robot=p["robot"], rate=p["rate"], speed_scaling=p["speed_scaling"], planner=OMGSettings(seed=p["seed"])
            )
        )
        robot_model = self.pipeline.robot
        self.frame = p["base_frame"] or robot_model.link_names[0]
        self.joints = p["trajectory_joints"] or robot_model.joint_names
        unknown = [j for j in self.joints if j not in robot_model.joint_names]
        if unknown:
            raise InputError(f"not joints of {robot_model.info.name}: {', '.join(unknown)}", field="trajectory_joints")
        self.finger_defaults = {j: robot_model.info.finger_open for j in robot_model.info.finger_joints}
        self.cameras = self._camera_parameters(p["cameras"])
        for cam in self.cameras:
            for key, kind in (("image_topic", Image), ("info_topic", CameraInfo)):
                self.create_subscription(kind, cam[key], self._keeper(cam[key]), qos_profile_sensor_data)
        self.joint_topic, self.click_topic = p["joint_states_topic"], p["clicked_point_topic"]
        self.create_subscription(JointState, self.joint_topic, self._keeper(self.joint_topic), qos_profile_sensor_data)
        self.create_subscription(PointStamped, self.click_topic, self._on_click, RELIABLE)
        self.add_on_set_parameters_callback(self._on_parameters)
        self.trajectory_pub = self.create_publisher(JointTrajectory, "~/trajectory", LATCHED)
        self.markers_pub = self.create_publisher(MarkerArray, "~/markers", LATCHED)
        self.status_pub = self.create_publisher(DiagnosticStatus, "~/status", LATCHED)
        self.create_service(Trigger, "~/plan", self._on_plan)
        self.create_service(Trigger, "~/pick_and_place", self._on_pick_and_place)
        self._drawn: Optional[PickOutcome] = None
        self._draw = self.create_guard_condition(self._publish_markers)  # after the response is sent
        self._tf = self._tf_buffer() if any(c["pose"] is None for c in self.cameras) else None
        self._controller = self._action_client(p["controller_action"])
        self.get_logger().info(
            f"pickplan: planning picks for {robot_model.info.name} in {self.frame} from "
            f"{len(self.cameras)} camera(s); call {self.resolve_service_name('~/plan')}"
        )

    # --- parameters -------------------------------------------------------------------------------
    def _declare_parameters(self, robot: Optional[str]) -> dict:
        defaults = {
            "robot": robot or "panda",
            "base_frame": "",
            "cameras": ["camera"],
            "joint_states_topic": "/joint_states",
            "clicked_point_topic": "/clicked_point",
            "rate": 100.0,
            "speed_scaling": 1.0,
            "seed": 0,
            "controller_action": "",
        }
        out = {name: self.declare_parameter(name, value).value for name, value in defaults.items()}
        if robot:  # the command line's --robot wins over a parameter file
            out["robot"] = robot
        out["trajectory_joints"] = list(
            self.declare_parameter("trajectory_joints", Parameter.Type.STRING_ARRAY).value or []
        )
        point = self.declare_parameter("target_point", Parameter.Type.DOUBLE_ARRAY).value
        if point:
            self.latest[TARGET] = ("target_point", list(point))
        self.place_parameters = {
            "place_region": list(self.declare_parameter("place_region", Parameter.Type.DOUBLE_ARRAY).value or []),
            "place_orientation": self.declare_parameter("place_orientation", Orientation.upright.value).value,
        }
        self.place = _place_request(**self.place_parameters)
        return out

    def _camera_parameters(self, names) -> List[dict]:
        if not names:
            raise InputError("expected at least one camera name", field="cameras")
        cameras = []
        for name in names:
            image = self.declare_parameter(f"{name}.image_topic", f"/{name}/depth/image_rect_raw").value
            info = self.declare_parameter(f"{name}.info_topic", f"/{name}/depth/camera_info").value
            pose = self.declare_parameter(f"{name}.pose", Parameter.Type.DOUBLE_ARRAY).value
            T = convert.pose_matrix(pose, f"{name}.pose") if pose else None
            if T is None and not available("tf2_ros"):
                raise InputError(
                    "no pose parameter and tf2_ros cannot be imported: give the camera's optical frame "
                    "in the base frame as x y z qx qy qz qw",
                    field=f"{name}.pose",
                )
            cameras.append({"name": name, "image_topic": image, "info_topic": info, "pose": T})
        return cameras

    def _tf_buffer(self):
        from tf2_ros import Buffer, TransformListener  # optional: no wheel on PyPI; a system ROS has it

        buffer = Buffer()
        self._tf_listener = TransformListener(buffer, self)
        return buffer

    def _action_client(self, name: str):
        if not name:
            return None
        if not available("control_msgs"):
            self.get_logger().warning(
                f"controller_action {name}: control_msgs cannot be imported; trajectories are only published"
            )
            return None
        from control_msgs.action import FollowJointTrajectory  # optional: no wheel on PyPI
        from rclpy.action import ActionClient

        return ActionClient(self, FollowJointTrajectory, name), FollowJointTrajectory

    def _keeper(self, topic: str):
        def keep(msg):
            self.latest[topic] = msg

        return keep

    # --- a request --------------------------------------------------------------------------------
    def _message(self, topic: str, what: str):
        msg = self.latest.get(topic)
        if msg is None:
            raise convert.MessageError(topic, f"no {what} received yet")
        return msg

    def _camera_pose(self, cam: dict, image) -> np.ndarray:
        if cam["pose"] is not None:
            return cam["pose"]
        try:
            tf = self._tf.lookup_transform(self.frame, image.header.frame_id, rclpy.time.Time())
        except Exception as exc:  # noqa: BLE001 - tf2's lookup errors share no base class worth naming
            raise convert.MessageError(
                f"{cam['name']}.pose", f"no transform {self.frame} <- {image.header.frame_id!r} in tf ({exc})"
            ) from None
        t, r = tf.transform.translation, tf.transform.rotation
        return convert.pose_matrix([t.x, t.y, t.z, r.x, r.y, r.z, r.w], f"tf {image.header.frame_id}")

    def _on_click(self, msg: PointStamped) -> None:
        self.latest[TARGET] = (self.click_topic, msg)

    def _on_parameters(self, params) -> SetParametersResult:
        for param in params:
            if param.name == "target_point":
                values = list(param.value or [])
                if len(values) != 3 or not all(np.isfinite(values)):
                    return SetParametersResult(successful=False, reason=f"target_point: expected x y z, got {values}")
                self.latest[TARGET] = ("target_point", values)
            elif param.name in self.place_parameters:
                asked = dict(
                    self.place_parameters,
                    **{param.name: param.value if isinstance(param.value, str) else list(param.value or [])},
                )
                try:
                    self.place = _place_request(**asked)
                except InputError as exc:
                    return SetParametersResult(successful=False, reason=str(exc))
                self.place_parameters = asked
            elif param.name != "use_sim_time":  # the clock's own
                return SetParametersResult(
                    successful=False, reason=f"{param.name}: read at start only; restart the node to change it"
                )
        return SetParametersResult(successful=True)

    def _target_point(self) -> np.ndarray:
        """The last point given, clicked or set as the target_point parameter."""
        source, value = self.latest.get(TARGET, (None, None))
        if source is None:
            raise convert.MessageError(
                self.click_topic,
                "no target: click a point (geometry_msgs/PointStamped) or set the target_point parameter",
            )
        if source == "target_point":
            return np.array(value, float)
        frame = value.header.frame_id
        if frame and frame != self.frame:
            raise convert.MessageError(
                f"{self.click_topic}.header.frame_id", f"{frame!r}: expected the base frame {self.frame!r}"
            )
        return convert.point(value.point, f"{self.click_topic}.point")

    def request(self) -> PickRequest:
        """The latest messages as a ``PickRequest``; raises ``MessageError`` naming the topic."""
        views = []
        for cam in self.cameras:
            image = self._message(cam["image_topic"], "depth image")
            info = self._message(cam["info_topic"], "camera info")
            depth = convert.depth_image(image, cam["image_topic"])
            K = convert.observation_K(info, depth.shape, cam["info_topic"])
            views.append(CameraView(depth, K, self._camera_pose(cam, image), cam["name"]))
        joints = self._message(self.joint_topic, "joint state")
        start = convert.joint_positions(joints, self.pipeline.robot.joint_names, self.finger_defaults, self.joint_topic)
        return PickRequest(views, start, self._target_point())

    def plan_once(self, place: bool = False) -> PickOutcome:
        """Plan the pick (``place``: and its place in ``place_region``) from the latest messages."""
        t0 = time.perf_counter()
        try:
            if place and self.place is None:
                raise InputError(
                    "no place region: set the place_region parameter (x0 y0 z0 x1 y1 z1)", field="place_region"
                )
            outcome = self.pipeline.plan(self.request(), self.place if place else None)
        except (InputError, ValueError) as exc:
            outcome = PickOutcome(PickStatus.bad_input, str(exc))
        except Exception as exc:  # noqa: BLE001 - a bug must fail the request, not end the node
            self.get_logger().error(traceback.format_exc())
            outcome = PickOutcome(PickStatus.internal_error, f"{type(exc).__name__}: {exc}")
        if outcome.success:
            msg = trajectory_message(outcome.timed, self.pipeline.robot, self.joints, self.frame)
            self.trajectory_pub.publish(msg)
            self._send_to_controller(msg)
        outcome.seconds["request"] = time.perf_counter() - t0
        self.status_pub.publish(self._status(outcome))
        if outcome.success:  # rclpy ties a severity to each call site: one call per severity
            self.get_logger().info(f"plan: {outcome.summary()}")
        else:
            self.get_logger().error(f"plan: {outcome.summary()}")
        return outcome

    def _status(self, outcome: PickOutcome) -> DiagnosticStatus:
        level = DiagnosticStatus.OK if outcome.success else DiagnosticStatus.ERROR
        values = [KeyValue(key="status", value=str(outcome.status))]
        values += [KeyValue(key=f"seconds.{k}", value=f"{v:.4f}") for k, v in sorted(outcome.seconds.items())]
        values += [KeyValue(key=f"segment.{name}", value=f"{t0:.4f} {t1:.4f}") for name, t0, t1 in outcome.segments]
        return DiagnosticStatus(
            level=level,
            name=self.get_fully_qualified_name(),
            message=outcome.summary(),
            hardware_id=self.pipeline.robot.info.name,
            values=values,
        )

    def _send_to_controller(self, msg: JointTrajectory) -> None:
        if self._controller is None:
            return
        client, action = self._controller
        if not client.server_is_ready():
            self.get_logger().error("controller action server not available: trajectory only published")
            return
        client.send_goal_async(action.Goal(trajectory=msg))

    def _on_plan(self, request, response, place: bool = False):
        try:
            outcome = self.plan_once(place)
        except Exception as exc:  # noqa: BLE001 - publishing or logging failed: still an answer, never a dead node
            outcome = PickOutcome(PickStatus.internal_error, f"{type(exc).__name__}: {exc}")
        response.success, response.message = outcome.success, outcome.summary()
        if self.markers_pub.get_subscription_count() > 0:
            self._drawn = outcome
            self._draw.trigger()
        return response

    def _on_pick_and_place(self, request, response):
        return self._on_plan(request, response, place=True)

    def _publish_markers(self) -> None:
        outcome, self._drawn = self._drawn, None
        if outcome is not None:
            self.markers_pub.publish(pick_markers(outcome, self.frame, self.get_clock().now().to_msg()))


def _place_request(place_region: list, place_orientation: str) -> Optional[PlaceRequest]:
    """The place request of the parameters (None: no region); ``InputError`` naming the parameter."""
    region, orientation = place_region, place_orientation
    if orientation not in (Orientation.upright.value, Orientation.stable.value):
        raise InputError(f"expected upright or stable, got {orientation!r}", field="place_orientation")
    if not region:
        return None
    if len(region) != 6 or not all(np.isfinite(region)):
        raise InputError(f"expected 6 finite numbers x0 y0 z0 x1 y1 z1, got {region}", field="place_region")
    try:
        return PlaceRequest(tuple(region[:3]), tuple(region[3:]), Orientation(orientation))
    except ValueError as exc:
        raise InputError(str(exc), field="place_region") from None


def run(robot: Optional[str] = None, args: Optional[List[str]] = None) -> int:
    """Start the node and spin until Ctrl-C (SIGINT), SIGTERM or shutdown; ``args``: ROS arguments.

    rclpy's own handler raises ``KeyboardInterrupt`` wherever the signal lands, and inside its
    message conversion that surfaces as a ``RuntimeError`` (a stop reported as a crash). So the node
    takes the signals itself: the handler only asks to stop, and the loop stops between callbacks.
    """
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    node = None
    try:
        node = PickNode(robot)
        executor = rclpy.executors.SingleThreadedExecutor()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=STOP_POLL_S)
    except rclpy.executors.ExternalShutdownException:
        pass
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if node is not None:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


def main(argv: Optional[List[str]] = None) -> int:
    """The ``pickplan-ros-node`` script: ``--robot NAME`` and ROS arguments."""
    argv = list(sys.argv[1:] if argv is None else argv)
    robot = None
    if "--robot" in argv:
        i = argv.index("--robot")
        robot = argv[i + 1] if i + 1 < len(argv) else None
        del argv[i : i + 2]
    return run(robot, [sys.argv[0]] + argv)
