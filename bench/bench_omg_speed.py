"""Issue 24: OMG against RRT-Connect on Table III scenes, and a new scene end to end, in one run.

    PICKPLAN_YCB_DIR=../shared/data/ycb .venv/bin/python bench/bench_omg_speed.py [--scenes 40] [--repeat 5]

Scenes are the Table III set (``pickplan bench planners --objects YCB``: scene seeds from
``scene_seeds(0, N)``, the YCB objects), settings are the paper's as the sweep uses them (n = 30,
N = 50, 30 goals, MD with ISF, simulated grasps). Plan time is what the sweep records: the total
less the goal set. RRT-Connect is the Table III baseline (``eval.baselines``: the same goal
ranking, the same success test). Per scene, OMG and RRT-C plans alternate ``--repeat`` times and
each keeps its median; the medians over scenes are printed, with the per-scene ratio.

A new scene: every scene's objects are seen once first (a warm-up pass: object models, disk SDF
caches and whatever the world keeps per object), then per scene a fresh ``World`` and one
``OMGPlanner.plan`` (checkers, ISF data, goal set and plan) are timed together.

The process is pinned to one core (``--core``) but for the last part, ``plan_many`` scaling: the
same plans (worlds built) on 1 and on 2 threads, unpinned. The load average is printed with the
figures, since the machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from dataclasses import replace

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from pickplan.core import objects  # noqa: E402
from pickplan.core.ik import IkSettings
from pickplan.eval.baselines import BaselineSettings, plan_baseline  # noqa: E402
from pickplan.omg import grasps as grasps_mod  # noqa: E402
from pickplan.omg.goals import GoalSetSettings  # noqa: E402
from pickplan.omg.planner import OMGPlanner, OMGSettings  # noqa: E402
from pickplan.omg.world import World  # noqa: E402
from pickplan.sim import scenes  # noqa: E402
from pickplan.sim.scene_sets import scene_seeds  # noqa: E402

STAGES = ("chomp", "costs", "selection", "isf", "metrics")


def load_scenes(n: int, ycb: str, folder: str):
    """The Table III scenes, generated once into ``folder`` and loaded from there afterwards."""
    os.makedirs(folder, exist_ok=True)
    out = []
    lib = objects.library(ycb)
    for i, seed in enumerate(scene_seeds(0, n)):
        path = os.path.join(folder, f"scene_{i:04d}.json")
        if not os.path.exists(path):
            scenes.generate_scene(seed, lib).save(path)
        out.append(scenes.Scene.load(path))
    return out


def paper_settings() -> OMGSettings:
    return OMGSettings(
        goals=GoalSetSettings(max_goals=30, seed=0),
        ik=IkSettings(seed=0),
        selection="MD",
        refine=True,
        iterations=50,
        grasp_kind="simulated",
        grasp_count=100,
        seed=0,
    )


def plan_time(result) -> float:
    return result.timings["total"] - result.timings.get("goal_set", 0.0)


def new_world(scene, settings, cache):
    return World(scene, settings.world) if cache is None else World(scene, settings.world, cache=cache)


def thread_scaling(scene_list, worlds, grasps, settings, workers: int, rounds: int = 3):
    """Wall time of planning every scene on 1 thread and on ``workers`` threads (best of ``rounds``)."""
    try:
        from pickplan.omg.batch import PlanJob, plan_many
    except ImportError:
        return None
    jobs = [PlanJob(s, grasps=g, world=w) for s, g, w in zip(scene_list, grasps, worlds)]
    out = {}
    for n in (1, workers):
        best = float("inf")
        for _ in range(rounds):
            t = time.perf_counter()
            plan_many(jobs, settings, workers=n)
            best = min(best, time.perf_counter() - t)
        out[n] = best
    return out


def make_cache():
    """The per-object cache the world takes, when this version of pickplan has one."""
    try:
        from pickplan.omg.world import ModelCache
    except ImportError:
        return None
    return ModelCache()


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=5, help="OMG / RRT-C plans per scene, alternating")
    ap.add_argument("--ycb", default=os.environ.get("PICKPLAN_YCB_DIR", "../shared/data/ycb"))
    ap.add_argument("--scene-dir", default="out/bench_omg_speed/scenes")
    ap.add_argument("--core", type=int, default=None, help="pin to this CPU (default: the current one)")
    ap.add_argument("--no-rrt", action="store_true", help="OMG only")
    ap.add_argument("--threads", type=int, default=2, help="plan_many threads for the scaling figure (0: skip)")
    ap.add_argument(
        "--clock",
        choices=("wall", "cpu"),
        default="wall",
        help="cpu: every timing in this process (the planners' stage timings too) reads this "
        "thread's CPU time, so other processes' load does not count (for a shared machine)",
    )
    args = ap.parse_args(argv)
    if args.clock == "cpu":
        time.perf_counter = time.thread_time  # bench-only: the planners time their stages with perf_counter
        args.threads = 0  # thread scaling is a wall-clock figure
    core = args.core if args.core is not None else os.sched_getaffinity(0).pop()
    os.sched_setaffinity(0, {core})
    print(f"pinned to CPU {core}; clock: {args.clock}; load before: {os.getloadavg()}", flush=True)

    settings = replace(paper_settings(), clock="thread_cpu" if args.clock == "cpu" else "wall")
    baseline = BaselineSettings(omg=settings)
    scene_list = load_scenes(args.scenes, args.ycb, args.scene_dir)
    cache = make_cache()
    print(f"{len(scene_list)} scenes; per-object cache: {'yes' if cache is not None else 'no'}", flush=True)

    # Warm-up: every object seen once (grasp sets, disk caches, the per-object cache if any).
    grasps = []
    t = time.perf_counter()
    for scene in scene_list:
        world = new_world(scene, settings, cache)
        grasps.append(
            grasps_mod.grasp_set(
                world.target_model, settings.grasp_kind, settings.grasp_count, seed=settings.seed
            ).poses
        )
        OMGPlanner(None, scene, settings, world=world).plan(grasps=grasps[-1])
    print(f"warm-up pass {time.perf_counter() - t:.1f} s", flush=True)

    rows, worlds = [], []
    for i, scene in enumerate(scene_list):
        t = time.perf_counter()
        world = new_world(scene, settings, cache)
        worlds.append(world)
        t_world = time.perf_counter() - t
        first = OMGPlanner(None, scene, settings, world=world).plan(grasps=grasps[i])
        t_new = time.perf_counter() - t
        omg_runs, rrt_runs = [], []
        for _ in range(args.repeat):
            omg_runs.append(OMGPlanner(None, scene, settings, world=world).plan(grasps=grasps[i]))
            if not args.no_rrt:
                rrt_runs.append(plan_baseline("RRT-C", scene, baseline, world=world, grasps=grasps[i]))
        row = {
            "new": t_new,
            "world": t_world,
            "prepare": first.timings["prepare"],
            "goal_set": first.timings["goal_set"],
            "first_plan": plan_time(first),
            "omg": median([plan_time(r) for r in omg_runs]),
            "rrt": median([plan_time(r) for r in rrt_runs]),
            "omg_ok": omg_runs[0].success,
            "rrt_ok": bool(rrt_runs and rrt_runs[0].success),
            "goals": omg_runs[0].goal_set_size,
            "its": omg_runs[0].iterations,
        }
        for k in STAGES:
            row[k] = median([r.timings[k] for r in omg_runs])
        row["python"] = median([plan_time(r) - sum(r.timings[k] for k in STAGES) for r in omg_runs])
        rows.append(row)
        print(
            f"scene {i:2d}: goals {row['goals']:2d} its {row['its']:2d} omg {1e3 * row['omg']:6.2f} ms "
            f"({'ok' if row['omg_ok'] else 'FAIL'})  rrt-c {1e3 * row['rrt']:6.2f} ms "
            f"({'ok' if row['rrt_ok'] else 'FAIL'})  new scene {1e3 * t_new:6.1f} ms "
            f"(world {1e3 * t_world:.1f}, checkers+isf {1e3 * row['prepare']:.1f}, "
            f"goal set {1e3 * row['goal_set']:.1f}, plan {1e3 * row['first_plan']:.1f})",
            flush=True,
        )

    planned = [r for r in rows if r["goals"] > 0]
    print(
        f"\n== {len(planned)} scenes with a goal set (of {len(rows)}), medians, one core; load after: {os.getloadavg()}"
    )
    print(
        f"OMG plan        {1e3 * median([r['omg'] for r in planned]):6.2f} ms   "
        f"success {sum(r['omg_ok'] for r in planned)}/{len(planned)}"
    )
    if not args.no_rrt:
        ratios = [r["omg"] / r["rrt"] for r in planned if r["rrt"] > 0]
        print(
            f"RRT-Connect     {1e3 * median([r['rrt'] for r in planned]):6.2f} ms   "
            f"success {sum(r['rrt_ok'] for r in planned)}/{len(planned)}"
        )
        print(
            f"ratio OMG/RRT-C per scene: median {median(ratios):.2f}  "
            f"(quartiles {np.percentile(ratios, 25):.2f} .. {np.percentile(ratios, 75):.2f})"
        )
    print(
        "OMG stages (ms): "
        + "  ".join(f"{k} {1e3 * median([r[k] for r in planned]):.2f}" for k in STAGES + ("python",))
    )
    print(
        f"new scene       {1e3 * median([r['new'] for r in rows]):6.1f} ms  (world "
        f"{1e3 * median([r['world'] for r in rows]):.1f}, checkers + ISF data "
        f"{1e3 * median([r['prepare'] for r in rows]):.1f}, goal set "
        f"{1e3 * median([r['goal_set'] for r in rows]):.1f}, plan {1e3 * median([r['first_plan'] for r in rows]):.1f})"
    )
    if args.threads > 1:
        os.sched_setaffinity(0, range(os.cpu_count()))
        scaling = thread_scaling(scene_list, worlds, grasps, settings, args.threads)
        if scaling:
            print(
                f"plan_many, {len(scene_list)} plans (worlds built): 1 thread {scaling[1]:.3f} s, {args.threads} "
                f"threads {scaling[args.threads]:.3f} s: {scaling[1] / scaling[args.threads]:.2f}x on "
                f"{os.cpu_count()} cores; load {os.getloadavg()}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
