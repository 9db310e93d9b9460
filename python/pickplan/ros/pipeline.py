"""One pick request -> a timed trajectory, by the library's own planning from depth (no ROS here).

A ``PickRequest`` holds what the node read from its topics, already converted (``ros.convert``):
per camera a depth image in metres, ``Observation.K`` and the camera pose in the planning frame;
the robot's joint positions; a point on or near the target. ``PickPipeline.plan`` then

1. finds the support plane (``perception.field.support_plane``, as ``perceive`` would) and the
   target as the object nearest the point (``perception.target.target_near_point``);
2. builds the ``Observation`` and plans as ``pickplan plan --observation`` does (``PerceivedWorld``,
   ``PerceivedPlanner``), from the joint positions, the plane handed on so it is found once;
3. times the plan within the robot's limits (times ``speed_scaling``) at ``rate`` Hz (toppra).

Any failure is a ``PickOutcome`` with a ``PickStatus`` and a reason, never an exception; the
pipeline keeps nothing from one request to the next but the robot's model data (``ModelCache``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import List, Optional, Tuple

import numpy as np

from pickplan.core.observation import Observation, ObservationError
from pickplan.core.settings import Option
from pickplan.core.timing import KinematicLimits, TimedTrajectory, TimingError, robot_limits
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld, PerceivedWorldSettings
from pickplan.omg.pickplace import PickPlacePlan, PickPlacePlanner, PickPlaceSettings, PickPlaceStatus
from pickplan.omg.place import PlaceRequest
from pickplan.omg.planner import OMGSettings, PlanResult, PlanStatus
from pickplan.perception.field import support_plane, view_points
from pickplan.perception.target import TargetSettings, target_near_point


class PickStatus(Option):
    """How a request ended: success, or why not."""

    success = "success"
    bad_input = "bad_input"  # a message or parameter that cannot be used (named in the reason)
    no_target = "no_target"  # no object near the point in any view
    no_goals = "no_goals"  # the planner's statuses (omg.planner.PlanStatus)
    ungraspable = "ungraspable"
    in_collision = "in_collision"
    not_smooth = "not_smooth"
    lift_blocked = "lift_blocked"  # pick and place (omg.pickplace.PickPlaceStatus)
    no_place_goals = "no_place_goals"
    place_failed = "place_failed"
    retract_blocked = "retract_blocked"
    internal_error = "internal_error"  # a bug: the reason names the exception


@dataclass(frozen=True)
class PickSettings:
    robot: str = "panda"  # a shipped description's name or a .toml file
    planner: OMGSettings = field(default_factory=OMGSettings)
    world: PerceivedWorldSettings = field(default_factory=PerceivedWorldSettings)
    target: TargetSettings = field(default_factory=TargetSettings)
    rate: float = 100.0  # Hz of the timed trajectory's samples
    speed_scaling: float = 1.0  # fraction of the robot's velocity and acceleration limits
    pickplace: PickPlaceSettings = field(default_factory=PickPlaceSettings)  # its ``pick``: ``planner``
    gripper_seconds: float = 0.5  # the shortest close and release in a pick and place

    def __post_init__(self):
        if not 0 < self.speed_scaling <= 1:
            raise ValueError(f"speed_scaling: expected a fraction in (0, 1], got {self.speed_scaling}")
        if not 0 < self.rate <= 10000:
            raise ValueError(f"rate: expected Hz in (0, 10000], got {self.rate}")
        if not 0 <= self.gripper_seconds <= 60:
            raise ValueError(f"gripper_seconds: expected seconds in [0, 60], got {self.gripper_seconds}")


@dataclass
class CameraView:
    depth: np.ndarray  # (H, W) metres, NaN: no return
    K: np.ndarray  # (3, 3) Observation.K
    pose: np.ndarray  # (4, 4) camera optical frame -> planning frame
    name: str = "camera"


@dataclass
class PickRequest:
    views: List[CameraView]
    start: np.ndarray  # (dof,) joint positions in the robot's joint order
    point: np.ndarray  # (3,) planning frame: the object nearest it is the target


@dataclass
class PickOutcome:
    status: PickStatus
    reason: str = ""
    result: Optional[PlanResult] = None
    timed: Optional[TimedTrajectory] = None
    world: Optional[PerceivedWorld] = None
    seconds: dict = field(default_factory=dict)  # target, plan, timing, total
    task: Optional[PickPlacePlan] = None  # a pick and place: the whole plan
    place: Optional[PlaceRequest] = None  # ... and where it was asked to put the object
    segments: List[Tuple[str, float, float]] = field(default_factory=list)  # its parts in ``timed``: name, start, end

    @property
    def success(self) -> bool:
        return self.status is PickStatus.success

    def summary(self) -> str:
        """One line: what was planned, or why not."""
        if not self.success:
            return f"{self.status}: {self.reason}"
        r, t = self.result, self.timed
        what = "pick and place" if self.task is not None else "pick"
        return (
            f"success: {what}, {len(t.t)} points over {t.duration:.2f} s, grasp {r.goal_source + 1} of "
            f"{r.goal_set_size}{' (refined)' if r.refined else ''}, planned in {self.seconds.get('total', 0.0):.3f} s"
        )


class PickPipeline:
    """Plans pick requests for one robot (see the module doc)."""

    def __init__(self, settings: PickSettings = PickSettings()):
        self.settings = settings
        self.cache = ModelCache()
        self.robot = self.cache.robot(settings.robot, np.eye(4))
        base = robot_limits(self.robot)
        self.limits = KinematicLimits(
            base.velocity * settings.speed_scaling, base.acceleration * settings.speed_scaling
        )

    def observation(self, request: PickRequest) -> Tuple[Observation, PerceivedWorldSettings]:
        """The request's views as an ``Observation`` with the target nearest its point segmented, and
        the world settings that carry the support plane found on the way (so ``perceive`` does not
        search again). Raises ``ObservationError``."""
        if not request.views:
            raise ObservationError("request: views: no camera image")
        depth = np.stack([np.nan_to_num(v.depth, nan=0.0) for v in request.views]).astype(np.float32)
        K = np.stack([v.K for v in request.views])
        poses = np.stack([v.pose for v in request.views])
        field_settings = self.settings.world.field
        plane = support_plane(
            view_points(depth, K, poses, 4), field_settings.plane_tolerance, seed=self.settings.world.seed
        )
        mask = target_near_point(depth, K, poses, request.point, plane, self.settings.target, source="request")
        obs = Observation(depth, K, poses, mask, source="request " + ", ".join(v.name for v in request.views))
        return obs, replace(self.settings.world, field=replace(field_settings, plane=plane))

    def _world(self, request: PickRequest, seconds: dict) -> Tuple[Optional[np.ndarray], object]:
        """(start, world) of a request, or (None, the failed ``PickOutcome``); ``seconds['target']`` filled."""
        t0 = time.perf_counter()
        try:
            start = self.robot.check_within_limits(np.asarray(request.start, float), "joint_states")
            obs, world_settings = self.observation(request)
        except ObservationError as exc:
            status = PickStatus.no_target if "target point" in str(exc) else PickStatus.bad_input
            return None, PickOutcome(status, str(exc))
        except ValueError as exc:
            return None, PickOutcome(PickStatus.bad_input, str(exc))
        seconds["target"] = time.perf_counter() - t0
        try:
            return start, PerceivedWorld(obs, self.robot, world_settings, cache=self.cache)
        except ValueError as exc:
            return None, PickOutcome(PickStatus.no_target, str(exc))

    def plan(self, request: PickRequest, place: Optional[PlaceRequest] = None) -> PickOutcome:
        """The pick of the target near ``request.point``; with ``place``, the pick and its place."""
        t0 = time.perf_counter()
        seconds = {}
        start, world = self._world(request, seconds)
        if start is None:  # world: the failed outcome
            return replace(world, seconds=dict(seconds, total=time.perf_counter() - t0))
        t1 = time.perf_counter()
        if place is not None:
            return self._pick_and_place(world, start, place, seconds, t0)
        result = PerceivedPlanner(world, self.settings.planner).plan(start=start)
        t2 = time.perf_counter()
        seconds["plan"] = t2 - t1
        if not result.success:
            reason = result.reason or _plan_failure(result)
            return PickOutcome(
                PickStatus(str(result.status)), reason, result, None, world, dict(seconds, total=t2 - t0)
            )
        try:
            timed = result.timed(self.settings.rate, self.limits)
        except TimingError as exc:
            return PickOutcome(
                PickStatus.internal_error,
                f"timing: {exc}",
                result,
                None,
                world,
                dict(seconds, total=time.perf_counter() - t0),
            )
        seconds["timing"] = time.perf_counter() - t2
        seconds["total"] = time.perf_counter() - t0
        return PickOutcome(PickStatus.success, "", result, timed, world, seconds)

    def _pick_and_place(
        self, world: PerceivedWorld, start: np.ndarray, place: PlaceRequest, seconds: dict, t0: float
    ) -> PickOutcome:
        t1 = time.perf_counter()
        settings = replace(self.settings.pickplace, pick=self.settings.planner)
        task = PickPlacePlanner(PerceivedPlanner(world, settings.pick), place, settings).plan(start=start)
        t2 = time.perf_counter()
        seconds["plan"] = t2 - t1
        if not task.success:
            status = (
                PickStatus(str(task.pick.status))
                if task.status is PickPlaceStatus.pick_failed
                else PickStatus(task.status.value)
            )
            reason = task.reason if task.pick.success else (task.pick.reason or _plan_failure(task.pick))
            return PickOutcome(
                status, reason, task.pick, None, world, dict(seconds, total=t2 - t0), task=task, place=place
            )
        try:
            timed, segments = task.timed_task(
                self.robot, self.settings.rate, self.limits, self.settings.gripper_seconds
            )
        except TimingError as exc:
            return PickOutcome(
                PickStatus.internal_error,
                f"timing: {exc}",
                task.pick,
                None,
                world,
                dict(seconds, total=time.perf_counter() - t0),
                task=task,
                place=place,
            )
        seconds["timing"] = time.perf_counter() - t2
        seconds["total"] = time.perf_counter() - t0
        return PickOutcome(
            PickStatus.success, "", task.pick, timed, world, seconds, task=task, place=place, segments=segments
        )


def _plan_failure(result: PlanResult) -> str:
    if result.status == PlanStatus.no_goals:
        reasons = ", ".join(f"{k}: {v}" for k, v in sorted(result.goal_reasons.items())) or "no grasp from the points"
        return f"no goal configuration for any grasp of the target ({reasons})"
    m = result.metrics
    return (
        f"the plan failed the success test ({result.status}: min clearance "
        f"{getattr(m, 'min_clearance', float('nan')):.3f} m, smoothness {getattr(m, 'smoothness', float('nan')):.3f})"
    )
