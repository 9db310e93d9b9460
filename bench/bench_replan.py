"""Warm-started replanning after the target moved (issue 36): per generated scene, a plan from scratch,
then the target moved by ``--shift`` m in a seeded horizontal direction and planned again two ways:
the warm replan (``omg.replan.Replanner``: objects moved in place, goals followed, the last
trajectory as the start) and a fresh plan of the moved scene (a new ``World`` sharing the model
cache, Algorithm 2 from scratch). Both are timed on the planning thread's CPU clock (the move
included for the warm one) and, with ``--execute``, executed in PyBullet on the moved scene.

    .venv/bin/python bench/bench_replan.py --scenes 40 --shift 0.02 --execute --out out/bench/replan
"""

from __future__ import annotations

import argparse
import csv
import os
import time
from dataclasses import replace

import numpy as np

from pickplan.core.io import atomic_open
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.replan import Replanner
from pickplan.omg.world import World
from pickplan.sim import scenes
from pickplan.sim.execution import execute_plan

FIELDS = (
    "scene",
    "first_success",
    "warm_success",
    "warm_ms",
    "warm_iterations",
    "warm_goals",
    "fresh_success",
    "fresh_ms",
    "fresh_iterations",
    "warm_lifted",
    "fresh_lifted",
)


def moved(scene, shift: float, rng):
    angle = rng.uniform(0, 2 * np.pi)
    o = scene.object(scene.target)
    T = np.array(o.pose, float)
    T[:2, 3] += shift * np.array([np.cos(angle), np.sin(angle)])
    return replace(scene, objects=[replace(x, pose=T) if x.name == scene.target else x for x in scene.objects]), T


def run_scene(seed: int, shift: float, execute: bool, settings: OMGSettings, cache) -> dict:
    scene = scenes.generate_scene(seed)
    planner = OMGPlanner(None, scene, settings, world=World(scene, settings.world, cache=cache))
    replanner = Replanner(planner)
    first = replanner.plan()
    row = {"scene": seed, "first_success": first.success}
    moved_scene, T = moved(scene, shift, np.random.default_rng(seed))
    t = time.thread_time()
    warm = replanner.replan(moved={scene.target: T})
    row.update(
        warm_success=warm.success,
        warm_ms=1000 * (time.thread_time() - t),
        warm_iterations=warm.iterations,
        warm_goals=warm.goal_set_size,
    )
    fresh_world = World(moved_scene, settings.world, cache=cache)
    t = time.thread_time()
    fresh = OMGPlanner(None, moved_scene, settings, world=fresh_world).plan()
    row.update(fresh_success=fresh.success, fresh_ms=1000 * (time.thread_time() - t), fresh_iterations=fresh.iterations)
    if execute:
        for name, result in (("warm", warm), ("fresh", fresh)):
            row[f"{name}_lifted"] = bool(result.success and execute_plan(moved_scene, result.trajectory).success)
    return row


def summary(rows) -> str:
    def rate(key):
        vals = [r[key] for r in rows if r.get(key) is not None and r["first_success"]]
        return f"{100 * np.mean(vals):.0f} % ({sum(vals)}/{len(vals)})" if vals else "-"

    planned = [r for r in rows if r["first_success"]]
    lines = [
        "| | warm replan | fresh plan |",
        "|---|---|---|",
        f"| success test passed | {rate('warm_success')} | {rate('fresh_success')} |",
        f"| lifted in PyBullet | {rate('warm_lifted')} | {rate('fresh_lifted')} |",
        f"| median ms CPU (p90) | {np.median([r['warm_ms'] for r in planned]):.1f} "
        f"({np.percentile([r['warm_ms'] for r in planned], 90):.1f}) | "
        f"{np.median([r['fresh_ms'] for r in planned]):.1f} ({np.percentile([r['fresh_ms'] for r in planned], 90):.1f}) |",
        f"| median iterations | {np.median([r['warm_iterations'] for r in planned]):.0f} | "
        f"{np.median([r['fresh_iterations'] for r in planned]):.0f} |",
    ]
    return "\n".join(lines) + f"\n\n{len(planned)} of {len(rows)} scenes planned from scratch first.\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0, help="first scene seed")
    ap.add_argument("--shift", type=float, default=0.02, help="m the target moves")
    ap.add_argument("--execute", action="store_true", help="execute both plans in PyBullet")
    ap.add_argument("--out", default="out/bench/replan")
    args = ap.parse_args()
    from pickplan.omg.model_cache import ModelCache

    settings, cache = OMGSettings(grasp_kind="antipodal", clock="thread_cpu"), ModelCache()
    rows = [run_scene(s, args.shift, args.execute, settings, cache) for s in range(args.seed, args.seed + args.scenes)]
    os.makedirs(args.out, exist_ok=True)
    with atomic_open(os.path.join(args.out, "runs.csv"), "w") as f:
        writer = csv.DictWriter(f, FIELDS)
        writer.writeheader()
        writer.writerows(rows)
    text = summary(rows)
    with atomic_open(os.path.join(args.out, "table.md"), "w") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
