"""The ``pickplan`` command line.

  pickplan demo                          the main job: plan + execute a grasp in clutter
  pickplan plan --scene SCENE.json       plan (and optionally execute) one scene
  pickplan plan --observation OBS.npz    plan from depth images (--scene S --execute: run on the true objects)
  pickplan pickplace --scene S --place REGION.json   pick the target and put it down in a region (--execute)
  pickplan scenes --n 100 --out DIR      generate a benchmark set of scenes
  pickplan bench selection|refinement|planners|ablation   the paper's Tables I-III and Fig. 8
  pickplan metamodel build|compare       pick-up on the move: grasp-success meta-model
  pickplan pickup cases                  pick-up on the move: the paper's six cases, Tables I-IV
  pickplan pickup plan|problems|replay   pick-up on the move: one problem file, random problems, replay
  pickplan view DIR [--html FILE]        a 3D view of a plan folder (live server, or a self-contained page)
  pickplan ros serve|call                the ROS 2 node (pip install 'pickplan[ros]')

Exit codes (cli/exit_codes.py): 0 success, 1 ran but no plan, 2 bad input, 3 internal error.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import Optional, Sequence

from pickplan.omg.grasps.sets import GraspKind
from pickplan.omg.selection import Selection
from pickplan.cli.exit_codes import ExitCode, run_command
from pickplan.cli.output import add_verbosity_options, configure_logging, level_of
from pickplan.eval.demo import DemoSettings, run_demo
from pickplan.eval.demo_place import run_demo_place
from pickplan.cli.pickplace import add_pickplace_command
from pickplan.sim import execution
from pickplan.eval.demo import metrics_table
from pickplan.core.io import write_json, write_text
from pickplan.omg.plan_file import plan_record
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.sim.scenes import Scene
from pickplan.cli.scenes import add_scene_commands
from pickplan.cli.bench import add_bench_commands
from pickplan.cli.robots import ROBOT_HELP, add_robot_commands
from pickplan.cli.view import add_view_commands
from pickplan.cli.observe import add_observe_commands
from pickplan.cli.ros import add_ros_commands
from pickplan.cli.plan_observation import run_plan_observation
from pickplan.core.errors import InputError


def _cmd_demo(args) -> int:
    run = (run_demo_place if args.place else run_demo)(args.out, DemoSettings(seed=args.seed, robot=args.robot))
    print()
    print(run.table)
    print(f"wrote {args.out}/{', '.join(run.files)} ({run.seconds:.1f} s)")
    return ExitCode.OK if run.lifted else ExitCode.NO_PLAN


def _cmd_plan(args) -> int:

    settings = OMGSettings(
        selection=args.selection,
        refine=not args.no_refine,
        iterations=args.iterations,
        grasp_kind=args.grasps,
        seed=args.seed,
    )
    if args.observation:  # the scene, if any, only for execution
        return run_plan_observation(args, settings)
    if not args.scene:
        raise InputError("expected --scene SCENE.json or --observation OBS.npz", field="--scene")
    scene = Scene.load(args.scene)
    planner = OMGPlanner(args.robot, scene, settings)
    result = planner.plan()
    executed = (
        execution.execute_plan(scene, result.trajectory, execution.ExecutionSettings(robot=args.robot))
        if args.execute and result.planned
        else None
    )
    table = metrics_table(result, executed)
    print(table)
    if result.reason:
        print(result.reason)
    if args.out:
        os.makedirs(args.out, exist_ok=True)
        write_text(os.path.join(args.out, "metrics.md"), table)
        scene.save(os.path.join(args.out, "scene.json"))  # beside the plan: `pickplan view` reads both
        write_json(
            os.path.join(args.out, "plan.json"),
            plan_record(result, planner.world(), executed.to_dict() if executed else None),
        )
    return ExitCode.OK if result.success else ExitCode.NO_PLAN


# Groups whose modules import what the other commands never need (scikit-learn: a third of the start-up of
# `pickplan plan`): imported when their command runs or every command is listed, else a stub names them.
LAZY_GROUPS = {
    "metamodel": ("pickplan.cli.metamodel", "add_metamodel_commands", "pick-up-on-the-move success meta-model"),
    "pickup": ("pickplan.cli.pickup", "add_pickup_commands", "pick-up on the move (Thakar et al.)"),
}


def _add_group(sub, name: str, loaded: bool) -> None:
    module, add, help = LAZY_GROUPS[name]
    if loaded:
        getattr(importlib.import_module(module), add)(sub, help=help)
    else:
        sub.add_parser(name, help=help)


def build_parser(command: Optional[str] = None) -> argparse.ArgumentParser:
    """Every command's parser; with ``command`` (the one about to run) the other lazy groups are stubs."""
    parser = argparse.ArgumentParser(prog="pickplan", description="Joint motion and grasp planning.")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="plan and execute a grasp in a generated cluttered scene")
    demo.add_argument("--out", default="out/demo", help="folder for the picture and the metrics table")
    demo.add_argument("--seed", type=int, default=1, help="scene seed")
    demo.add_argument("--robot", default="panda", help=ROBOT_HELP)
    demo.add_argument(
        "--place", action="store_true", help="pick and place: put the target down in a free region beside the clutter"
    )
    demo.set_defaults(handler=_cmd_demo)
    plan = sub.add_parser("plan", help="plan one scene (JSON from `pickplan scenes`) or one depth observation")
    plan.add_argument("--scene", default=None, help="scene JSON; with --observation only to --execute on")
    plan.add_argument(
        "--observation",
        default=None,
        help="plan from depth images (.npz from `pickplan observe`): no mesh or stored grasp is read",
    )
    plan.add_argument("--selection", default=Selection.MD.value, choices=[s.value for s in Selection])
    plan.add_argument("--grasps", default=GraspKind.simulated.value, choices=[k.value for k in GraspKind])
    plan.add_argument("--iterations", type=int, default=50)
    plan.add_argument("--no-refine", action="store_true", help="turn C-Space ISF off")
    plan.add_argument("--execute", action="store_true", help="also execute the plan in PyBullet")
    plan.add_argument("--seed", type=int, default=0)
    plan.add_argument("--robot", default="panda", help=ROBOT_HELP)
    plan.add_argument("--out", default=None, help="folder for metrics.md, plan.json and scene.json")
    plan.set_defaults(handler=_cmd_plan)

    add_scene_commands(sub)
    add_bench_commands(sub)
    for name in LAZY_GROUPS:
        _add_group(sub, name, loaded=command is None or command == name)
    add_robot_commands(sub)
    add_view_commands(sub)
    add_observe_commands(sub)
    add_pickplace_command(sub)
    add_ros_commands(sub)
    add_verbosity_options(parser)  # last: on every command registered above
    return parser


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # ROS's own arguments (`pickplan ros serve ... --ros-args -p a:=1`) pass through unparsed
    ros_args = argv[argv.index("--ros-args") :] if "--ros-args" in argv else []
    command = next((a for a in argv if not a.startswith("-")), None)
    args = build_parser(command).parse_args(argv[: len(argv) - len(ros_args)])
    args.ros_args = ros_args
    configure_logging(level_of(args))
    handler = getattr(args, "handler", None) or getattr(args, "func")
    return run_command(args.command, handler, args)


if __name__ == "__main__":
    sys.exit(main())
