"""Depth images to a planned trajectory (issue 36): the latency of one request, with its stages, for
one and three 640 x 480 views, as ``pickplan bench perception`` plans them (Table III's OMG settings,
the rendered target mask). The observations are rendered first (not timed); every request then goes
through one long-lived ``PerceivedPlanner`` (``plan(observation=...)``: the robot's data and the hand's
field kept across requests), after one warm-up request. CPU time, as the machine is shared: the
request's ``time.process_time``, its stages' thread CPU time; medians over the scenes.

    .venv/bin/python bench/bench_depth_latency.py --scenes 20 --views 1 3 --noise-mm 2 [--profile 1]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # one core per request, as every bench here (before numpy loads)

import argparse  # noqa: E402
import cProfile  # noqa: E402
import dataclasses  # noqa: E402
import pstats  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from pickplan.core.errors import InputError  # noqa: E402
from pickplan.eval.methods import Table, method_spec  # noqa: E402
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorldSettings  # noqa: E402
from pickplan.sim import scenes  # noqa: E402
from pickplan.sim.observe import render_observation  # noqa: E402

STAGES = ("plane", "field", "scene", "world", "grasps", "goal_set", "plan", "total")


def request(obs, planner: PerceivedPlanner) -> dict:
    """One request: CPU seconds per stage and in all."""
    t0 = time.process_time()
    result = planner.plan(observation=obs)
    total = time.process_time() - t0
    s = dict(planner.world().seconds)
    plan = float(result.timings["total"] - result.timings["goal_set"])
    return {
        "plane": s["plane"],
        "field": s["field"],
        "scene": s["scene"],
        "world": s["world"],
        "grasps": s["grasps"],
        "goal_set": float(result.timings["goal_set"]),
        "plan": plan,
        "total": total,
        "success": bool(result.success),
    }


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
        planner = PerceivedPlanner(
            settings=settings, world_settings=PerceivedWorldSettings(clock="thread_cpu")
        )  # long-lived: the robot's data built once
        request(observations[0], planner)  # warm-up: the robot's data and the hand's field
        if args.profile:
            prof = cProfile.Profile()
            prof.enable()
            for obs in observations[: args.profile]:
                request(obs, planner)
            prof.disable()
            pstats.Stats(prof).sort_stats(args.sort).print_stats(45)
        rows = [request(obs, planner) for obs in observations]
        med = [1000 * np.median([r[k] for r in rows]) for k in STAGES]
        ok = sum(r["success"] for r in rows)
        print(
            f"| {views} | {len(rows)} | " + " | ".join(f"{m:.1f}" for m in med) + f" | {ok}/{len(rows)} |", flush=True
        )


if __name__ == "__main__":
    main()
