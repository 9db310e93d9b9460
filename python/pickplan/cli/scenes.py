"""``pickplan scenes``: write a benchmark set of generated scenes (one JSON each, plus index.json).

Wired into ``pickplan.cli.main`` through ``add_scene_commands``.
"""
from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence

from pickplan.cli.exit_codes import run_command
from pickplan.sim.scene_sets import write_scene_set


def add_scene_commands(subparsers) -> None:
    """Add ``scenes`` to a ``pickplan`` argparse sub-parser set."""
    p = subparsers.add_parser("scenes", help="generate a benchmark set of cluttered tabletop scenes (JSON)")
    p.add_argument("--n", type=int, default=100, help="number of scenes")
    p.add_argument("--seed", type=int, default=0, help="seed of the set (each scene gets its own derived seed)")
    p.add_argument("--out", required=True, help="output folder: scene_XXXX.json and index.json")
    p.add_argument("--objects", default=None,
                   help="YCB-layout object folder (default: $PICKPLAN_YCB_DIR if set, else the built-in objects)")
    p.add_argument("--orientation", choices=("upright", "resting"), default="upright",
                   help="upright (the paper's protocol) or any stable resting pose (lying boxes, upside-down bowls)")
    p.set_defaults(handler=run_scenes)


def run_scenes(args: argparse.Namespace) -> int:
    index = write_scene_set(args.n, args.seed, args.out, args.objects, orientation=args.orientation)
    per = index["seconds"] / max(index["count"], 1)
    print(f"wrote {index['count']} scenes to {args.out} ({per:.2f} s per scene, objects: {index['objects']})")
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="pickplan", description=__doc__)
    add_scene_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    code = run_command(args.command, args.handler, args)
    if code:  # as argparse does for its own errors: the stand-alone entry exits
        raise SystemExit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
