"""``pickplan bench mbm``: the MotionBenchMaker problem sets (the field's benchmark) with pickplan and
its baselines in one run, every path through the independent checker (``eval.mbm``)."""

from __future__ import annotations

import argparse

from pickplan.eval.mbm import DEFAULT_PLANNERS, SETS, MbmPlanner, MbmSettings, run_mbm
from pickplan.eval.mbm_planners import vamp_module


def run_mbm_command(args: argparse.Namespace) -> int:
    settings = MbmSettings(
        problems=args.problems,
        sets=tuple(args.sets),
        planners=tuple(args.planners),
        robot_dir=args.robot_dir,
        out=args.out,
        workers=args.workers,
        limit=args.limit,
        time_limit=args.time_limit,
        seed=args.seed,
        progress=False if args.no_progress else None,
    )
    if MbmPlanner.vamp in settings.planners and vamp_module() is None:
        print(
            "VAMP is not importable here: its rows are left out (build it with "
            "../shared/tools/vamp/build-vamp.sh .venv/bin/python panda)"
        )
    run_mbm(settings)
    with open(f"{settings.out}/summary.md", encoding="utf-8") as f:
        print(f.read())
    print(f"wrote {settings.out}/runs.csv, summary.md")
    return 0


def add_mbm_command(sub) -> None:
    p = sub.add_parser("mbm", help="MotionBenchMaker problems: pickplan beside OMPL and VAMP, checked independently")
    p.add_argument(
        "--problems",
        required=True,
        help="the problem archive (read in place, e.g. ../shared/data/mbm/problems_panda.tar.bz2) or a "
        "folder holding problems/<set>/sceneNNNN.yaml and requestNNNN.yaml",
    )
    p.add_argument("--sets", nargs="+", default=list(SETS), help="problem sets (default: the five Panda sets)")
    p.add_argument(
        "--planners",
        nargs="+",
        default=[q.value for q in DEFAULT_PLANNERS],
        choices=[q.value for q in MbmPlanner],
        help="planners (default: pickplan ompl vamp)",
    )
    p.add_argument("--robot-dir", default=None, help="the Panda model folder (default: panda/ beside the problems)")
    p.add_argument("--out", default="out/bench/mbm", help="output folder (default out/bench/mbm)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (default 1: times on one core)")
    p.add_argument("--limit", type=int, default=0, help="only problems with an index below this (0: all)")
    p.add_argument("--time-limit", type=float, default=10.0, help="seconds per problem and planner")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(handler=run_mbm_command)
