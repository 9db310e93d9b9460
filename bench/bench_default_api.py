"""The README's API in a loop over scenes of known objects (issue 36): a new ``OMGPlanner(None, scene)``
per scene (each with its own model cache) against one long-lived planner asked ``plan(scene=...)``
(its cache keeps the SDFs, FCL shapes, robot data and grasp sets of the objects it has seen). The
long-lived planner is timed on its second pass over the scenes, when every object is known. CPU time
of the planning thread per scene (world, grasps, goal set, plan).

    .venv/bin/python bench/bench_default_api.py --scenes 20
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.sim import scenes


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0, help="first scene seed")
    ap.add_argument("--grasp-kind", default="antipodal")
    args = ap.parse_args()
    settings = OMGSettings(grasp_kind=args.grasp_kind)
    all_scenes = [scenes.generate_scene(s) for s in range(args.seed, args.seed + args.scenes)]
    fresh, fresh_ok = [], 0
    for scene in all_scenes:
        t = time.thread_time()
        fresh_ok += OMGPlanner(None, scene, settings).plan().success
        fresh.append(time.thread_time() - t)
    planner = OMGPlanner(None, settings=settings)
    for scene in all_scenes:  # the first pass meets every object once
        planner.plan(scene=scene)
    known, known_ok = [], 0
    for scene in all_scenes:
        t = time.thread_time()
        known_ok += planner.plan(scene=scene).success
        known.append(time.thread_time() - t)
    n = len(all_scenes)
    print("| per scene | median ms CPU | p90 | success |\n|---|---|---|---|")
    for name, ts, ok in (("new planner per scene", fresh, fresh_ok), ("one planner, objects known", known, known_ok)):
        print(f"| {name} | {1000 * np.median(ts):.0f} | {1000 * np.percentile(ts, 90):.0f} | {ok}/{n} |")


if __name__ == "__main__":
    main()
