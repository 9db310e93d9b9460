"""One unit of a sweep (``experiments``): a scene, a method and a run planned, and executed in PyBullet,
into one flat record; and the grasp sets the units share, generated once beforehand."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import List, Optional, Sequence

import numpy as np

from pickplan.core.description import robot_info
from pickplan.core.objects import model_from_source
from pickplan.core.timing import robot_limits, time_parameterize
from pickplan.eval.baselines import OMPL_PLANNERS, BaselineSettings, plan_baseline
from pickplan.eval.methods import method_spec
from pickplan.eval.plots import STAGES
from pickplan.omg import grasps as grasps_mod
from pickplan.omg.grasps import GraspKind, GraspSet
from pickplan.omg.grasps.generators import SupportFilter
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.planner import OMGPlanner, PlanStatus, target_graspability
from pickplan.omg.world import CheckerKind, World, WorldSettings
from pickplan.sim.execution import ExecutionSettings, execute_plan
from pickplan.sim.scenes import Scene


def _grasps_job(job: dict) -> dict:
    """Generate (and cache on disk) an object's grasp set once, before the units need it."""

    try:
        grasps_mod.grasp_set(
            model_from_source(job["name"], job["source"]),
            job["kind"],
            job["n"],
            seed=0,
            gripper=robot_info(job.get("robot", "panda")),
            progress=False,
        ) if job["kind"] == "simulated" else None
    except (ValueError, TypeError):
        pass  # no such set (e.g. graspit for the built-ins): the units report it
    return job


def grasp_jobs(units: Sequence[dict]) -> List[dict]:
    seen = {}
    for u in units:
        target = u["scene"]["target"]
        src = next(o["source"] for o in u["scene"]["objects"] if o["name"] == target)
        kind = u.get("grasp_kind") or method_spec(u["table"], u["method"]).grasp_kind
        robot = u.get("robot", "panda")
        seen[(target, src, kind, robot)] = {
            "name": target,
            "source": src,
            "kind": kind,
            "n": u["grasp_candidates"],
            "robot": robot,
        }
    return list(seen.values())


# A sweep's worker plans scene after scene of the same objects, and every method of a scene plans with
# the same generated grasps: one bounded ModelCache per worker process holds SDF grids, FCL shapes, the
# robot, surface samples and generated grasp sets. Records do not depend on it (the same values are
# built either way); it only spares rebuilding them.
_WORKER_MODELS = ModelCache()


def _unit_grasps(world: World, scene: Scene, kind: str, n: int, robot: str) -> GraspSet:
    """The unit's grasp set of the target (its poses, and what the generator rejected)."""
    aware = (
        {
            "support": SupportFilter.under(
                world.target_pose, robot=world.robot, plane=world.support_plane, approach=world.open_approach()
            )
        }
        if kind == "antipodal"
        else {}
    )

    def build():
        return grasps_mod.grasp_set(world.target_model, kind, n, seed=0, gripper=world.robot.info, **aware)

    if kind not in ("antipodal", "approach"):  # stored sets: read from disk
        return build()
    source = next(o.source for o in scene.objects if o.name == scene.target)
    key = ("grasps", kind, scene.target, source, np.asarray(world.target_pose).tobytes(), robot, int(n))
    gs = world.cache.derived(key, build)
    return replace(gs, poses=gs.poses.copy())  # a unit may not change what the next one reads


def finite(x: float) -> Optional[float]:
    """A float for a JSON record: None for nan (not measured)."""
    return float(x) if np.isfinite(x) else None


def run_unit(unit: dict) -> dict:
    """Plan (and execute) one unit; returns its flat record. Deterministic for a given unit."""

    t0 = time.perf_counter()
    spec = method_spec(unit["table"], unit["method"])
    if unit.get("grasp_kind"):
        spec = replace(spec, grasp_kind=GraspKind.parse(unit["grasp_kind"], "grasp set kind"))
    scene = Scene.from_dict(unit["scene"])
    seed = int(unit["seed"])
    record = {
        "table": unit["table"],
        "scene": unit["scene_name"],
        "target": scene.target,
        "method": unit["method"],
        "run": unit["run"],
        "seed": seed,
        "grasp_kind": spec.grasp_kind,
    }
    world_settings = WorldSettings(robot=unit.get("robot", "panda"))
    world = World(scene, world_settings, cache=_WORKER_MODELS)
    verdict = target_graspability(world)  # geometry, whatever the method: ungraspable units are counted apart
    if not verdict.graspable:
        record.update(
            status=PlanStatus.ungraspable,
            reason=f"ungraspable: {verdict.reason}",
            valid=True,
            graspable=False,
            planned=False,
            planning_success=False,
            execution_success=False,
            execution_run=bool(unit["execute"]),
            unit_seconds=time.perf_counter() - t0,
        )
        return record
    # Scene setup (FCL meshes), not goal-set or planning time; only the OMPL baselines validate
    # states with the "obstacles" checker.
    for kind in (CheckerKind.goal, CheckerKind.hand) + (
        (CheckerKind.obstacles,) if spec.baseline in OMPL_PLANNERS else ()
    ):
        world.checker(kind)
    try:
        grasps = _unit_grasps(world, scene, spec.grasp_kind, unit["grasp_candidates"], world_settings.robot)
    except ValueError as exc:  # e.g. no stored graspit set for a built-in object: not a planning failure
        record.update(
            status=PlanStatus.no_grasps,
            reason=str(exc),
            valid=False,
            planning_success=False,
            execution_success=False,
            unit_seconds=time.perf_counter() - t0,
        )
        return record
    omg = spec.omg_settings(unit["grasps"], unit["grasp_candidates"], unit["iterations"], seed, world_settings)
    chomp = omg.chomp

    def plan(poses):
        if spec.baseline is None:
            return OMGPlanner(None, scene, omg, world=world).plan(grasps=poses)
        bs = BaselineSettings(
            omg=omg,
            max_goals_tried=unit["max_goals_tried"],
            chomp_iterations=unit["iterations"],
            time_limit=unit["time_limit"],
        )
        return plan_baseline(spec.baseline, scene, bs, world=world, grasps=poses)

    result = plan(grasps.poses)
    dense = omg.denser_grasp_count()
    if result.status == PlanStatus.no_goals and dense and dense > len(grasps):  # as the planner's own default grasps
        first_goal_set_time = result.timings.get("goal_set", 0.0)
        grasps = _unit_grasps(world, scene, spec.grasp_kind, dense, world_settings.robot)
        result = plan(grasps.poses)
        result.timings["goal_set"] = result.timings.get("goal_set", 0.0) + first_goal_set_time
    if len(grasps) == 0:  # a graspable target the generator found nothing for: say what it rejected
        result.goal_reasons = {"no_candidates": 1, **{f"candidates {k}": v for k, v in grasps.rejected.items() if v}}
    planned = result.planned
    m = result.metrics
    record.update(
        status=result.status,
        valid=True,
        graspable=True,
        planned=planned,
        goal_reasons=dict(result.goal_reasons) if result.status == PlanStatus.no_goals else {},
        planning_success=bool(result.success),
        goal_set_size=result.goal_set_size,
        iterations=result.iterations,
        refined=bool(result.refined),
        goal_set_time=float(result.timings.get("goal_set", 0.0)),
        plan_time=float(result.timings["total"] - result.timings.get("goal_set", 0.0)),
        smoothness=float(m.smoothness) if planned else None,
        collision=float(m.collision) if planned else None,
        min_clearance=float(m.min_clearance) if planned else None,
        grasp_cost=float(world.grasp_refiner().cost(result.goal)[0].total) if planned else None,
        stage_times={k: float(result.timings.get(k, 0.0)) for k in STAGES},
    )
    if planned and omg.goals.quality is not None:  # how well the executed (maybe refined) grasp holds, by the model
        hand = np.linalg.inv(world.target_pose) @ result.hand_pose
        record["grasp_margin"] = finite(float(world.grasp_quality(hand[None], omg.goals.quality).margin[0]))
    # The duration a controller needs: the path timed within the robot's velocity/acceleration limits.
    control_rate = 1.0 / ExecutionSettings.time_step  # samples at PyBullet's control rate: executed as they are
    timed = time_parameterize(result.trajectory, control_rate, robot_limits(world.robot)) if planned else None
    record["trajectory_duration"] = timed.duration if planned else None
    record.update(execution_success=False, execution_status="not_executed", execution_run=bool(unit["execute"]))
    if unit["execute"] and result.success:
        ex = execute_plan(
            scene,
            timed if unit.get("timed_execution") else result.trajectory,
            ExecutionSettings(robot=world_settings.robot, waypoint_dt=chomp.duration / chomp.n),
        )
        record.update(
            execution_success=bool(ex.success),
            execution_status=ex.status,
            execution_time=ex.seconds,
            execution_sim_time=ex.sim_time,
            slip=finite(ex.slip),
            slip_rotation=finite(ex.slip_rotation),
            grip_force=ex.grip_force,
            lift=finite(ex.lift),
            execution_message=ex.message,
        )
    record["unit_seconds"] = time.perf_counter() - t0
    return record


# --- sweeps ----------------------------------------------------------------------------------------
