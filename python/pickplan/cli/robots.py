"""``pickplan robots``: the shipped robot descriptions, and a check of a user's description file."""
from __future__ import annotations

import argparse

from pickplan.core.description import shipped
from pickplan.core.description_check import check_description


def add_robot_commands(subparsers) -> None:
    p = subparsers.add_parser("robots", help="robot descriptions: list the shipped ones, check a file")
    sub = p.add_subparsers(dest="robots_command", required=True)
    sub.add_parser("list", help="the shipped robot descriptions").set_defaults(handler=run_list)
    check = sub.add_parser("check", help="validate a robot description (TOML) and name every problem")
    check.add_argument("file", help="a .toml description, or the name of a shipped one")
    check.set_defaults(handler=run_check)


def run_list(args: argparse.Namespace) -> int:
    for name in shipped():
        desc, problems = check_description(name)
        status = "ok" if not problems else f"{len(problems)} problem(s)"
        print(f"{name:14s} {desc.description if desc else '':70s} {status}")
    return 0


def run_check(args: argparse.Namespace) -> int:
    """0 when usable; 2 (bad input) with every problem listed otherwise."""
    desc, problems = check_description(args.file)
    if problems:
        print(f"{args.file}: {len(problems)} problem(s):")
        for p in problems:
            print(f"  - {p}")
        return 2
    g = desc.gripper
    print(f"{args.file}: ok: {desc.name}, {len(desc.arm_joints)} arm joints, gripper {g.hand_link} "
          f"opening {g.max_opening * 1000:.0f} mm")
    return 0
