"""Goal selection study (issue 6): planning success of Fixed, Proj, FTC, FTL, EXP, MD on generated
scenes, with the data that explains the differences: switches, the initial goal's rank, and (with
``--oracle``) which goals of the goal set succeed when planned alone (Fixed on that goal only).

    .venv/bin/python bench/bench_selection_study.py --set builtin --scenes 20 --out out/selstudy/builtin.json
    .venv/bin/python bench/bench_selection_study.py --set dense --scenes 20 --oracle --out out/selstudy/dense.json
    .venv/bin/python bench/bench_selection_study.py --set ycb --scenes 20 --out out/selstudy/ycb.json
    ... --approach-clearance 0      # the goal set without the approach-clearance filter (before)
    ... --start-spread 0.8          # random starts: ready pose + U(-0.8, 0.8) rad per arm joint, >= 5 cm clear
    ... --n 50                      # 50 waypoints instead of 30 (Fig. 8's hardest discretization)

Serial, one process; scenes are generated once into ``--scene-dir`` and reused. Built-in scenes use
100 antipodal grasps (seed 0; the built-ins have no stored simulated set), YCB scenes the stored
simulated set. Table I setting: no ISF, 30 goals, N = 50, pre-termination as in the planner.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
import warnings
from dataclasses import replace

import numpy as np

from pickplan.omg import grasps as grasps_mod
from pickplan.core import objects
from pickplan.omg import planner as omg
from pickplan.sim import scenes
from pickplan.omg.goals import GoalSetSettings, build_goal_set
from pickplan.sim.scene_sets import scene_seeds
from pickplan.omg.world import World

POLICIES = ("Fixed", "Proj", "FTC", "FTL", "EXP", "MD")
SETS = {
    "builtin": (None, scenes.SceneSettings()),
    "dense": (None, scenes.SceneSettings(min_objects=6, max_objects=7, region_x=(0.4, 0.7), region_y=(-0.25, 0.25))),
    "clutter": (None, scenes.SceneSettings(min_objects=6, max_objects=10, region_x=(0.4, 0.7), region_y=(-0.2, 0.2))),
    "ycb": ("/work/shared/data/ycb", scenes.SceneSettings()),
}


def load_scenes(name: str, count: int, seed: int, folder: str):
    lib_dir, settings = SETS[name]
    lib = objects.library(lib_dir) if lib_dir else objects.library("builtin")
    os.makedirs(folder, exist_ok=True)
    out = []
    for i, s in enumerate(scene_seeds(seed, count)):
        path = os.path.join(folder, f"{name}_{seed}_{i:03d}.json")
        if not os.path.exists(path):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                try:
                    scenes.generate_scene(s, lib, settings).save(path)
                except RuntimeError as exc:  # too few objects came to rest: no scene for this seed
                    print(f"{os.path.basename(path)}: skipped ({exc})", flush=True)
                    continue
        out.append((path, scenes.Scene.load(path)))
    return out


def scene_grasps(world: World, kind: str) -> np.ndarray:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if kind == "simulated" and "simulated" in world.target_model.grasps:
            return grasps_mod.grasp_set(world.target_model, "simulated").poses
        return grasps_mod.antipodal_grasps(world.target_model, 100, seed=0).poses


def random_start(world: World, spread: float, seed: int) -> np.ndarray:
    """The ready pose with every arm joint moved by U(-spread, spread) rad (clipped to the limits),
    redrawn until the arm is at least 5 cm from the table and objects (FCL)."""
    rng = np.random.default_rng(seed)
    ready, checker = np.array(world.start), world.checker("goal")
    arm = world.robot.info.arm_dof
    for _ in range(200):
        q = ready.copy()
        q[:arm] += rng.uniform(-spread, spread, arm)
        q = world.robot.clip_to_limits(q)
        if checker.min_distance(q) > 0.05:
            return q
    raise RuntimeError(f"no start with 5 cm clearance within {spread} rad of the ready pose")


def study_scene(
    scene, settings: omg.OMGSettings, policies, oracle: bool, kind: str, start_spread: float = 0.0, start_seed: int = 0
) -> dict:
    world = World(scene)
    g = scene_grasps(world, kind)
    start = random_start(world, start_spread, start_seed) if start_spread > 0 else None
    rec = {"target": scene.target, "objects": len(scene.objects), "policies": {}}
    for p in policies:
        r = omg.OMGPlanner(None, scene, replace(settings, selection=p), world=world).plan(start=start, grasps=g)
        h = r.history
        rec["policies"][p] = {
            "status": r.status,
            "success": bool(r.success),
            "goal_set": r.goal_set_size,
            "iterations": r.iterations,
            "switches": h["switches"],
            "grasp": r.grasp_index,
            "initial_grasp": h.get("initial_grasp", -1),
            "goals": [int(x) for x in h["goal"]],
            "min_clearance": getattr(r.metrics, "min_clearance", None),
            "smoothness": getattr(r.metrics, "smoothness", None),
            "costs": [np.round(c, 5).tolist() for c in h["costs"]] if p == "MD" else None,
            "reasons": r.goal_reasons if p == "Fixed" else None,
        }
    if oracle:
        gs = build_goal_set(world, g, world.start if start is None else start, settings.goals, settings.ik)
        alone = {}
        for gi in gs.grasp_index:
            r = omg.OMGPlanner(None, scene, replace(settings, selection="Fixed"), world=world).plan(
                start=start, grasps=g[[gi]]
            )
            alone[int(gi)] = r.status
        rec["alone"] = alone
        rec["goal_grasps"] = [int(x) for x in gs.grasp_index]
    return rec


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--set", choices=sorted(SETS), default="builtin")
    ap.add_argument("--scenes", type=int, default=20)
    ap.add_argument("--first", type=int, default=0, help="skip this many scenes of the set")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--policies", nargs="+", default=list(POLICIES))
    ap.add_argument(
        "--approach-clearance",
        type=float,
        default=None,
        help="goal-set approach clearance (m); default: the goal set's default",
    )
    ap.add_argument("--oracle", action="store_true", help="also plan every goal of the goal set alone")
    ap.add_argument(
        "--start-spread",
        type=float,
        default=0.0,
        help="random start per scene: ready pose + U(-S, S) rad per arm joint (0: the ready pose)",
    )
    ap.add_argument("--n", type=int, default=None, help="trajectory waypoints (default: the planner's, 30)")
    ap.add_argument("--scene-dir", default="out/selstudy/scenes")
    ap.add_argument("--out", required=True)
    a = ap.parse_args(argv)
    goals = (
        GoalSetSettings() if a.approach_clearance is None else GoalSetSettings(approach_clearance=a.approach_clearance)
    )
    settings = omg.OMGSettings(refine=False, goals=goals)
    if a.n is not None:
        settings = replace(settings, chomp=replace(settings.chomp, n=a.n))
    kind = "simulated" if a.set == "ycb" else "antipodal"
    records = []
    t0 = time.perf_counter()
    for k, (path, scene) in enumerate(load_scenes(a.set, a.first + a.scenes, a.seed, a.scene_dir)[a.first :]):
        rec = study_scene(scene, settings, a.policies, a.oracle, kind, a.start_spread, start_seed=a.first + k)
        rec["scene"] = path
        records.append(rec)
        line = " ".join(
            f"{p}:{'ok' if v['success'] else v['status'][:4]}/{v['switches']}" for p, v in rec["policies"].items()
        )
        extra = ""
        if a.oracle:
            extra = f" alone ok {sum(s == 'success' for s in rec['alone'].values())}/{len(rec['alone'])}"
        print(
            f"[{k + 1}/{a.scenes} {time.perf_counter() - t0:.0f}s] {os.path.basename(path)} {line}{extra}", flush=True
        )
    summary = {p: sum(r["policies"][p]["success"] for r in records) for p in a.policies}
    planned = sum(r["policies"][a.policies[0]]["goal_set"] > 0 for r in records)
    print("success:", summary, f"(scenes {len(records)}, with goals {planned})")
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    with open(a.out, "w") as f:
        json.dump({"args": vars(a), "summary": summary, "records": records}, f)
    return 0


if __name__ == "__main__":
    sys.exit(main())
