"""Grasp-set benchmark: generation time of each generator per object, and PyBullet lift-test success
of the "simulated" (shake-verified) set against raw antipodal candidates (and the YCB files).

    .venv/bin/python bench/bench_grasps.py                       # built-ins + YCB (if present)
    .venv/bin/python bench/bench_grasps.py --objects 025_mug --n 50 --sim-n 30 --workers 2

Prints a Markdown table (figures in bench/README.md). No cache: every run simulates.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

from pickplan.omg import grasps as G
from pickplan.omg.grasps import physics as S
from pickplan.omg.grasps import simulated as SG
from pickplan.core import objects

DEFAULT_OBJECTS = ("005_tomato_soup_can", "006_mustard_bottle", "021_bleach_cleanser", "025_mug", "024_bowl")
YCB_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "ycb")


def timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def rate(r) -> str:
    r = np.asarray(r)
    ok = r >= 0
    return f"{S.lift_rate(r):.2f} ({int(r[ok].sum())}/{int(ok.sum())})" if ok.any() else "n/a (0 applicable)"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", nargs="*", default=list(DEFAULT_OBJECTS))
    ap.add_argument("--ycb", default=os.environ.get("PICKPLAN_YCB_DIR", YCB_DIR), help="YCB folder ('' to skip)")
    ap.add_argument("--n", type=int, default=100, help="grasps per generated approach/antipodal set")
    ap.add_argument("--lift-n", type=int, default=30, help="antipodal candidates lift-tested")
    ap.add_argument("--sim-n", type=int, default=20, help="simulated grasps generated and lift-tested")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    libs = [("builtin", objects.library("builtin"))]
    if a.ycb and os.path.isdir(a.ycb):
        libs.append(("ycb", objects.library(a.ycb)))
    else:
        print(f"(YCB folder not found at {a.ycb}: YCB rows skipped)", file=sys.stderr)
    print(
        "| object | approach n=%d (s) | antipodal n=%d (s) | simulated n=%d, %d workers (s, tested) "
        "| lift: antipodal | lift: simulated | lift: YCB file |" % (a.n, a.n, a.sim_n, a.workers)
    )
    print("|---|---|---|---|---|---|---|")
    for src, lib in libs:
        for name in a.objects:
            if name not in lib:
                continue
            model = lib.get(name)
            _, t_app = timed(G.approach_grasps, model, a.n, a.seed)
            anti, t_anti = timed(G.antipodal_grasps, model, a.n, a.seed)
            sim, t_sim = timed(
                SG.simulated_grasps, model, a.sim_n, a.seed, workers=a.workers, cache=False, progress=False
            )
            lift_a = S.lift_test(model, anti.poses[: a.lift_n]) if len(anti) else np.zeros(0)
            lift_s = S.lift_test(model, sim.poses) if len(sim) else np.zeros(0)
            lift_y = "-"
            if "simulated" in model.grasps:
                lift_y = rate(S.lift_test(model, G.load_grasp_set(model, "simulated").poses[: a.lift_n]))
            tested = int(sim.info.get("tested", 0)) if len(sim) else 0
            print(
                f"| {src}:{name} | {t_app:.2f} | {t_anti:.2f} ({len(anti)}) | {t_sim:.1f} ({len(sim)} of {tested}) "
                f"| {rate(lift_a)} | {rate(lift_s)} | {lift_y} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
