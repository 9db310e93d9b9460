"""``pickplan scenes``: write a benchmark set of generated scenes (one JSON each, plus index.json).

Wired into ``pickplan.cli.main`` through ``add_scene_commands``.
"""

from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence, Tuple

from pickplan.cli.exit_codes import run_command
from pickplan.cli.output import add_verbosity_options, configure_logging, level_of
from pickplan.sim.layouts import Layout
from pickplan.sim.scene_sets import write_scene_set
from pickplan.sim.scenes import ORIENTATIONS, SceneSettings


def clutter_range(text: str) -> Tuple[int, int]:
    """'8-12' -> (8, 12); a single number N means exactly N objects."""
    lo, sep, hi = text.partition("-")
    try:
        pair = (int(lo), int(hi) if sep else int(lo))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N-M (e.g. 8-12), got {text!r}") from None
    if not 1 <= pair[0] <= pair[1]:
        raise argparse.ArgumentTypeError(f"expected 1 <= N <= M, got {text!r}")
    return pair


def add_scene_commands(subparsers) -> None:
    """Add ``scenes`` to a ``pickplan`` argparse sub-parser set."""
    p = subparsers.add_parser("scenes", help="generate a benchmark set of cluttered tabletop scenes (JSON)")
    p.add_argument("--n", type=int, default=100, help="number of scenes")
    p.add_argument("--seed", type=int, default=0, help="seed of the set (each scene gets its own derived seed)")
    p.add_argument("--out", required=True, help="output folder: scene_XXXX.json and index.json")
    p.add_argument(
        "--objects",
        default=None,
        help="'builtin' (YCB stand-ins), 'procedural' (generated families: thin, flat, small, tools, "
        "handles) or a YCB-layout object folder (default: $PICKPLAN_YCB_DIR if set, else builtin)",
    )
    p.add_argument(
        "--poses",
        "--orientation",
        dest="poses",
        choices=ORIENTATIONS,
        default="upright",
        help="upright (the paper's protocol); stable: a resting pose drawn with the probability a random "
        "drop ends on it (lying bottles, boxes on any face); resting: any stable pose, uniformly",
    )
    p.add_argument(
        "--clutter",
        type=clutter_range,
        default=(SceneSettings.min_objects, SceneSettings.max_objects),
        metavar="N-M",
        help="objects per scene, fewest-most (default 3-7, the paper's)",
    )
    p.add_argument(
        "--robot",
        default="panda",
        help="the robot the scenes are made for (a shipped description, a short name such as 'ur5', or a "
        ".toml file): it stands at its start while objects settle, and the target is one its "
        "gripper can grasp (default panda)",
    )
    p.add_argument(
        "--layout",
        choices=[k.value for k in Layout],
        default=Layout.table.value,
        help="table (the default), shelf (boards at several heights, reached from the front), bin (walls "
        "on the table, reached from above) or cabinet (an open door and a drawer)",
    )
    p.set_defaults(handler=run_scenes)


def run_scenes(args: argparse.Namespace) -> int:
    index = write_scene_set(
        args.n,
        args.seed,
        args.out,
        args.objects,
        orientation=args.poses,
        clutter=args.clutter,
        robot=args.robot,
        layout=args.layout,
    )
    per = index["seconds"] / max(index["count"], 1)
    print(f"wrote {index['count']} scenes to {args.out} ({per:.2f} s per scene, objects: {index['objects']})")
    return 0


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="pickplan", description=__doc__)
    add_scene_commands(parser.add_subparsers(dest="command", required=True))
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_logging(level_of(args))
    code = run_command(args.command, args.handler, args)
    if code:  # as argparse does for its own errors: the stand-alone entry exits
        raise SystemExit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
