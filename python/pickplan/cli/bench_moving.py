"""``pickplan bench moving``: moving targets (a conveyor at several speeds, a nudge) picked in PyBullet by
the closed loop, with its baselines (replans from scratch, one plan) in the same run (``eval.moving_bench``)."""

from __future__ import annotations

import argparse
from dataclasses import replace

from pickplan.eval.moving import LoopSettings, MovingMethod
from pickplan.eval.moving_bench import MovingBenchSettings, run_moving_bench, summary


def run_moving_command(args: argparse.Namespace) -> int:
    loop = replace(LoopSettings(), rate=args.rate)
    settings = MovingBenchSettings(
        out=args.out,
        speeds=tuple(v / 100 for v in args.speeds),
        nudge=args.nudge / 100,
        scenes=args.scenes,
        seed=args.seed,
        methods=tuple(args.methods),
        workers=args.workers,
        loop=loop,
        progress=False if args.no_progress else None,
    )
    print(summary(settings, run_moving_bench(settings)))
    print(f"wrote {settings.out}/summary.md, {settings.out}/units/<case>_<method>/runs.csv")
    return 0


def add_moving_command(sub) -> None:
    p = sub.add_parser("moving", help="moving targets: a conveyor and a nudge, closed loop beside its baselines")
    p.add_argument(
        "--speeds",
        type=float,
        nargs="+",
        default=[0.0, 5.0, 10.0, 20.0],
        help="conveyor speeds in cm/s (default 0 5 10 20)",
    )
    p.add_argument("--nudge", type=float, default=4.0, help="cm the still target is pushed once (0: no nudge case)")
    p.add_argument("--scenes", type=int, default=100, help="generated scenes per case (default 100)")
    p.add_argument("--seed", type=int, default=0, help="first scene seed")
    p.add_argument(
        "--methods",
        nargs="+",
        default=[m.value for m in MovingMethod],
        choices=[m.value for m in MovingMethod],
        help="default: all three",
    )
    p.add_argument("--rate", type=float, default=LoopSettings().rate, help="replans per second (default 5)")
    p.add_argument("--workers", type=int, default=1, help="local worker processes (<= 1: serial)")
    p.add_argument("--out", default="out/bench/moving", help="output folder (default out/bench/moving); resumes there")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(handler=run_moving_command)
