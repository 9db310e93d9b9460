"""Pick and place: plan a pick, carry the object, put it down where a ``PlaceRequest`` asks.

The segments, each a straight IK path or an OMG plan:

1. **approach** (``pick``): the OMG planner's grasp plan (``OMGPlanner.plan``);
2. **lift**: straight along the support's normal from the grasp, the held object on the robot
   (``attach.HeldWorld``); it may touch its support for the first ``lift_contact`` metres, nothing else;
3. **transfer** (``place``): Algorithm 2 from the lifted configuration to the place goal set
   (``place.build_place_goal_set``): CHOMP-Proj, online selection among the place goals, the same
   success test with the held object's body points; its tail is the **set-down**, straight along
   gravity from ``PlaceSettings.goals.standoff`` above the place;
4. release, then **retract**: straight back up along the set-down's axis, the object left at its place.

>>> planner = PickPlacePlanner(OMGPlanner(None, scene), PlaceRequest.load("region.json"))
>>> plan = planner.plan()                     # or planner.plan_pick(); planner.attach(pick); planner.plan_place(...)
>>> plan.status, plan.segments()              # [("approach", Q), ("lift", Q), ("transfer", Q), ("retract", Q)]
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field, replace
from typing import Iterator, List, Optional, Tuple

import numpy as np

from pickplan.core import collision
from pickplan.core.settings import Option
from pickplan.core.timing import KinematicLimits, TimedTrajectory, concatenate, joint_move, time_parameterize
from pickplan.omg.attach import (
    AttachSettings,
    HeldCheck,
    HeldObject,
    HeldWorld,
    held_from_plan,
    straight_path,
    straight_path_steps,
)
from pickplan.omg.carry_seed import upright_initialization
from pickplan.omg.chomp import ChompSettings
from pickplan.omg.goals import GoalSet
from pickplan.omg.grasps.verify import VerifySettings
from pickplan.omg.place import PlaceGoalSet, PlaceRequest, PlaceSettings, build_place_goal_set, reason_summary
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanResult, plan_to_goal_set
from pickplan.omg.verified_pick import verified_pick


class PickPlaceStatus(Option):
    """How a pick-and-place plan ended (``PickPlacePlan.reason`` says more)."""

    success = "success"
    pick_failed = "pick_failed"  # the grasp plan failed (``pick.status``: no_goals, in_collision, ...)
    lift_blocked = "lift_blocked"  # the straight lift is unreachable or collides
    no_place_goals = "no_place_goals"  # no place goal (the reason: out of reach, too small, blocked)
    place_failed = "place_failed"  # the transfer failed the success test
    retract_blocked = "retract_blocked"  # the straight retract is unreachable or collides


# The failures another grasp of the same pick could avoid: the hand's place relative to the object
# decides the lift, the place goals (the hand at the place) and the transfer's and retract's clearance.
REGRASP = (
    PickPlaceStatus.lift_blocked,
    PickPlaceStatus.no_place_goals,
    PickPlaceStatus.place_failed,
    PickPlaceStatus.retract_blocked,
)


# The transfer's CHOMP: its waypoints 0.2 s apart (a pick's 0.1 s). The success test's smoothness is a
# bound on the mean squared joint speed (the prior sums (dq/dt)^2); a transfer crosses the workspace,
# about twice a pick's reach, and over 3 s even its straight line fails that bound (the timed
# trajectory's duration comes from toppra, not from this).
TRANSFER_CHOMP = ChompSettings(duration=6.0)


@dataclass(frozen=True)
class PickPlaceSettings:
    pick: OMGSettings = field(default_factory=OMGSettings)
    # The transfer's Algorithm 2: no C-Space ISF (it refines grasps, not places); the old place of the
    # held object is never an obstacle. Its goal-cost estimates read every 3rd tail waypoint and body point
    # (a pick's 2nd): they were most of the transfer's time; on the bench's first 12 YCB scenes the
    # transfers chose the same goals with them (of 20 goals: all 11; of 10: 10 of 11), and all succeeded.
    place: OMGSettings = field(
        default_factory=lambda: OMGSettings(
            chomp=TRANSFER_CHOMP, refine=False, transit_avoids_target=False, cost_time_stride=3, cost_point_stride=3
        )
    )
    goals: PlaceSettings = field(default_factory=PlaceSettings)
    attach: AttachSettings = field(default_factory=AttachSettings)
    # The lift rises until the robot and the held object keep the success test's clearance from every
    # object (the transfer starts there and cannot move its start), at least lift_min, at most lift_max.
    lift_min: float = 0.08  # m along the support's normal
    lift_max: float = 0.30
    lift_step: float = 0.01  # m between the lift's waypoints
    lift_contact: float = 0.01  # m of the lift in which the held object may touch its support
    retract: float = 0.10  # m straight up after the release
    retract_steps: int = 10
    # The carry (lift, transfer) is timed within this share of the velocity limits (its square of the
    # acceleration limits): an object held by friction alone slips when the hand jerks it about.
    carry_speed: float = 0.5
    # The transfer's CHOMP starts from the hand's straight path that turns the held object only by the yaw
    # between its lifted and placed poses (``carry_seed``), then from the straight line in joint space
    upright_carry: bool = True
    # A place that fails for a reason another grasp could change (``REGRASP``): the pick's other goals
    # are screened in the goal set's order for one place goal each, and the pick planned again among the
    # first ``regrasp_candidates`` that have one (those not chosen stay candidates, topped up from the rest
    # after a failed place), up to ``regrasp_plans`` times (0: never). A bowl held
    # across its rim puts the hand outside the rim, where a bin's wall stands; held nearer its top, it fits.
    regrasp_plans: int = 2
    regrasp_candidates: int = 3
    # The pick's grasp, as planned (refined or not), is lifted in PyBullet before the carry is planned, the
    # hand coming in from the standoff (``grasps.verify.lift_grasps``; each verdict cached); while it
    # falls, the pick is planned again without it, at most ``budget`` plans. The carry needs a grasp
    # that holds, and the quality is computed on the object's mesh where the physics may have another
    # model (a pitcher's 2 mm lip, filled solid in its collision model). None: no lift.
    verify_pick: Optional[VerifySettings] = VerifySettings(budget=5)


@dataclass
class PickPlacePlan:
    """Both segments of a pick and place (see the module doc); arrays are (T, dof) waypoints."""

    status: PickPlaceStatus
    reason: str
    pick: PlanResult
    lift: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    held: Optional[HeldObject] = None
    place: Optional[PlanResult] = None
    place_goals: Optional[PlaceGoalSet] = None
    place_pose: Optional[np.ndarray] = None  # (4, 4) the object's planned pose at release
    retract: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    timings: dict = field(default_factory=dict)
    carry_speed: float = 1.0  # the carry's share of the limits (``PickPlaceSettings``)

    @property
    def success(self) -> bool:
        return self.status is PickPlaceStatus.success

    def segments(self) -> List[Tuple[str, np.ndarray]]:
        """The planned segments in order (those planned so far)."""
        out = [("approach", self.pick.trajectory)]
        if len(self.lift) > 1:
            out.append(("lift", self.lift))
        if self.place is not None and self.place.planned:
            out.append(("transfer", self.place.trajectory))
        if len(self.retract):
            out.append(("retract", self.retract))
        return out

    @property
    def trajectory(self) -> np.ndarray:
        """Every segment's waypoints in one array (each junction once)."""
        segs = [Q for _, Q in self.segments()]
        return np.vstack([segs[0]] + [Q[1:] for Q in segs[1:]])

    def timed(
        self, rate: float = 1000.0, names: Optional[Tuple[str, ...]] = None, limits: Optional[KinematicLimits] = None
    ) -> List[Tuple[str, TimedTrajectory]]:
        """Each segment (of ``names``, default all) timed within ``limits`` (default: the robot's), rest to
        rest (the hand stops to close, to release and between straight segments); the carry (lift,
        transfer) within ``carry_speed`` of the velocity limits and its square of the acceleration limits."""
        limits, k = limits or self.pick.limits, self.carry_speed
        carry = KinematicLimits(limits.velocity * k, limits.acceleration * k * k)
        return [
            (name, time_parameterize(Q, rate, carry if name in ("lift", "transfer") else limits))
            for name, Q in self.segments()
            if names is None or name in names
        ]

    def timed_task(
        self, robot, rate: float = 1000.0, limits: Optional[KinematicLimits] = None, gripper_seconds: float = 0.5
    ) -> Tuple[TimedTrajectory, List[Tuple[str, float, float]]]:
        """The whole task as one trajectory for a controller: approach, **close** (the arm still, the
        fingers to ``finger_closed``: they stop on the object), lift and transfer with the fingers
        commanded closed, **release** (to the open hand), retract; and each part's (name, start, end) in
        seconds, for a gripper driven apart from the arm. A successful plan only."""
        if not self.success:
            raise ValueError(f"timed_task: the plan did not succeed ({self.status.value})")
        limits = limits or self.pick.limits
        parts = dict(self.timed(rate, limits=limits))
        closed = float(robot.info.finger_closed)
        for name in ("lift", "transfer"):
            parts[name].q = robot.with_fingers(parts[name].q, closed)
        q_grasp, q_place = parts["approach"].q[-1], parts["transfer"].q[-1]
        parts["close"] = joint_move(q_grasp, robot.with_fingers(q_grasp, closed), limits, rate, gripper_seconds)
        parts["release"] = joint_move(q_place, parts["retract"].q[0], limits, rate, gripper_seconds)
        order = [n for n in ("approach", "close", "lift", "transfer", "release", "retract") if n in parts]
        whole, spans = concatenate([parts[n] for n in order])
        return whole, [(n, t0, t1) for n, (t0, t1) in zip(order, spans)]

    def to_dict(self) -> dict:
        """JSON-ready: status, reason, segments, held object, place pose, timings (seconds)."""
        d = {
            "status": self.status.value,
            "reason": self.reason,
            "pick_status": self.pick.status.value,
            "segments": [{"name": n, "waypoints": np.asarray(Q).tolist()} for n, Q in self.segments()],
            "timings": {k: float(v) for k, v in self.timings.items()},
        }
        if self.held is not None:
            d["held"] = self.held.to_dict()
        if self.place_pose is not None:
            d["place_pose"] = np.asarray(self.place_pose).tolist()
        if self.place is not None:
            d["place_status"] = self.place.status.value
            d["place_metrics"] = {
                k: (bool(v) if isinstance(v, (bool, np.bool_)) else float(v))
                for k, v in self.place.metrics.to_dict().items()
            }
        if self.place_goals is not None:
            d["place_goal_reasons"] = self.place_goals.reason_counts()
            d["place_goal_set"] = np.asarray(self.place_goals.goal_set.goals).tolist()
        return d


def _path_clear(carrying: HeldWorld, path: np.ndarray, contact_until: int) -> bool:
    """Every configuration of a straight path clear: the held object may touch its support in the
    first ``contact_until`` configurations. A world without meshes (perceived) checks body points in
    its field instead (the target and the table left out, as the success test does)."""
    support, carry = carrying.checker(HeldCheck.support), carrying.checker(HeldCheck.carry)
    if carry is None:
        X = carrying.robot.transform_points(path, carrying.body)
        d, _ = carrying.sdf.distance(X.reshape(-1, 3), cutoff=0.05, exclude=(carrying.target,), exclude_table=True)
        return bool(d.min() >= 0.0)
    return not any((support if k < contact_until else carry).in_collision(q) for k, q in enumerate(path))


def _retract_checker(world, place_pose: np.ndarray) -> Optional[collision.CollisionChecker]:
    """FCL for the robot alone with the object left at ``place_pose``: the open fingers may graze it
    and the table (they were around it, next to its support)."""
    if not hasattr(world, "scene_meshes"):
        return None
    robot = world.robot
    meshes = [
        collision.SceneMesh(m.name, m.mesh, place_pose if m.name == world.target else m.pose)
        for m in world.scene_meshes()
    ]
    moving = set(robot.moving_links())
    allowed = tuple((n, "table") for i, n in enumerate(robot.link_names) if i not in moving) + tuple(
        (f, o) for f in robot.finger_links for o in (world.target, "table")
    )
    table = collision.Table(tuple(np.asarray(world.scene.table.size, float)), np.asarray(world.scene.table.pose, float))
    return collision.CollisionChecker(
        robot,
        meshes,
        table,
        collision.CollisionSettings(allowed_pairs=allowed),
        shapes=world.cache.shapes,
        link_meshes=world.cache.link_meshes(robot),
    )


class PickPlacePlanner:
    """Pick and place with an OMG planner (``OMGPlanner`` or ``PerceivedPlanner``): ``plan`` does the whole
    task; ``plan_pick``, ``attach``, ``plan_lift``, ``plan_place`` and ``plan_retract`` are its steps."""

    def __init__(
        self,
        planner: OMGPlanner,
        request: PlaceRequest,
        settings: PickPlaceSettings = PickPlaceSettings(),
        transfer=None,
    ):
        """``transfer(world, q0, goal_set) -> PlanResult``: another planner for the transfer (a baseline);
        None: Algorithm 2 (``planner.plan_to_goal_set`` with ``settings.place``)."""
        self.planner, self.request, self.settings = planner, request, settings
        self.transfer = transfer
        # what the timings read: the place's StageClock (thread_cpu: a loaded machine's other processes do not count)
        self.clock = settings.place.clock.timer()

    @property
    def world(self):
        return self.planner.world()

    def plan_pick(self, start=None, grasps=None) -> PlanResult:
        return self._plan_pick(start, grasps, set())[0]

    def _plan_pick(self, start, grasps, fell: set) -> Tuple[PlanResult, Optional[GoalSet]]:
        """The pick and its goal set (``verified_pick``: its grasp lifted in PyBullet first)."""
        return verified_pick(self.planner, start, grasps, self.settings.verify_pick, fell, self.clock)

    def attach(self, q_grasp: np.ndarray, held: Optional[HeldObject] = None) -> HeldWorld:
        """The world while carrying: the target held as ``q_grasp`` grasps it (or as ``held`` says: the
        grasp actually executed)."""
        world = self.world
        return HeldWorld(world, held if held is not None else held_from_plan(world, q_grasp, self.settings.attach))

    def prepare(self, carrying: HeldWorld) -> None:
        """What the place planning of ``carrying`` reads that depends on the grasp only (the robot with
        the held object: FCL models, the CHOMP problem, the clearance problem), built before it is timed."""
        for kind in (HeldCheck.carry, HeldCheck.hand, HeldCheck.support):
            carrying.checker(kind)
        carrying.clearance_problem
        tail = self.settings.goals.goals.standoff_steps + 1
        carrying.chomp(replace(self.settings.place.chomp, obstacle_tail=tail))

    def plan_lift(self, carrying: HeldWorld, q_grasp: np.ndarray) -> Tuple[np.ndarray, bool]:
        """The straight lift (see ``PickPlaceSettings``) and whether it is reachable and clear."""
        s = self.settings
        normal, _ = carrying.support_plane
        steps = int(round(s.lift_max / s.lift_step))
        path, good = straight_path_steps(carrying.robot, q_grasp, normal, steps * s.lift_step, steps)
        need = s.place.metrics.clearance
        first = int(round(s.lift_min / s.lift_step))
        X = carrying.robot.transform_points(path[first:], carrying.body)
        # measured as the success test measures (the transfer starts here, and its test reads this start)
        d, _ = carrying.sdf.distance(
            X.reshape(-1, 3), cutoff=need, exclude=(carrying.target,), exclude_table=True, reference=True
        )
        clear = np.flatnonzero(d.reshape(len(X), -1).min(axis=1) >= need)
        path = path[: first + (int(clear[0]) if len(clear) else len(X) - 1) + 1]
        contact = int(np.ceil(s.lift_contact / s.lift_step)) + 1
        return path, bool(np.all(good[: len(path) - 1])) and _path_clear(carrying, path, contact)

    def plan_place(self, carrying: HeldWorld, start: np.ndarray) -> Tuple[PlaceGoalSet, Optional[PlanResult]]:
        """The place goal set from ``start`` (the lifted configuration) and the transfer to it (None
        when the set is empty)."""
        goals = self._place_goal_set(carrying, start, self._goal_settings())
        if len(goals) == 0:
            return goals, None
        if self.transfer is not None:
            return goals, self.transfer(carrying, start, goals.goal_set)
        gs, n = goals.goal_set, self.settings.place.chomp.n
        warm = upright_initialization(carrying, start, gs.tails, n) if self.settings.upright_carry else None
        return goals, plan_to_goal_set(self.settings.place, carrying, start, gs, warm)

    def _place_goal_set(self, carrying: HeldWorld, start: np.ndarray, settings: PlaceSettings) -> PlaceGoalSet:
        model = getattr(carrying.base, "models", {}).get(carrying.target)  # its stable resting poses
        return build_place_goal_set(carrying, self.request, start, settings, model, clock=self.clock)

    def _goal_settings(self) -> PlaceSettings:
        """The place goal sets' settings, their set-down's clearance checked between its configurations as
        densely as the transfer's success test interpolates it (``MetricSettings.steps`` over the CHOMP
        waypoints): at the configurations alone a bowl's set-down kept 1 cm there and 0.92 cm between."""
        s, place = self.settings.goals, self.settings.place
        substeps = max(s.goals.approach_substeps, math.ceil(place.metrics.steps / max(place.chomp.n, 1)))
        return replace(s, goals=replace(s.goals, approach_substeps=substeps))

    def plan_retract(self, q_place: np.ndarray, place_pose: np.ndarray) -> Tuple[np.ndarray, bool]:
        s, world = self.settings, self.world
        up = np.array([0.0, 0.0, 1.0])
        path, ok = straight_path(world.robot, q_place, up, s.retract, s.retract_steps)
        checker = _retract_checker(world, place_pose)
        return path, ok and (checker is None or not any(checker.in_collision(q) for q in path[1:]))

    def plan(self, start=None, grasps=None) -> PickPlacePlan:
        t0 = self.clock()
        fell: set = set()
        pick, pick_goals = self._plan_pick(start, grasps, fell)
        timings = {"pick": pick.timings.get("total", 0.0)}
        if not pick.success:
            return PickPlacePlan(
                PickPlaceStatus.pick_failed, f"pick: {pick.status.value} {pick.reason}".strip(), pick, timings=timings
            )
        plan = self.plan_after_pick(pick, timings=timings, t0=t0)
        if plan.status in REGRASP and self.settings.regrasp_plans > 0:
            plan = self._regrasp(plan, pick_goals, start, t0, fell)
        return plan

    def _regrasp(self, failed: PickPlacePlan, pick_goals, start, t0: float, fell: set) -> PickPlacePlan:
        """``failed``'s pick planned again among the pick's other goals that have a place goal
        (``PickPlaceSettings.regrasp_plans``); ``failed`` (its reason saying how many were screened) when
        none of them completes the task."""
        s, t = self.settings, self.clock()
        tried, rounds, placeable = {failed.pick.grasp_index} | fell, 0, []
        supply = self._placeable(pick_goals, tried)
        while rounds < s.regrasp_plans:
            placeable += itertools.islice(supply, s.regrasp_candidates - len(placeable))  # topped up
            if not placeable:
                break
            rounds += 1
            dropped: set = set()  # candidates whose grasp fell in the pick's lift
            pick = self._plan_pick(start, pick_goals.grasps[placeable], dropped)[0]
            if not pick.success or pick.grasp_index < 0:
                placeable = []  # no pick among them: the next round's candidates are new ones
                continue
            chosen = placeable[pick.grasp_index]  # an index into the first pick's grasps again
            placeable = [k for i, k in enumerate(placeable) if i not in dropped and k != chosen]
            pick.grasp_index = chosen
            plan = self.plan_after_pick(pick, timings=dict(failed.timings, pick=pick.timings.get("total", 0.0)))
            plan.timings["regrasp"] = self.clock() - t
            if plan.success:
                plan.timings["total"] = self.clock() - t0
                plan.reason = (
                    f"regrasp: {failed.status.value} with the first grasp, {len(tried) - 1} other goals screened"
                )
                return plan
        failed.timings["regrasp"] = self.clock() - t
        failed.reason += f" (regrasp: {len(tried) - 1} other pick goals screened, {rounds} plans)"
        return failed

    def _placeable(self, pick_goals, tried: set) -> Iterator[int]:
        """The pick goals' grasps (indices) not in ``tried`` whose grasp lifts clear and has one place goal
        (the goal set stops at one), in the goal set's order, screened lazily; each is added to ``tried``."""
        settings = self._goal_settings()
        settings = replace(settings, goals=replace(settings.goals, max_goals=1))
        for index, q_grasp in zip(pick_goals.grasp_index, pick_goals.goals):
            if int(index) in tried:
                continue
            tried.add(int(index))
            carrying = self.attach(q_grasp)
            lift, ok = self.plan_lift(carrying, q_grasp)
            if ok and len(self._place_goal_set(carrying, lift[-1], settings)):
                yield int(index)

    def plan_after_pick(
        self,
        pick: PlanResult,
        held: Optional[HeldObject] = None,
        start: Optional[np.ndarray] = None,
        timings: Optional[dict] = None,
        t0: Optional[float] = None,
    ) -> PickPlacePlan:
        """Lift, place and retract after ``pick`` (the grasp as planned, or ``held``: as executed). With
        ``start`` (the configuration after a lift already executed) no lift is planned: the place starts there."""
        timings = dict(timings or {})
        t = self.clock()
        carrying = self.attach(pick.goal, held)
        self.prepare(carrying)
        timings["attach"] = self.clock() - t
        t = self.clock()
        if start is None:
            lift, ok = self.plan_lift(carrying, pick.goal)
        else:
            lift, ok = np.asarray(start, dtype=float)[None], True
        timings["lift"] = self.clock() - t
        plan = PickPlacePlan(
            PickPlaceStatus.lift_blocked,
            "lift: unreachable or in collision",
            pick,
            lift,
            carrying.held,
            timings=timings,
            carry_speed=self.settings.carry_speed,
        )
        if not ok:
            return plan
        t = self.clock()
        goals, place = self.plan_place(carrying, lift[-1])
        timings["place"] = self.clock() - t
        plan.place_goals, plan.place = goals, place
        if place is None:
            plan.status, plan.reason = PickPlaceStatus.no_place_goals, reason_summary(goals)
            return plan
        if not place.success:
            plan.status, plan.reason = PickPlaceStatus.place_failed, f"transfer: {place.status.value}"
            return plan
        plan.place_pose = goals.object_poses[place.grasp_index]
        t = self.clock()
        plan.retract, ok = self.plan_retract(place.goal, plan.place_pose)
        timings["retract"] = self.clock() - t
        if t0 is not None:
            timings["total"] = self.clock() - t0
        plan.status, plan.reason = (
            (PickPlaceStatus.success, "")
            if ok
            else (PickPlaceStatus.retract_blocked, "retract: unreachable or in collision")
        )
        return plan


def pick_and_place(
    scene, request: PlaceRequest, robot=None, settings: PickPlaceSettings = PickPlaceSettings(), grasps=None
) -> PickPlacePlan:
    """The whole task in one call: plan the pick of ``scene.target`` and its place as ``request`` asks."""
    return PickPlacePlanner(OMGPlanner(robot, scene, settings.pick), request, settings).plan(grasps=grasps)
