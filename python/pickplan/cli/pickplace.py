"""``pickplan pickplace --scene S --place REGION.json``: plan a pick and place (and execute it in
PyBullet); ``--observation OBS.npz`` plans from depth images (the scene then only executes).

Writes to ``--out``: ``pickplace.json`` (both segments, timed within the robot's limits),
``plan.json`` + ``scene.json`` + ``view.html`` (the 3D view: the object carried and placed) and the
request as ``region.json``.
"""

from __future__ import annotations

import os
from typing import Optional

from pickplan.cli.exit_codes import ExitCode
from pickplan.cli.robots import ROBOT_HELP
from pickplan.core.errors import InputError
from pickplan.core.io import write_json
from pickplan.eval.pickplace import execute_in_sim
from pickplan.omg.grasps.sets import GraspKind
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.omg.pickplace import PickPlacePlan, PickPlacePlanner, PickPlaceSettings
from pickplan.omg.pickplace_file import pickplace_record, view_record
from pickplan.omg.place import PlaceRequest
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.selection import Selection
from pickplan.sim.scenes import Scene
from pickplan.sim.view import view_folder
from pickplan.sim.view_page import write_html


def summary(plan: PickPlacePlan) -> str:
    lines = [
        f"pick and place: {plan.status.value}" + (f" ({plan.reason})" if plan.reason else ""),
        f"  pick: {plan.pick.status.value}, {plan.pick.goal_set_size} goals, "
        f"{1000 * plan.pick.timings.get('total', 0.0):.1f} ms",
    ]
    if plan.place_goals is not None:
        lines.append(
            f"  place goal set: {len(plan.place_goals)} goals of {len(plan.place_goals.object_poses)} "
            f"candidates ({plan.place_goals.reason_counts()})"
        )
    if plan.place is not None:
        lines.append(
            f"  transfer: {plan.place.status.value}, {plan.place.iterations} iterations, place planning "
            f"{1000 * plan.timings.get('place', 0.0):.1f} ms (goal set + trajectory)"
        )
    return "\n".join(lines)


def write_outputs(
    out: str,
    scene: Optional[Scene],
    request: PlaceRequest,
    plan: PickPlacePlan,
    robot: str,
    execution: Optional[dict] = None,
    observed: bool = False,
) -> None:
    """pickplace.json, region.json; with a scene also scene.json, plan.json and view.html (``observed``: the
    plan is from depth; the view draws the scene's true target carried)."""
    os.makedirs(out, exist_ok=True)
    timed = plan.timed(1000.0) if plan.success else None
    write_json(os.path.join(out, "pickplace.json"), pickplace_record(plan, request, robot, timed, execution))
    write_json(os.path.join(out, "region.json"), request.to_dict())
    if scene is not None:
        scene.save(os.path.join(out, "scene.json"))
        frame = scene.object(scene.target).pose if observed else None
        write_json(os.path.join(out, "plan.json"), view_record(plan, robot, scene.target, frame))
        write_html(view_folder(out), os.path.join(out, "view.html"))


def run_pickplace(args) -> int:
    request = PlaceRequest.load(args.place)
    scene = Scene.load(args.scene) if args.scene else None
    pick = OMGSettings(selection=args.selection, grasp_kind=args.grasps, seed=args.seed)
    settings = PickPlaceSettings(pick=pick)
    if args.observation:
        world = PerceivedWorld.load(args.observation, robot=args.robot)
        planner = PickPlacePlanner(PerceivedPlanner(world, pick), request, settings)
    elif scene is None:
        raise InputError("expected --scene SCENE.json or --observation OBS.npz", field="--scene")
    else:
        planner = PickPlacePlanner(OMGPlanner(args.robot, scene, pick), request, settings)
    plan = planner.plan()
    print(summary(plan))
    executed = None
    if args.execute and plan.success:
        if scene is None:
            raise InputError("--execute needs --scene (the true objects to execute on)", field="--execute")
        frame = scene.object(scene.target).pose if args.observation else None
        ex = execute_in_sim(
            scene,
            planner,
            plan,
            request,
            planner.world.robot.info.name,
            **({"frame": frame} if frame is not None else {}),
        )
        executed = ex.to_dict()
        print(f"  executed: {ex.status.value}" + (f" ({ex.message})" if ex.message else ""))
    if args.out:
        write_outputs(
            args.out, scene, request, plan, planner.world.robot.info.name, executed, observed=bool(args.observation)
        )
        print(f"wrote {args.out}/pickplace.json, region.json" + (", scene.json, plan.json, view.html" if scene else ""))
    ok = plan.success and (executed is None or executed["success"])
    return ExitCode.OK if ok else ExitCode.NO_PLAN


def add_pickplace_command(sub) -> None:
    p = sub.add_parser("pickplace", help="plan (and execute) a pick and place: the target put where REGION.json asks")
    p.add_argument("--scene", default=None, help="scene JSON; with --observation only to --execute on")
    p.add_argument("--place", required=True, help="place request JSON: region min/max, orientation, yaw")
    p.add_argument("--observation", default=None, help="plan from depth images (.npz from `pickplan observe`)")
    p.add_argument("--selection", default=Selection.MD.value, choices=[s.value for s in Selection])
    p.add_argument("--grasps", default=GraspKind.simulated.value, choices=[k.value for k in GraspKind])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--robot", default="panda", help=ROBOT_HELP)
    p.add_argument("--execute", action="store_true", help="also execute it in PyBullet (needs --scene)")
    p.add_argument("--out", default=None, help="folder for pickplace.json, plan.json, scene.json, view.html")
    p.set_defaults(handler=run_pickplace)
