"""CHOMP on generated cluttered scenes: straight-line initialization to a reachable goal (the first goal
of the goal set built from antipodal grasps), 100 iterations; success = the paper's planning success.

    .venv/bin/python bench/bench_chomp_scenes.py --scenes 20
"""

import argparse
import time
import warnings

import numpy as np

from pickplan.omg import chomp
from pickplan.omg import goals
from pickplan.omg import grasps
from pickplan.sim import scenes
from pickplan.omg import world


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--iterations", type=int, default=100)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    ok = tried = free = 0
    times = []
    for seed in range(args.scenes):
        sc = scenes.generate_scene(seed)
        w = world.World(sc)
        gs = goals.build_goal_set(w, grasps.grasp_set(w.target_model, "antipodal", 100, seed=0).poses)
        if len(gs) == 0:
            print(f"scene {seed}: no reachable goal, skipped")
            continue
        m = gs.tails.shape[1]
        c = chomp.Chomp(w.robot, w.sdf, w.body, chomp.ChompSettings(obstacle_tail=m), exclude=(w.target,))
        xi0 = c.initial_trajectory(w.start, gs.goals[0], kind="linear")
        xi0[-m:] = gs.tails[0]
        t = time.perf_counter()
        res = c.optimize(
            w.start, gs.tails[0], args.iterations, xi0=xi0, metric_settings=chomp.MetricSettings(tail_waypoints=m)
        )
        times.append(time.perf_counter() - t)
        tried += 1
        ok += bool(res.metrics.success)
        free += bool(res.metrics.collision_free)
        print(
            f"scene {seed}: {'success' if res.metrics.success else 'failure'}, "
            f"{'collision-free' if res.metrics.collision_free else 'in collision'}, clearance "
            f"{res.metrics.min_clearance * 100:.1f} cm, smoothness {res.metrics.smoothness:.1f}, "
            f"{times[-1] * 1e3:.0f} ms",
            flush=True,
        )
    print(
        f"CHOMP success {ok}/{tried}, collision-free {free}/{tried}; "
        f"median {np.median(times) * 1e3:.0f} ms per 100-iteration optimization"
    )


if __name__ == "__main__":
    main()
