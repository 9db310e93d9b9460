"""The ``OMG-3v`` unit of ``bench pickplace``: the whole pick and place planned from a depth
observation of three views (``PerceivedWorld``: no mesh, no stored grasp; the held object is its
observed points), executed on the true objects; the carry is checked on the true meshes."""

from __future__ import annotations

import time

import numpy as np

from pickplan.eval.pickplace import carry_fields, execute_unit_plan, plan_fields, unit_settings, unit_task
from pickplan.omg.attach import HeldWorld, held_from_poses
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.omg.pickplace import PickPlacePlanner
from pickplan.sim.observe import render_observation

VIEWS = 3


def run_perceived_pickplace_unit(unit: dict) -> dict:
    t0 = time.perf_counter()
    scene, request, true_world, record = unit_task(unit)
    if not record["graspable"]:
        record["unit_seconds"] = time.perf_counter() - t0
        return record
    try:
        world = PerceivedWorld(
            render_observation(scene, views=VIEWS, seed=int(unit["seed"])),
            robot=true_world.robot,
            cache=true_world.cache,
        )
    except ValueError as exc:  # the target hidden from every camera: a failed pick, said why
        record.update(status="no_world", reason=str(exc), unit_seconds=time.perf_counter() - t0)
        return record
    settings = unit_settings(unit, "OMG", true_world.settings)
    planner = PickPlacePlanner(PerceivedPlanner(world, settings.pick), request, settings)
    plan = planner.plan()
    record.update(plan_fields(plan))
    if plan.success:
        robot = true_world.robot
        truth = true_world.target_pose  # the true object frame in the perceived one (the world at the observation)
        hand = robot.link_pose(plan.pick.goal, robot.hand_link)
        held = held_from_poses(scene.target, hand, truth, true_world.target_model.mesh)
        record.update(carry_fields(plan, HeldWorld(true_world, held)))
        if unit["execute"]:
            execute_unit_plan(unit, scene, planner, plan, request, record, frame=np.asarray(truth))
    record["unit_seconds"] = time.perf_counter() - t0
    return record
