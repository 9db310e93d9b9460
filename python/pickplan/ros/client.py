"""Calling the node from Python (``pickplan ros call``; the tests and the bench use it too).

``PickClient(node_name)`` wraps an rclpy node that can set the target point (the node's
``target_point`` parameter, through the standard ``SetParameters`` service, acknowledged before the
plan is requested), call ``~/plan`` and wait for the trajectory it publishes.

>>> with PickClient() as client:
...     reply = client.plan(point=(0.55, 0.02, 0.08))
...     reply.success, reply.message, reply.trajectory   # JointTrajectory or None
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional, Sequence

from pickplan.ros.extra import require_ros

require_ros()

import rclpy  # noqa: E402
from rcl_interfaces.msg import Parameter as ParameterMsg  # noqa: E402
from rcl_interfaces.msg import ParameterType, ParameterValue  # noqa: E402
from rcl_interfaces.srv import SetParameters  # noqa: E402
from std_srvs.srv import Trigger  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from pickplan.ros.node import LATCHED  # noqa: E402


@dataclass
class PlanReply:
    success: bool
    message: str
    trajectory: Optional[JointTrajectory]   # the one published for this request (None on failure)
    seconds: float                          # from the request to the trajectory (or the failed response)


class PickClient:
    """A client node of the pickplan node ``server`` (its fully qualified name)."""

    def __init__(self, server: str = "/pickplan", name: str = "pickplan_client", args=None, context=None):
        self._own_context = context is None and not rclpy.ok()
        if self._own_context:
            rclpy.init(args=args)
        self.node = rclpy.create_node(name)
        self.server = server.rstrip("/")
        self.plan_client = self.node.create_client(Trigger, f"{self.server}/plan")
        self.param_client = self.node.create_client(SetParameters, f"{self.server}/set_parameters")
        self._trajectories = []
        self.node.create_subscription(JointTrajectory, f"{self.server}/trajectory", self._trajectories.append, LATCHED)

    def __enter__(self) -> "PickClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.node.destroy_node()
        if self._own_context and rclpy.ok():
            rclpy.shutdown()

    def wait_for_server(self, timeout: float = 30.0) -> bool:
        return self.plan_client.wait_for_service(timeout_sec=timeout) and \
            self.param_client.wait_for_service(timeout_sec=timeout)

    def _call(self, client, request, timeout: float):
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout)
        if not future.done():
            client.remove_pending_request(future)
            raise TimeoutError(f"{client.srv_name}: no answer within {timeout} s")
        return future.result()

    def set_target(self, point: Sequence[float], timeout: float = 10.0) -> None:
        value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[float(v) for v in point])
        reply = self._call(self.param_client, SetParameters.Request(
            parameters=[ParameterMsg(name="target_point", value=value)]), timeout)
        if not reply.results[0].successful:
            raise ValueError(f"target_point: refused: {reply.results[0].reason}")

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def plan(self, point: Optional[Sequence[float]] = None, timeout: float = 120.0) -> PlanReply:
        """Plan (for ``point``, or for the node's current target) and wait for the trajectory."""
        if point is not None:
            self.set_target(point)
        self._trajectories.clear()
        t0 = time.perf_counter()
        reply = self._call(self.plan_client, Trigger.Request(), timeout)
        trajectory = None
        if reply.success:  # published before the response: arrives first or right after
            end = time.monotonic() + 10.0
            while not self._trajectories and time.monotonic() < end:
                rclpy.spin_once(self.node, timeout_sec=0.01)
            trajectory = self._trajectories[-1] if self._trajectories else None
        return PlanReply(reply.success, reply.message, trajectory, time.perf_counter() - t0)
