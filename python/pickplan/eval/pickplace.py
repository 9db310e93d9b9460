"""``pickplan bench pickplace``: pick and place on generated scenes (issue 34).

A unit is one (scene, method, run). Every scene gets one place task (``place_regions``): scene i's
region is free (i % 3 == 0), partly cluttered (1) or inside a bin (2). The pick is the OMG planner's
(MD selection, C-Space ISF) for every method; the methods differ on the place segment (the transfer):

* ``OMG``: Algorithm 2 on the place goal set, MD selection (``omg.pickplace``);
* ``Fixed``: the same with Fixed selection (the initial estimate's best place goal, kept);
* ``CHOMP``: plain CHOMP through the ranked place goals, the first feasible (``eval.baselines``);
* ``RRT-C``: RRT-Connect to the ranked place goals' pre-places, the set-down appended;
* ``OMG-3v``: OMG planned from a depth observation of three views (``PerceivedWorld``): the held
  object is its observed points; executed on the true objects.

Successful plans are executed in PyBullet (``sim.pickplace_exec``): pick, lift, transfer, set-down,
release, retract. When the grasp as executed differs from the planned one (``replan_shift``,
``replan_angle_deg``), the place is planned again from the executed grasp before the transfer.
Every successful plan's carry (lift and transfer) is checked densely with FCL on the true meshes:
``held_collision`` says whether the held object touched anything it may not.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Optional

import numpy as np

from pickplan.core.ik import IkSettings
from pickplan.core.settings import Option
from pickplan.eval.baselines import BaselineSettings, plan_baseline_to_goal_set
from pickplan.eval.place_regions import RegionKind, place_task
from pickplan.eval.units import _WORKER_MODELS, _unit_grasps
from pickplan.omg.attach import HELD_LINK, HeldCheck, HeldWorld
from pickplan.omg.chomp import ChompSettings
from pickplan.omg.goals import GoalSetSettings
from pickplan.omg.pickplace import PickPlacePlan, PickPlacePlanner, PickPlaceSettings
from pickplan.omg.place import PlaceRequest
from pickplan.omg.planner import OMGPlanner, OMGSettings, target_graspability
from pickplan.omg.world import World, WorldSettings
from pickplan.sim.execution import ExecutionSettings
from pickplan.sim.pickplace_exec import PickPlaceExecSettings, PickPlaceExecution, PlaceCheck, execute_pick_and_place
from pickplan.sim.scenes import Scene

PICKPLACE_METHODS = ("OMG", "Fixed", "CHOMP", "RRT-C")
PERCEPTION_METHOD = "OMG-3v"
REPLAN_SHIFT = 0.003  # m: an executed grasp this far from the planned one is planned for again
REPLAN_ANGLE_DEG = 2.0
FALLBACK_SHIFT = 0.02  # m: a grasp changed by less, for which no place plan is found, keeps the planned place
FALLBACK_ANGLE_DEG = 15.0


def region_kind(scene_name: str) -> RegionKind:
    """Scene i's region: free, cluttered, bin in turn."""
    index = int(scene_name.rsplit("_", 1)[-1]) if scene_name.rsplit("_", 1)[-1].isdigit() else 0
    return (RegionKind.free, RegionKind.cluttered, RegionKind.bin)[index % 3]


def place_check(request: PlaceRequest, place_pose: np.ndarray) -> PlaceCheck:
    return PlaceCheck(
        request.region_min,
        request.region_max,
        np.asarray(place_pose, float),
        request.tolerance_deg,
        None if request.yaw_deg is None else request.yaw_tolerance_deg,
    )


def transfer_planner(method: str, settings: PickPlaceSettings, max_goals_tried: int = 5, time_limit: float = 1.0):
    """The transfer planner a method names: None (Algorithm 2: ``OMG``, ``Fixed``) or a baseline's."""
    if method not in ("CHOMP", "RRT-C"):
        return None
    bs = BaselineSettings(
        omg=settings.place,
        max_goals_tried=max_goals_tried,
        chomp_iterations=settings.place.iterations,
        time_limit=time_limit,
    )
    return lambda world, q0, goal_set: plan_baseline_to_goal_set(method, world, q0, goal_set, bs)


class CarryContact(Option):
    """What touched what it may not along a carry (``carry_contacts``)."""

    held = "held"  # the held object
    robot = "robot"  # a robot link (a finger on a bin's wall, a link on a neighbour)


def carry_contacts(plan: PickPlacePlan, carrying: HeldWorld, steps: int = 200) -> set:
    """Which of the held object and the robot (true meshes) touch what they may not along the lift and
    the transfer, densely: the support may be touched on the lift's first centimetre and the set-down."""
    support, carry = carrying.checker(HeldCheck.support), carrying.checker(HeldCheck.carry)
    segments = dict(plan.segments())
    set_down = plan.place_goals.goal_set.tails.shape[1]  # the transfer's last rows: pre-place to place
    found = set()
    for name in ("lift", "transfer"):
        Q = segments.get(name)
        if Q is None or len(Q) < 2:
            continue
        s = np.linspace(0.0, len(Q) - 1, steps)
        i = np.minimum(s.astype(int), len(Q) - 2)
        dense = Q[i] + (s - i)[:, None] * (Q[i + 1] - Q[i])
        for k, q in enumerate(dense):
            checker = support if (s[k] <= 1.0 if name == "lift" else s[k] >= len(Q) - set_down) else carry
            if checker.in_collision(q):
                held = {c.link == HELD_LINK for c in checker.contacts(q)}
                found |= {CarryContact.held if h else CarryContact.robot for h in held} or {CarryContact.robot}
    return found


def carry_fields(plan: PickPlacePlan, carrying: HeldWorld) -> dict:
    """The record's ``held_collision`` and ``robot_collision`` (``carry_contacts``)."""
    found = carry_contacts(plan, carrying)
    return {"held_collision": CarryContact.held in found, "robot_collision": CarryContact.robot in found}


def _grasp_change(planned: np.ndarray, executed: np.ndarray) -> tuple:
    d = np.linalg.inv(planned) @ executed
    angle = math.degrees(math.acos(float(np.clip((np.trace(d[:3, :3]) - 1) / 2, -1.0, 1.0))))
    return float(np.linalg.norm(d[:3, 3])), angle


def unit_settings(unit: dict, method: str, world_settings: WorldSettings) -> PickPlaceSettings:
    seed = int(unit["seed"])
    pick = OMGSettings(
        chomp=ChompSettings(),
        goals=GoalSetSettings(max_goals=unit["grasps"], seed=seed),
        ik=IkSettings(seed=seed),
        iterations=unit["iterations"],
        grasp_kind=unit.get("grasp_kind") or "simulated",
        grasp_count=unit["grasp_candidates"],
        seed=seed,
        world=world_settings,
        clock="thread_cpu",
    )
    place = replace(
        PickPlaceSettings().place,
        iterations=unit["iterations"],
        seed=seed,  # the transfer's defaults
        selection="Fixed" if method == "Fixed" else "MD",
        world=world_settings,
        clock="thread_cpu",
    )
    return PickPlaceSettings(pick=pick, place=place)


def execute_in_sim(
    scene,
    planner: PickPlacePlanner,
    plan: PickPlacePlan,
    request: PlaceRequest,
    robot: str,
    frame: np.ndarray = np.eye(4),
    info: Optional[dict] = None,
    record=None,
) -> PickPlaceExecution:
    """Execute ``plan`` in PyBullet, replanning the place when the grasp as executed differs from the
    planned one (``REPLAN_SHIFT``, ``REPLAN_ANGLE_DEG``); ``info`` receives the grasp change and whether
    it replanned. ``frame``: the true object frame in the planner's object frame (a perceived object's
    frame is the world at the observation: the true pose then). ``record``: frames to render."""
    rate = 1.0 / ExecutionSettings.time_step
    to_planner = np.linalg.inv(frame)
    info = {} if info is None else info

    def timed(p, names):
        return p.timed(rate, names)

    def replan(q_now, executed):
        executed = executed @ to_planner
        shift, angle = _grasp_change(plan.held.hand_T_object, executed)
        info.update(grasp_shift=shift, grasp_angle_deg=angle, replanned=False)
        if shift <= REPLAN_SHIFT and angle <= REPLAN_ANGLE_DEG:
            return timed(plan, ("transfer", "retract")), plan.place_pose @ frame
        info["replanned"] = True
        again = planner.plan_after_pick(plan.pick, held=replace(plan.held, hand_T_object=executed), start=q_now)
        if not again.success:
            info["replan_status"] = again.status.value
            if shift > FALLBACK_SHIFT or angle > FALLBACK_ANGLE_DEG:
                return None
            # a small change the place cannot be planned for again (a clearance lost by millimetres):
            # the planned place, as the planned grasp would have it
            return timed(plan, ("transfer", "retract")), plan.place_pose @ frame
        return timed(again, ("transfer", "retract")), again.place_pose @ frame

    return execute_pick_and_place(
        scene,
        timed(plan, ("approach", "lift")),
        place_check(request, plan.place_pose @ frame),
        PickPlaceExecSettings(ExecutionSettings(robot=robot)),
        record=record,
        replan=replan,
    )


def execute_unit_plan(
    unit, scene, planner: PickPlacePlanner, plan: PickPlacePlan, request, record, frame: np.ndarray = np.eye(4)
) -> None:
    """``execute_in_sim`` for a bench unit; fills ``record``."""
    ex = execute_in_sim(scene, planner, plan, request, unit.get("robot", "panda"), frame, info=record)
    record.update(
        complete=bool(ex.success),
        execution_status=ex.status.value,
        execution_message=ex.message,
        tilt_deg=ex.tilt_deg,
        max_moved=max(ex.object_displacements.values(), default=0.0),
        execution_time=ex.seconds,
    )


def unit_task(unit: dict) -> tuple:
    """The unit's scene (with its bin), place request, true world and first record fields; the record
    says ``graspable`` (a target no grasp of the gripper can hold is counted apart)."""
    kind = region_kind(unit["scene_name"])
    scene, request = place_task(Scene.from_dict(unit["scene"]), kind, seed=int(unit["scene"].get("seed") or 0))
    record = {
        "table": "pickplace",
        "scene": unit["scene_name"],
        "target": scene.target,
        "method": unit["method"],
        "run": unit["run"],
        "seed": int(unit["seed"]),
        "region": kind.value,
        "valid": True,
        "pick_success": False,
        "place_planned": False,
        "place_success": False,
        "complete": False,
        "execution_run": bool(unit["execute"]),
    }
    world = World(scene, WorldSettings(robot=unit.get("robot", "panda")), cache=_WORKER_MODELS)
    verdict = target_graspability(world)
    record["graspable"] = bool(verdict.graspable)
    if not verdict.graspable:
        record.update(status="ungraspable", reason=f"ungraspable: {verdict.reason}")
    return scene, request, world, record


def run_pickplace_unit(unit: dict) -> dict:
    """Plan (and execute) one pick-and-place unit; one flat record with the pick's and the place's outcomes."""
    t0 = time.perf_counter()
    method = unit["method"]
    scene, request, world, record = unit_task(unit)
    if not record["graspable"]:
        record["unit_seconds"] = time.perf_counter() - t0
        return record
    world_settings = world.settings
    settings = unit_settings(unit, method, world_settings)
    grasps = _unit_grasps(world, scene, settings.pick.grasp_kind, unit["grasp_candidates"], world_settings.robot).poses
    planner = PickPlacePlanner(
        OMGPlanner(None, scene, settings.pick, world=world),
        request,
        settings,
        transfer=transfer_planner(method, settings, unit["max_goals_tried"], unit["time_limit"]),
    )
    plan = planner.plan(grasps=grasps)
    record.update(plan_fields(plan))
    if plan.success:
        record.update(carry_fields(plan, planner.attach(plan.pick.goal, plan.held)))
        if unit["execute"]:
            execute_unit_plan(unit, scene, planner, plan, request, record)
    record["unit_seconds"] = time.perf_counter() - t0
    return record


def plan_fields(plan: PickPlacePlan) -> dict:
    out = {
        "status": plan.status.value,
        "reason": plan.reason,
        "pick_status": plan.pick.status.value,
        "pick_success": plan.pick.success,
        "pick_time": float(plan.pick.timings.get("total", 0.0)),
        "attach_time": plan.timings.get("attach"),
        "lift_time": plan.timings.get("lift"),
        "regrasp_time": plan.timings.get("regrasp"),  # other grasps screened and planned (None: not tried)
    }
    if plan.place_goals is not None:
        out.update(
            place_goals=len(plan.place_goals),
            place_goal_set_time=float(plan.place_goals.seconds),
            place_verdict=plan.place_goals.verdict.value,
        )
    if plan.place is not None:
        m = plan.place.metrics
        out.update(
            place_planned=True,
            place_success=plan.place.success,
            place_status=plan.place.status.value,
            place_time=float(plan.timings.get("place", 0.0)),
            place_plan_time=float(plan.place.timings.get("total", 0.0) - plan.place.timings.get("goal_set", 0.0)),
            place_smoothness=float(getattr(m, "smoothness", float("nan"))),
            place_clearance=float(getattr(m, "min_clearance", float("nan"))),
            place_iterations=int(plan.place.iterations),
        )
    if plan.success:
        out["duration"] = float(sum(t.duration for _, t in plan.timed(250.0)))
    return out
