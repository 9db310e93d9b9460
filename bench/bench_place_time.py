"""Where place planning's time goes (issue 34): the pick-and-place bench's units (the scenes of an earlier
``pickplan bench pickplace`` run, their regions and settings), each planned once as the bench plans it,
then its place planned again with the caches warm and timed by parts on the planning thread's CPU clock:
the place goal set, and the transfer's stages (CHOMP, goal-cost estimates, selection, the success test).

    .venv/bin/pickplan bench pickplace --objects ../shared/data/ycb --scenes 12 --runs 1 --methods OMG \\
        --grasp-kind antipodal --no-execute --out out/bench/pp12
    .venv/bin/python bench/bench_place_time.py out/bench/pp12
"""

from __future__ import annotations

import argparse
import glob
import os
import time

import numpy as np

from pickplan.eval import experiments
from pickplan.eval.pickplace import unit_settings, unit_task
from pickplan.eval.units import _unit_grasps
from pickplan.omg.pickplace import PickPlacePlanner
from pickplan.omg.planner import OMGPlanner

STAGES = ("chomp", "costs", "selection", "metrics")


def place_times(unit: dict):
    """(goals kept, goal set ms, place ms, {stage: ms}) of the unit's place planned a second time, or None."""
    scene, request, world, record = unit_task(unit)
    if not record["graspable"]:
        return None
    settings = unit_settings(unit, "OMG", world.settings)
    grasps = _unit_grasps(world, scene, settings.pick.grasp_kind, unit["grasp_candidates"], world.settings.robot).poses
    planner = PickPlacePlanner(OMGPlanner(None, scene, settings.pick, world=world), request, settings)
    plan = planner.plan(grasps=grasps)
    if plan.place is None:
        return None
    carrying = planner.attach(plan.pick.goal, plan.held)
    planner.prepare(carrying)
    t = time.thread_time()
    goals, place = planner.plan_place(carrying, plan.lift[-1])
    total = time.thread_time() - t
    return len(goals), 1e3 * goals.seconds, 1e3 * total, {k: 1e3 * place.timings.get(k, 0.0) for k in STAGES}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("run", help="the output folder of a `pickplan bench pickplace` run (its scenes/ and sweep.json)")
    ap.add_argument("--objects", default="../shared/data/ycb", help="the objects that run used")
    ap.add_argument("--limit", type=int, default=0, help="units (0: all)")
    args = ap.parse_args()
    files = sorted(glob.glob(os.path.join(args.run, "scenes", "scene_*.json")))
    if not files:
        raise SystemExit(f"no scenes in {args.run}/scenes")
    s = experiments.SweepSettings(
        table="pickplace",
        scene_dir=os.path.join(args.run, "scenes"),
        objects=args.objects,
        grasp_kind="antipodal",
        runs=1,
        methods=("OMG",),
        execute=False,
        workers=0,
    ).effective()
    units = experiments.make_units(s, files)[: args.limit or None]
    rows = []
    for unit in units:
        out = place_times(unit)
        if out is None:
            print(f"{unit['scene_name']}: no place planned")
            continue
        kept, goal_set, total, stages = out
        rows.append((goal_set, total, *stages.values()))
        print(
            f"{unit['scene_name']}: {kept} goals, goal set {goal_set:.1f} ms, place {total:.1f} ms, "
            + ", ".join(f"{k} {v:.1f}" for k, v in stages.items()),
            flush=True,
        )
    if rows:
        med = np.median(np.array(rows), axis=0)
        print(
            f"median of {len(rows)}: goal set {med[0]:.1f} ms, place {med[1]:.1f} ms, "
            + ", ".join(f"{k} {v:.1f}" for k, v in zip(STAGES, med[2:]))
        )


if __name__ == "__main__":
    main()
