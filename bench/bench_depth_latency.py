"""Depth images to a planned trajectory (issue 36): the latency of one request, with its stages, for
one and three 640 x 480 views, as ``pickplan bench perception`` plans them (Table III's OMG settings,
the rendered target mask). The observations are rendered first (not timed); every request then goes
through one long-lived planner (``perceived_world``'s ``PerceivedPlanner``-for-frames path: the robot's
data and the hand's field kept across requests), after one warm-up request. CPU time
(``time.process_time``: the machine is shared) per stage, medians over the scenes.

    .venv/bin/python bench/bench_depth_latency.py --scenes 20 --views 1 3 --noise-mm 2 [--profile 1]
"""
from __future__ import annotations

import argparse
import dataclasses
import cProfile
import pstats
import time

import numpy as np

from pickplan.core.errors import InputError
from pickplan.eval.methods import Table, method_spec
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.sim import scenes
from pickplan.sim.observe import render_observation

STAGES = ("plane", "field", "scene", "world", "grasps", "goal_set", "plan", "total")


def request(obs, settings, cache: ModelCache) -> dict:
    """One request, CPU seconds per stage (the world's own timers read ``time.process_time``)."""
    t0 = time.process_time()
    world = PerceivedWorld(obs, cache=cache)
    result = PerceivedPlanner(world, settings).plan()
    total = time.process_time() - t0
    s = dict(world.seconds)
    plan = float(result.timings["total"] - result.timings["goal_set"])
    return {"plane": s["plane"], "field": s["field"], "scene": s["scene"], "world": s["world"],
            "grasps": s["grasps"], "goal_set": float(result.timings["goal_set"]), "plan": plan, "total": total,
            "success": bool(result.success)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--seed", type=int, default=0, help="first scene seed")
    ap.add_argument("--views", type=int, nargs="+", default=[1, 3])
    ap.add_argument("--noise-mm", type=float, default=2.0)
    ap.add_argument("--sort", default="cumulative", help="cProfile sort key")
    ap.add_argument("--profile", type=int, default=0, help="cProfile this many requests per view count; print the top")
    args = ap.parse_args()
    settings = method_spec(Table.planners, "OMG").omg_settings(30, 100, 50, 0)
    settings = dataclasses.replace(settings, clock="thread_cpu")
    all_scenes = [scenes.generate_scene(s) for s in range(args.seed, args.seed + args.scenes)]
    print(f"| views | requests | {' | '.join(STAGES)} (ms CPU, median) | success |")
    print("|---" * (len(STAGES) + 3) + "|")
    for views in args.views:
        observations = []
        for k, sc in enumerate(all_scenes):
            try:
                observations.append(render_observation(sc, views=views, noise=args.noise_mm / 1000, seed=k))
            except InputError:  # the target hidden from every camera: no request to time
                continue
        cache = ModelCache()
        request(observations[0], settings, cache)  # warm-up: the robot's data and the hand's field
        if args.profile:
            prof = cProfile.Profile()
            prof.enable()
            for obs in observations[:args.profile]:
                request(obs, settings, cache)
            prof.disable()
            pstats.Stats(prof).sort_stats(args.sort).print_stats(45)
        rows = [request(obs, settings, cache) for obs in observations]
        med = [1000 * np.median([r[k] for r in rows]) for k in STAGES]
        ok = sum(r["success"] for r in rows)
        print(f"| {views} | {len(rows)} | " + " | ".join(f"{m:.1f}" for m in med) + f" | {ok}/{len(rows)} |", flush=True)


if __name__ == "__main__":
    main()
