"""Seconds per new object of the physics verification (``omg.grasps.verify``): for each procedural
family's first object in its most likely resting pose, ``--n`` antipodal grasps the support allows,
judged by the quality and lifted in PyBullet where it is unsure; then the same call again (cached).
Prints a Markdown table: grasps, simulated, kept, seconds (first call, cached call).

    .venv/bin/python bench/bench_verify.py --n 30
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np

from pickplan.core import objects, procedural
from pickplan.omg.grasps import antipodal_grasps
from pickplan.omg.grasps.generators import SupportFilter
from pickplan.omg.grasps.verify import verify_grasps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=30, help="antipodal grasps per object")
    ap.add_argument("--families", nargs="+", default=list(procedural.FAMILIES))
    args = ap.parse_args()
    os.environ.setdefault("PICKPLAN_CACHE_DIR", tempfile.mkdtemp(prefix="pickplan-verify-"))  # a cold cache
    lib = objects.library("procedural")
    print("| object | grasps | simulated | kept | generation (s) | verification (s) | cached (s) |")
    print("|---|---|---|---|---|---|---|")
    total = []
    for family in args.families:
        model = lib.get(f"{family}_00")
        pose = model.resting_poses[int(np.argmax(model.resting_probabilities))]
        t0 = time.perf_counter()
        gs = antipodal_grasps(model, args.n, seed=0, support=SupportFilter.under(pose))
        t1 = time.perf_counter()
        v = verify_grasps(model, gs.poses, pose)
        t2 = time.perf_counter()
        verify_grasps(model, gs.poses, pose)
        t3 = time.perf_counter()
        total.append(t2 - t1)
        print(
            f"| {model.name} | {len(gs)} | {int(v.simulated.sum())} | {int(v.keep.sum())} | {t1 - t0:.1f} | "
            f"{t2 - t1:.1f} | {t3 - t2:.3f} |"
        )
    print(f"\nverification: median {np.median(total):.1f} s, max {np.max(total):.1f} s per object")


if __name__ == "__main__":
    main()
