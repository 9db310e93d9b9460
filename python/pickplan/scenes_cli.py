"""``pickplan scenes``: write a benchmark set of generated scenes (one JSON each, plus index.json).

Wired into ``pickplan.cli`` through ``add_scene_commands``; also runs on its own:
``python -m pickplan.scenes_cli scenes --n 3 --out /tmp/s``.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import List, Optional, Sequence, TextIO

import numpy as np

from .io import write_json


def scene_seeds(seed: int, n: int) -> List[int]:
    """Independent per-scene seeds derived from the set's seed (scene i is reproducible on its own)."""
    return [int(s) for s in np.random.SeedSequence(int(seed)).generate_state(n, dtype=np.uint32)]


def _progress(done: int, total: int, started: float, stream: TextIO, width: int = 30) -> None:
    filled = width * done // max(total, 1)
    elapsed = time.perf_counter() - started
    rate = elapsed / done if done else 0.0
    stream.write(f"\rscenes [{'#' * filled}{'.' * (width - filled)}] {done}/{total}  {rate:.2f} s/scene")
    if done == total:
        stream.write("\n")
    stream.flush()


def write_scene_set(n: int, seed: int, out: str, objects: Optional[str] = None,
                    progress: bool = True, stream: Optional[TextIO] = None, orientation: str = "upright") -> dict:
    """Generate ``n`` scenes into ``out`` (scene_0000.json, ...) and return the index it writes.

    The progress bar goes to ``stream`` (default: the current ``sys.stderr``).
    """
    from . import objects as objects_mod
    from .scenes import SceneSettings, generate_scene

    if n < 1:
        raise ValueError(f"--n must be >= 1, got {n}")
    lib = objects_mod.library(objects)  # None: $PICKPLAN_YCB_DIR, else the built-ins
    settings = SceneSettings(orientation=orientation)
    os.makedirs(out, exist_ok=True)
    started = time.perf_counter()
    entries = []
    for i, s in enumerate(scene_seeds(seed, n)):
        t0 = time.perf_counter()
        scene = generate_scene(s, lib, settings)
        fname = f"scene_{i:04d}.json"
        scene.save(os.path.join(out, fname))
        entries.append({"file": fname, "seed": s, "target": scene.target,
                        "objects": [o.name for o in scene.objects], "seconds": round(time.perf_counter() - t0, 4)})
        if progress:
            _progress(i + 1, n, started, stream if stream is not None else sys.stderr)
    index = {"count": n, "seed": seed, "objects": lib.source, "orientation": orientation, "scenes": entries,
             "seconds": round(time.perf_counter() - started, 3)}
    write_json(os.path.join(out, "index.json"), index)
    return index


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
    try:
        return args.handler(args)
    except (FileNotFoundError, ValueError) as exc:
        parser.exit(2, f"pickplan {args.command}: error: {exc}\n")


if __name__ == "__main__":
    sys.exit(main())
