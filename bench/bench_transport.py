"""Transport test of the "Simulated" (shake-verified) grasps against their raw antipodal candidates.

For each object: the ``--n`` antipodal candidates of round 0 of ``simulated_grasps(model, n, --seed)``
(``grasps.physics.shake_candidates``); those applicable on the table (the open hand clears it in one of
the three most stable resting poses) are shake-tested (the ``simulated_grasps`` rule: kept when
``shake_test`` holds, with the same seeds) and transport-tested (``grasps.physics.transport_trial``). Rates are over the
applicable candidates: all of them ("antipodal"), the shake-held ones ("simulated") and the
shake-rejected ones. Prints a Markdown table; pooled rates with Wilson 95 % intervals and a
one-sided Fisher exact test (simulated vs rejected).

    .venv/bin/python bench/bench_transport.py --workers 2
    .venv/bin/python bench/bench_transport.py --objects 021_bleach_cleanser --n 20 --source builtin
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time

import numpy as np

from pickplan.omg.grasps import physics as S
from pickplan.core import objects

HARD = ("003_cracker_box", "004_sugar_box", "006_mustard_bottle", "021_bleach_cleanser")
EASY = ("005_tomato_soup_can", "010_potted_meat_can", "024_bowl", "025_mug")
YCB_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "ycb")


def wilson(k: int, n: int, z: float = 1.96):
    if n == 0:
        return float("nan"), float("nan")
    p = k / n
    d = 1 + z * z / n
    c = (p + z * z / (2 * n)) / d
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return c - h, c + h


def fmt(k: int, n: int) -> str:
    return f"{k / n:.2f} ({k}/{n})" if n else "n/a"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--objects", nargs="*", default=list(HARD + EASY))
    ap.add_argument("--source", nargs="*", default=["builtin", "ycb"], help="builtin and/or ycb")
    ap.add_argument("--ycb", default=os.environ.get("PICKPLAN_YCB_DIR", YCB_DIR))
    ap.add_argument("--n", type=int, default=40, help="antipodal candidates per object")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    from scipy.stats import fisher_exact

    libs = []
    if "builtin" in a.source:
        libs.append(("builtin", objects.library("builtin")))
    if "ycb" in a.source and a.ycb and os.path.isdir(a.ycb):
        libs.append(("ycb", objects.library(a.ycb)))
    print("| object | candidates (applicable) | antipodal | simulated (shake-held) | shake-rejected | s |")
    print("|---|---|---|---|---|---|")
    pooled = {}
    for src, lib in libs:
        for name in a.objects:
            if name not in lib:
                continue
            t0 = time.perf_counter()
            model = lib.get(name)
            total = len(S.shake_candidates(model, a.n, a.seed)[0])
            rows = S.shake_and_transport(model, a.n, a.seed, a.workers)
            sh = np.array([r["shake"]["held"] for r in rows], bool)
            ok = np.array([r["transport"]["held"] for r in rows], bool)
            group = "hard" if name in HARD else "easy"
            p = pooled.setdefault((src, group), [0, 0, 0, 0])
            p[0] += int(ok.sum())
            p[1] += len(ok)
            p[2] += int(ok[sh].sum())
            p[3] += int(sh.sum())
            print(
                f"| {src}:{name} | {total} ({len(rows)}) | {fmt(int(ok.sum()), len(ok))} | "
                f"{fmt(int(ok[sh].sum()), int(sh.sum()))} | {fmt(int(ok[~sh].sum()), int((~sh).sum()))} | "
                f"{time.perf_counter() - t0:.0f} |",
                flush=True,
            )
    print()
    for (src, group), (k_all, n_all, k_sim, n_sim) in sorted(pooled.items()):
        k_rej, n_rej = k_all - k_sim, n_all - n_sim
        lo_a, hi_a = wilson(k_all, n_all)
        lo_s, hi_s = wilson(k_sim, n_sim)
        pval = (
            fisher_exact([[k_sim, n_sim - k_sim], [k_rej, n_rej - k_rej]], alternative="greater")[1]
            if n_sim and n_rej
            else float("nan")
        )
        print(
            f"{src} {group}: antipodal {fmt(k_all, n_all)} [{lo_a:.2f}, {hi_a:.2f}], simulated "
            f"{fmt(k_sim, n_sim)} [{lo_s:.2f}, {hi_s:.2f}], rejected {fmt(k_rej, n_rej)}; "
            f"Fisher one-sided p (simulated > rejected) = {pval:.2g}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
