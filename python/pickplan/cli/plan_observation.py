"""``pickplan plan --observation OBS.npz [--scene S --execute] [--out DIR]``: the OMG planner on what
depth cameras saw (``omg.perceived_world``). The scene file, when given, is used only to execute the
plan in PyBullet on the true objects, never to plan."""

from __future__ import annotations

import argparse
import os

from pickplan.cli.exit_codes import ExitCode
from pickplan.core.errors import InputError
from pickplan.core.io import write_json, write_text
from pickplan.core.observation import Observation
from pickplan.eval.demo import metrics_table
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.core import robots
from pickplan.omg.plan_file import plan_record
from pickplan.omg.planner import OMGSettings, PlanStatus
from pickplan.sim import execution
from pickplan.sim.scenes import Scene


def run_plan_observation(args: argparse.Namespace, settings: OMGSettings) -> int:
    if args.execute and not args.scene:
        raise InputError("--execute needs --scene: the true objects the plan is executed on", field="--execute")
    observation = Observation.load(args.observation)  # an InputError names the file and the bad field
    scene = Scene.load(args.scene) if args.scene else None  # loaded up front: a bad file fails before planning
    world = PerceivedWorld(observation, robots.load_robot(args.robot))
    result = PerceivedPlanner(world, settings).plan()
    executed = (
        execution.execute_plan(scene, result.trajectory, execution.ExecutionSettings(robot=args.robot))
        if args.execute and result.status != PlanStatus.no_goals
        else None
    )
    table = metrics_table(result, executed)
    seconds = world.seconds
    table += (
        f"From {observation.views} depth view(s): field {seconds['plane'] + seconds['field'] + seconds['scene']:.3f} s, "
        f"{len(world.perceived.target_points)} target points, grasps from points {seconds['grasps']:.3f} s "
        "(no object mesh or stored grasp read).\n"
    )
    print(table)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        write_text(os.path.join(args.out, "metrics.md"), table)
        if scene is not None:  # beside the plan: `pickplan view` reads both
            scene.save(os.path.join(args.out, "scene.json"))
        write_json(
            os.path.join(args.out, "plan.json"), plan_record(result, world, executed.to_dict() if executed else None)
        )
    return ExitCode.OK if result.success else ExitCode.NO_PLAN
