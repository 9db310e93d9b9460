"""Benchmark for pick-up on the move (issue 8 targets).

Measures, with fixed seeds:
  1. wall time of one simulation (target <= 0.1 s), per part, mean and worst;
  2. simulations per boundary of the active learner (target <= 300) and labels saved by the
     S_c monotonicity;
  3. active learner vs uniform random sampling at the same budget (accuracy on an
     independent simulated test set);
  4. rho of the meta-model vs extensive sampling for the low / medium / high uncertainty
     levels (target: within 5 %, never above it by more than 1 %).

    PYTHONPATH=python python bench/bench_pickup.py --workers 2 --out /tmp/bench_pickup
    PYTHONPATH=python python bench/bench_pickup.py --quick        # a minute or two
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

from pickplan.pickup.metamodel.active import ActiveConfig, PoseDomain, learn_boundary, learn_random, predict
from pickplan.pickup.metamodel.compare import compare, plot_comparison, summarize, table_markdown
from pickplan.core.io import write_text
from pickplan.pickup.metamodel.build import build_metamodel
from pickplan.pickup.metamodel.model import BuildConfig
from pickplan.pickup.metamodel.parallel import SimRunner, sample_seeds
from pickplan.pickup.metamodel.parts import PARTS
from pickplan.pickup.metamodel.sim import SimConfig, simulate_grasp


def bench_sim_time(n: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    dom = PoseDomain()
    out = {}
    for part in sorted(PARTS):
        t = []
        for k in range(n):
            off = dom.to_offsets(rng.uniform(-0.5, 0.5, 3))
            s_g, s_c = rng.uniform(0.05, 0.5), rng.uniform(0.05, 0.15)
            t0 = time.perf_counter()
            simulate_grasp(part, off, s_g, s_c, seed=k)
            t.append(time.perf_counter() - t0)
        out[part] = {"mean_s": float(np.mean(t)), "worst_s": float(np.max(t)), "n": n}
    return out


def bench_active_vs_random(part, pairs, cfg: ActiveConfig, n_test: int, workers: int, seed: int) -> list:
    dom = PoseDomain()
    rows = []
    with SimRunner(part, SimConfig(), workers) as runner:
        for s_g, s_c in pairs:
            count = [0]

            def label(U, s_g=s_g, s_c=s_c):
                sd = sample_seeds(seed + 1, count[0], len(U))
                count[0] += len(U)
                return runner.run(dom.to_offsets(U), s_g, s_c, sd)

            act = learn_boundary(label, cfg, seed=seed)
            rnd = learn_random(label, act.n_simulations, cfg, seed=seed + 2)
            # Test poses from the query distribution (the focus mixture) and uniform.
            rng = np.random.default_rng(seed + 3)
            T = np.vstack(
                [
                    np.clip(rng.normal(0, cfg.focus_scale, (n_test // 2, 3)), -1, 1),
                    rng.uniform(-1, 1, (n_test - n_test // 2, 3)),
                ]
            )
            yT = runner.run(dom.to_offsets(T), s_g, s_c, sample_seeds(seed + 4, 0, n_test))
            rows.append(
                {
                    "s_g": s_g,
                    "s_c": s_c,
                    "budget": act.n_simulations,
                    "converged": act.converged,
                    "accuracy_active": float(np.mean(predict(act.model, T) == yT)),
                    "accuracy_random": float(np.mean(predict(rnd.model, T) == yT)),
                    "test_success_fraction": float(yT.mean()),
                }
            )
            print(rows[-1], file=sys.stderr)
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--part", default="box", choices=sorted(PARTS))
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=None, help="extensive samples per pair")
    ap.add_argument("--out", default=os.path.join("results", "bench_pickup"))
    ap.add_argument("--cache", default=None, help="directory caching the extensive-sampling labels (reruns are free)")
    args = ap.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    report = {"part": args.part, "quick": args.quick, "seed": args.seed}

    report["sim_time"] = bench_sim_time(5 if args.quick else 30, args.seed)
    print("sim time:", json.dumps(report["sim_time"]), file=sys.stderr)

    if args.quick:
        cfg = BuildConfig.quick()
        n_ext, n_test, pairs = args.samples or 100, 100, [(0.5, 0.05)]
    else:
        cfg = BuildConfig(sg_grid=(0.1, 0.3, 0.5), sc_grid=(0.05, 0.15))
        n_ext, n_test, pairs = args.samples or 1000, 400, [(0.3, 0.1), (0.5, 0.05)]

    t0 = time.perf_counter()
    report["active_vs_random"] = bench_active_vs_random(args.part, pairs, cfg.active, n_test, args.workers, args.seed)
    report["active_vs_random_s"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    mm = build_metamodel(args.part, cfg, seed=args.seed, workers=args.workers, progress=True)
    report["build_s"] = time.perf_counter() - t0
    mm.save(os.path.join(args.out, f"metamodel_{args.part}.json"))
    report["boundaries"] = [
        {
            "s_g": bm.s_g,
            "s_c": bm.s_c,
            "simulations": bm.n_simulations,
            "free_labels": int((~bm.simulated).sum()),
            "d_ft": bm.d_ft,
            "width": bm.width,
            "converged": bm.converged,
        }
        for _, bm in sorted(mm.boundaries.items())
    ]
    t0 = time.perf_counter()
    rows = compare(mm, n_samples=n_ext, seed=args.seed, workers=args.workers, cache_dir=args.cache)
    report["compare_s"] = time.perf_counter() - t0
    report["n_extensive"] = n_ext
    report["compare_summary"] = summarize(rows)
    write_text(os.path.join(args.out, "comparison.md"), table_markdown(rows, args.part))
    try:
        plot_comparison(rows, os.path.join(args.out, "comparison.png"), title=args.part)
    except ImportError:
        print("matplotlib missing: no plot", file=sys.stderr)
    write_text(os.path.join(args.out, "report.json"), json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))
    print(table_markdown(rows, args.part))
    return 0


if __name__ == "__main__":
    sys.exit(main())
