"""Calling the node from Python (``pickplan ros call``; the tests and the bench use it too).

``PickClient(node_name)`` wraps an rclpy node that can set the target point and the place region
(the node's ``target_point`` and ``place_region`` parameters, through the standard ``SetParameters``
service, acknowledged before the plan is requested), call ``~/plan`` or ``~/pick_and_place`` and wait
for the trajectory it publishes and the status that describes it.

>>> with PickClient() as client:
...     reply = client.plan(point=(0.55, 0.02, 0.08))
...     reply.success, reply.message, reply.trajectory   # JointTrajectory or None
...     reply = client.pick_and_place(point=(0.55, 0.02, 0.08), region=(0.35, -0.5, 0.0, 0.6, -0.25, 0.4))
...     reply.segments                                   # [("approach", 0.0, 1.4), ("close", 1.4, 1.9), ...]
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

from pickplan.ros.extra import require_ros

require_ros()

import rclpy  # noqa: E402
from diagnostic_msgs.msg import DiagnosticStatus  # noqa: E402
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
    trajectory: Optional[JointTrajectory]  # the one published for this request (None on failure)
    seconds: float  # from the request to the trajectory (or the failed response)
    segments: List[Tuple[str, float, float]] = field(default_factory=list)  # a pick and place's parts: name, start, end


class PickClient:
    """A client node of the pickplan node ``server`` (its fully qualified name)."""

    def __init__(self, server: str = "/pickplan", name: str = "pickplan_client", args=None, context=None):
        self._own_context = context is None and not rclpy.ok()
        if self._own_context:
            rclpy.init(args=args)
        self.node = rclpy.create_node(name)
        self.server = server.rstrip("/")
        self.plan_client = self.node.create_client(Trigger, f"{self.server}/plan")
        self.place_client = self.node.create_client(Trigger, f"{self.server}/pick_and_place")
        self.param_client = self.node.create_client(SetParameters, f"{self.server}/set_parameters")
        self._trajectories = []
        self.node.create_subscription(JointTrajectory, f"{self.server}/trajectory", self._trajectories.append, LATCHED)
        self._statuses = []
        self.node.create_subscription(DiagnosticStatus, f"{self.server}/status", self._statuses.append, LATCHED)

    def __enter__(self) -> "PickClient":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        self.node.destroy_node()
        if self._own_context and rclpy.ok():
            rclpy.shutdown()

    def wait_for_server(self, timeout: float = 30.0) -> bool:
        return all(
            c.wait_for_service(timeout_sec=timeout) for c in (self.plan_client, self.place_client, self.param_client)
        )

    def _call(self, client, request, timeout: float):
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout)
        if not future.done():
            client.remove_pending_request(future)
            raise TimeoutError(f"{client.srv_name}: no answer within {timeout} s")
        return future.result()

    def set_parameters(self, values: dict, timeout: float = 10.0) -> None:
        """Set the node's parameters (name -> list of numbers or a string); ``ValueError`` with the
        node's reason when it refuses one."""
        params = []
        for name, value in values.items():
            if isinstance(value, str):
                v = ParameterValue(type=ParameterType.PARAMETER_STRING, string_value=value)
            else:
                v = ParameterValue(
                    type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[float(x) for x in value]
                )
            params.append(ParameterMsg(name=name, value=v))
        reply = self._call(self.param_client, SetParameters.Request(parameters=params), timeout)
        for name, result in zip(values, reply.results):
            if not result.successful:
                raise ValueError(f"{name}: refused: {result.reason}")

    def set_target(self, point: Sequence[float], timeout: float = 10.0) -> None:
        self.set_parameters({"target_point": point}, timeout)

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self.node, timeout_sec=min(0.05, max(0.0, end - time.monotonic())))

    def plan(self, point: Optional[Sequence[float]] = None, timeout: float = 120.0) -> PlanReply:
        """Plan the pick (for ``point``, or for the node's current target) and wait for the trajectory."""
        if point is not None:
            self.set_target(point)
        return self._request(self.plan_client, timeout)

    def pick_and_place(
        self,
        point: Optional[Sequence[float]] = None,
        region: Optional[Sequence[float]] = None,
        orientation: Optional[str] = None,
        timeout: float = 120.0,
    ) -> PlanReply:
        """Plan the pick and the place in ``region`` (x0 y0 z0 x1 y1 z1; default: the node's place_region)."""
        values = {
            k: v
            for k, v in (("target_point", point), ("place_region", region), ("place_orientation", orientation))
            if v is not None
        }
        if values:
            self.set_parameters(values)
        return self._request(self.place_client, timeout)

    def _request(self, client, timeout: float) -> PlanReply:
        self._trajectories.clear()
        self._statuses.clear()
        t0 = time.perf_counter()
        reply = self._call(client, Trigger.Request(), timeout)
        trajectory = None
        if reply.success:  # published before the response: arrives first or right after
            end = time.monotonic() + 10.0
            while not (self._trajectories and self._statuses) and time.monotonic() < end:
                rclpy.spin_once(self.node, timeout_sec=0.01)
            trajectory = self._trajectories[-1] if self._trajectories else None
        segments = []
        if self._statuses:
            for kv in self._statuses[-1].values:
                if kv.key.startswith("segment."):
                    t_start, t_end = (float(x) for x in kv.value.split())
                    segments.append((kv.key[len("segment.") :], t_start, t_end))
        return PlanReply(
            reply.success, reply.message, trajectory, time.perf_counter() - t0, sorted(segments, key=lambda seg: seg[1])
        )
