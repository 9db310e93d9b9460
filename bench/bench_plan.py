"""Wall time of a full OMG plan (``OMGPlanner.plan``) by stage, on generated scenes.

Defaults are the paper's setting of the planning-time benchmark: n = 30, goal sets capped at 30,
ISF on, MD selection, pre-termination; grasps are the target's built-in antipodal set (or pass
``--grasps simulated`` with the YCB data). Scene preparation (SDF grids, the merged scene grid, FCL
models, grasp generation) is reported apart: it is done once per scene, not per plan.

    .venv/bin/python bench/bench_plan.py --scenes 10 [--repeat 3] [--no-merged]

Prints one line per scene and the median of every stage over the scenes with a goal set.
"""

import argparse
import statistics
import time

from pickplan.omg import planner as omg
from pickplan.sim import scenes
from pickplan.core import sdf
from pickplan.omg import world

STAGES = ("goal_set", "chomp", "costs", "selection", "isf", "metrics", "total")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=10, help="scene seeds 0..N-1")
    ap.add_argument("--repeat", type=int, default=3, help="plans per scene; the fastest is kept")
    ap.add_argument("--grasps", default="antipodal")
    ap.add_argument("--selection", default="MD")
    ap.add_argument("--no-merged", action="store_true", help="per-object SDF grids instead of the merged grid")
    args = ap.parse_args(argv)
    settings = omg.OMGSettings(
        grasp_kind=args.grasps,
        selection=args.selection,
        world=world.WorldSettings(sdf=sdf.SdfSettings(merged=not args.no_merged)),
    )
    rows = []
    for seed in range(args.scenes):
        scene = scenes.generate_scene(seed)
        t = time.perf_counter()
        planner = omg.OMGPlanner(None, scene, settings)
        w = planner.world()
        prep = time.perf_counter() - t
        grasps = planner.default_grasps(w)
        best = None
        for _ in range(args.repeat):
            r = planner.plan(grasps=grasps)
            if best is None or r.timings["total"] < best.timings["total"]:
                best = r
        print(
            f"scene {seed}: {best.status:12s} goals {best.goal_set_size:3d} its {best.iterations:2d}  "
            + "  ".join(f"{k} {1e3 * best.timings[k]:7.1f}" for k in STAGES)
            + f"  ms | world {1e3 * prep:.0f} ms (merge {1e3 * w.merge_seconds:.0f})"
        )
        if best.goal_set_size:
            rows.append(best)
    if rows:
        print(
            f"median over {len(rows)} scenes with goals (ms): "
            + "  ".join(f"{k} {1e3 * statistics.median(r.timings[k] for r in rows):.1f}" for k in STAGES)
        )
        print(f"planning success {sum(r.success for r in rows)}/{len(rows)}")


if __name__ == "__main__":
    main()
