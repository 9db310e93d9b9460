"""``pickplan robots``: the shipped robot descriptions, and a check of a user's description file."""

from __future__ import annotations

import argparse

from pickplan.core import objects as objects_mod
from pickplan.core.description import robot_info, shipped, shipped_name
from pickplan.core.robots import check_description
from pickplan.omg.grasps import HandObjectChecker, load_grasp_set

ROBOT_HELP = (
    "the robot: a shipped description (`pickplan robots list`; a short name such as 'iiwa' or 'ur5' "
    "is the part of one shipped name before its first '_') or a .toml description file; default panda"
)


def add_robot_commands(subparsers) -> None:
    p = subparsers.add_parser("robots", help="robot descriptions: list the shipped ones, check a file")
    sub = p.add_subparsers(dest="robots_command", required=True)
    sub.add_parser("list", help="the shipped robot descriptions").set_defaults(handler=run_list)
    check = sub.add_parser("check", help="validate a robot description (TOML) and name every problem")
    check.add_argument("file", help="a .toml description, or the name of a shipped one")
    check.set_defaults(handler=run_check)
    grasps = sub.add_parser(
        "grasps", help="how many of each object's stored (Panda) grasps convert to a robot's gripper"
    )
    grasps.add_argument("robot", help=ROBOT_HELP)
    grasps.add_argument("--objects", required=True, help="a YCB object folder")
    grasps.add_argument("--kind", default="simulated", help="stored set: simulated or graspit")
    grasps.set_defaults(handler=run_grasps)


def run_list(args: argparse.Namespace) -> int:
    for name in shipped():
        desc, problems = check_description(name)
        status = "ok" if not problems else f"{len(problems)} problem(s)"
        print(f"{name:14s} {desc.description if desc else '':70s} {status}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """0 when usable; 2 (bad input) with every problem listed otherwise: exactly the problems that
    make every other command (``--robot FILE``) refuse the file (one path: ``robots.load_robot``)."""
    desc, problems = check_description(args.file)
    if problems:
        print(f"{args.file}: {len(problems)} problem(s):")
        for p in problems:
            print(f"  - {p}")
        return 2
    g = desc.gripper
    print(
        f"{args.file}: ok: {desc.name}, {len(desc.arm_joints)} arm joints, gripper {g.hand_link} "
        f"opening {g.max_opening * 1000:.0f} mm"
    )
    return 0


def run_grasps(args: argparse.Namespace) -> int:
    """A markdown table: per object, the stored grasps and how many fit the gripper (``convert_grasps``)."""
    info = robot_info(args.robot)
    library = objects_mod.library(args.objects)
    print(
        f"| object | stored {args.kind} | kept for {shipped_name(args.robot) if '.' not in args.robot else info.name} |"
    )
    print("|---|---|---|")
    total = kept = 0
    for name in library.names:
        model = library.get(name)
        if args.kind not in model.grasps:
            continue
        n, k = len(model.grasps[args.kind]), len(load_grasp_set(model, args.kind, info, HandObjectChecker))
        total, kept = total + n, kept + k
        print(f"| {name} | {n} | {k} ({100.0 * k / max(n, 1):.0f} %) |")
    print(f"| all | {total} | {kept} ({100.0 * kept / max(total, 1):.0f} %) |")
    return 0
