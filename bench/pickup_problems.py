"""Successive refinement vs seeded single shots on random pick-up problems (issue 23 targets).

    PYTHONPATH=python nice python bench/pickup_problems.py --n 100 --seed 0 --shots 10 \
        --metamodel out/metamodel_box.json --out out/bench_pickup_problems

For each of N problems of `pickplan pickup problems --seed S` (random_problems.Workspace): one
successive-refinement solve and SHOTS single shots (seeds 0..SHOTS-1), each in one worker process,
timed with the process CPU clock (time.process_time; one thread: Ipopt/MUMPS and BLAS run
single-threaded here). A solve counts as solved when Ipopt converged AND it passes the dense checks
(solve_problem.dense_checks: pose error at T2, non-holonomic error, clearance, joint limits, grasp
velocity, rho >= gamma). Writes OUT/records.json and OUT/summary.md; prints the summary.
``--set '{"arm_seeds": 4}'`` overrides PlannerSettings fields of the successive refinement only (the
single shots keep the defaults: what a single shot is does not change). ``--shots-from
OUT/records.jsonl`` reuses the single shots of an earlier run on the same problems
(seeded and independent of the successive refinement's settings) and solves only the successive
refinement: a change to it is then measured against the same baseline in a tenth of the time.

Targets: successive solves every problem any single shot solves and >= 95 % of all; its T is
shorter than the best single shot's on >= 90 % of the problems both solve; CPU per problem
median <= 0.7 s, worst <= 2 s.

Issue 37: ``--layout paper|side|behind|cluttered|headings`` draws the problems of that layout
(random_problems.Layout; several layouts: one run each, OUT/LAYOUT/); ``--method routed`` solves with
``routed.plan_routed`` (certificate, lower bound, route seeds), ``--time-limit S`` solves each problem
a second time with that wall-clock budget, ``--near-bound X`` passes plan_routed's stage-1 stop.
With ``--shots 0`` the summary is issue 37's: solved, declared infeasible (reason verified: the
certificate's), failed, T / lower bound, CPU and wall.
"""

from __future__ import annotations

import argparse
import json
import os
import time
from dataclasses import replace

import numpy as np

from pickplan.core.io import write_json, write_text
from pickplan.core.runner import Order, Runner
from pickplan.pickup.nlp import cases, planner, problem_file, random_problems, routed, solve_problem
from pickplan.pickup.nlp.feasibility import Reason

TIE = 1e-3  # relative: T within 0.1 % of the best shot counts as a tie, not as shorter
CASES = "cases"  # --layout cases: the paper's six problem files instead of random ones


def _solve(job) -> dict:
    spec, metamodel, method, seed, overrides, *rest = job
    routed_options, budget = (rest[0], rest[1:]) if rest else ({}, [])
    robot = planner.mobile_ur5()
    rho = solve_problem.rho_for_spec(spec, metamodel, progress=False)
    problem = problem_file.native_problem(robot, spec, rho)
    out = {}
    for limit in [0.0] + budget if budget and budget[0] else [0.0]:
        settings = planner.PlannerSettings(seed=seed, **overrides)
        t0, w0 = time.process_time(), time.monotonic()  # the solve only (not the benchmark's dense checks)
        if method is planner.Method.routed:
            p = routed.plan_routed(robot, problem, settings, time_limit=limit, **routed_options)
        else:
            p = planner.plan(robot, problem, settings, method)
        cpu, wall = time.process_time() - t0, time.monotonic() - w0
        if limit:
            metrics = planner.evaluate(robot, problem, p) if p.success else None
            checks = solve_problem.dense_checks(problem, p, metrics)
            out["budget"] = {
                "limit": limit,
                "status": str(p.status),
                "wall": wall,
                "cpu": cpu,
                "T": p.T if p.success else None,
                "solved": bool(p.success and checks and all(checks.values())),
            }
        else:
            out.update(_record(robot, problem, spec, p, method, seed, cpu, wall))
    return out


def _record(robot, problem, spec, p, method, seed, cpu, wall) -> dict:
    metrics = planner.evaluate(robot, problem, p) if p.stages_completed > 0 else None
    sol = solve_problem.ProblemSolution(spec, problem, p, metrics, solve_problem.dense_checks(problem, p, metrics))
    stage = lambda s: {
        "stage": s.stage,
        "status": str(s.status),
        "iterations": s.iterations,  # noqa: E731
        "rounds": s.rounds,
        "cpu": s.cpu_seconds,
        "T": s.objective,
    }
    return {
        "method": str(method),
        "seed": seed,
        "status": str(p.status),
        "best_stage": p.stages_completed,
        "converged": bool(p.success),
        "solved": bool(sol.passed),
        "T": p.T if p.success else None,
        "cpu": cpu,
        "wall": wall,
        "native_cpu": p.total_cpu_seconds,
        "stages": [stage(s) for s in p.stages],
        "lower_bound": p.lower_bound if np.isfinite(p.lower_bound) else None,
        "reason": str(p.reason),
        "detail": p.detail,
        "seed_used": p.seed,
        "direct": stage(p.direct) if p.direct else None,
        "direct_chosen": bool(p.direct_chosen),
        "arm_seed_T": [None if np.isnan(t) else t for t in p.arm_seed_T],
        "failed_checks": [k for k, ok in sol.checks.items() if not ok],
        "metrics": {
            k: getattr(sol.metrics, k)
            for k in (
                "pose_error_position",
                "pose_error_orientation",
                "nonholonomic_mean",
                "min_clearance",
                "success_probability",
            )
        }
        if sol.metrics is not None
        else None,
    }


def summarize(records: list, gamma: float) -> str:
    n = len(records)
    succ = [r["successive"] for r in records]
    best_shot = []
    for r in records:
        ok = [s["T"] for s in r["shots"] if s["solved"]]
        best_shot.append(min(ok) if ok else None)
    any_shot = [b is not None for b in best_shot]
    solved = [s["solved"] for s in succ]
    missed = [i for i in range(n) if any_shot[i] and not solved[i]]
    both = [i for i in range(n) if any_shot[i] and solved[i]]
    shorter = [i for i in both if succ[i]["T"] < best_shot[i] * (1 - TIE)]
    ties = [i for i in both if abs(succ[i]["T"] - best_shot[i]) <= TIE * best_shot[i]]
    cpu = np.array([s["cpu"] for s in succ])
    shot_cpu = np.array([s["cpu"] for r in records for s in r["shots"]])
    conv_fail = [i for i in range(n) if succ[i]["converged"] and not succ[i]["solved"]]
    unsolved = [(i, succ[i]["status"], succ[i]["best_stage"]) for i in range(n) if not solved[i]]
    ratio = np.array([succ[i]["T"] / best_shot[i] for i in both])
    lines = [
        f"problems: {n} (gamma {gamma}); single shots per problem: {len(records[0]['shots'])}",
        "",
        "| target | measured |",
        "|---|---|",
        f"| successive solves every problem a single shot solves | {len(both)} of {sum(any_shot)}"
        f"{' (missed: ' + ', '.join(map(str, missed)) + ')' if missed else ''} |",
        f"| successive solves >= 95 % of all | {sum(solved)} of {n} ({sum(solved) / n:.0%}) |",
        f"| T shorter than the best of the shots on >= 90 % of the problems both solve | {len(shorter)} of "
        f"{len(both)} ({len(shorter) / max(len(both), 1):.0%}); ties within {TIE:.1%}: {len(ties)}; longer: "
        f"{len(both) - len(shorter) - len(ties)} |",
        f"| CPU per problem median <= 0.7 s, worst <= 2 s | median {np.median(cpu):.2f} s, p90 "
        f"{np.percentile(cpu, 90):.2f} s, worst {cpu.max():.2f} s |",
        f"| dense checks pass | {sum(solved)} of {sum(s['converged'] for s in succ)} converged solutions"
        f"{' (failed: ' + str(conv_fail) + ')' if conv_fail else ''} |",
        "",
        f"T(successive) / T(best shot) on the problems both solve: median {np.median(ratio):.3f}, "
        f"min {ratio.min():.3f}, max {ratio.max():.3f}."
        if len(ratio)
        else "",
        f"Single shots: {sum(s['solved'] for r in records for s in r['shots'])} of {len(shot_cpu)} solved; "
        f"CPU median {np.median(shot_cpu):.2f} s, worst {shot_cpu.max():.2f} s; problems solved by at least one: "
        f"{sum(any_shot)}.",
        f"Unsolved by successive refinement (problem, status, best stage): {unsolved or 'none'}.",
    ]
    return "\n".join(lines) + "\n"


def _count(values) -> dict:
    out = {}
    for v in values:
        out[v] = out.get(v, 0) + 1
    return dict(sorted(out.items()))


def summarize_layout(records: list, layout: str) -> str:
    """Issue 37's figures of one layout (records of a --shots 0 run)."""
    succ = [r["successive"] for r in records]
    n = len(succ)
    declared = [
        i
        for i, s in enumerate(succ)
        if s["reason"] in (Reason.out_of_reach, Reason.gamma_unattainable, Reason.horizon_too_short)
    ]
    solved = [i for i, s in enumerate(succ) if s["solved"]]
    failed = [(i, succ[i]["status"], succ[i]["reason"]) for i in range(n) if i not in solved and i not in declared]
    ratio = np.array([succ[i]["T"] / succ[i]["lower_bound"] for i in solved if succ[i]["lower_bound"]])
    cpu, wall = np.array([s["cpu"] for s in succ]), np.array([s["wall"] for s in succ])
    feasible = n - len(declared)
    lines = [
        f"### layout {layout}: {n} problems",
        "",
        "| target | measured |",
        "|---|---|",
        f"| solved or declared infeasible with a verified reason | {len(solved)} solved, {len(declared)} declared "
        f"infeasible ({', '.join(str(i) + ': ' + succ[i]['reason'] for i in declared) or 'none'}), {len(failed)} failed |",
        f"| >= 95 % of the problems with a feasible certificate solved | {len(solved)} of {feasible} "
        f"({len(solved) / max(feasible, 1):.0%}) |",
    ]
    if len(ratio):
        lines.append(
            f"| T / lower bound: median <= 1.5, max <= 3 | median {np.median(ratio):.2f}, p90 "
            f"{np.percentile(ratio, 90):.2f}, max {ratio.max():.2f}; above 3: {int((ratio > 3).sum())}; "
            f"bound above a solved T (a bug): {int((ratio < 1).sum())} |"
        )
    lines.append(
        f"| CPU median <= 1 s | median {np.median(cpu):.2f} s, p90 {np.percentile(cpu, 90):.2f} s, worst "
        f"{cpu.max():.2f} s (wall median {np.median(wall):.2f} s, worst {wall.max():.2f} s) |"
    )
    budget = [r["successive"].get("budget") for r in records]
    if all(budget):
        bw = np.array([b["wall"] for b in budget])
        kept = [i for i in solved if budget[i]["solved"]]
        lines.append(
            f"| --time-limit {budget[0]['limit']:g}: no wall time above it; every problem solved without it "
            f"still feasible | worst wall {bw.max():.2f} s (over the limit: {int((bw > budget[0]['limit']).sum())}); "
            f"{len(kept)} of {len(solved)} solved ones feasible with the budget |"
        )
    lines += [
        "",
        f"Not solved (problem, status, reason): {failed or 'none'}.",
        f"Seeds the solutions came from: {_count(succ[i]['seed_used'] for i in solved)}.",
    ]
    return "\n".join(lines) + "\n"


def _routed_options(args) -> dict:
    """plan_routed's keyword arguments from the command line (those left unset keep its defaults)."""
    return {} if args.near_bound is None else {"near_bound": args.near_bound}


def _run_layout(args, overrides, layout, out) -> list:
    if layout == CASES:  # the paper's six cases, as shipped
        specs = [problem_file.load_problem(cases.case_path(c)) for c in range(1, 7)]
    else:
        specs = random_problems.random_problems(
            args.n, args.seed, random_problems.Workspace(layout=random_problems.Layout(layout))
        )
    if args.metamodel:
        named = args.metamodel in (problem_file.STANDIN, *problem_file.BUILTIN_PARTS)
        specs = [replace(s, metamodel=args.metamodel if named else os.path.abspath(args.metamodel)) for s in specs]
    else:  # built once here, not in every worker
        solve_problem.rho_for_spec(specs[0], workers=args.workers)
    earlier = None
    if args.shots_from:
        with open(args.shots_from, encoding="utf-8") as f:
            earlier = [json.loads(line)["shots"] for line in f if line.strip()]
        if len(earlier) < len(specs) or any(len(e) != args.shots for e in earlier[: len(specs)]):
            raise SystemExit(f"{args.shots_from}: expected {args.shots} single shots for each of {len(specs)} problems")
    method = planner.Method(args.method)
    jobs = []
    for s in specs:
        jobs.append((s, None, method, 0, overrides, _routed_options(args), args.time_limit))
        if earlier is None:
            jobs += [(s, None, planner.Method.single_shot, k, {}) for k in range(args.shots)]
    os.makedirs(out, exist_ok=True)
    partial = os.path.join(out, "records.jsonl")  # one line per finished problem (a run cut short still counts)
    k, done, records = 1 if earlier else 1 + args.shots, [], []
    with Runner(args.workers) as runner, open(partial, "w", encoding="utf-8") as log:
        for _, result in runner.map(_solve, jobs, Order.JOBS):
            done.append(result)
            if len(done) == k:
                i = len(records)
                records.append({"problem": i, "successive": done[0], "shots": earlier[i] if earlier else done[1:]})
                log.write(json.dumps(records[-1]) + "\n")
                log.flush()
                done = []
    write_json(os.path.join(out, "records.json"), records)
    return records


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--shots", type=int, default=10)
    ap.add_argument(
        "--metamodel",
        default=None,
        help="meta-model JSON or 'standin' (default: the problems' built-in box, built on first use)",
    )
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", default="out/bench_pickup_problems")
    ap.add_argument("--summarize", default=None, metavar="JSONL", help="only summarize the records of a (partial) run")
    ap.add_argument(
        "--shots-from",
        default=None,
        metavar="JSONL",
        help="take the single shots from the records.jsonl of an earlier run on the same problems (they do "
        "not depend on the successive refinement's settings) and solve only the successive refinement",
    )
    ap.add_argument(
        "--set",
        default="{}",
        metavar="JSON",
        help="PlannerSettings overrides (a JSON object) for the successive refinement only",
    )
    ap.add_argument(
        "--layout",
        nargs="+",
        default=["paper"],
        choices=[x.value for x in random_problems.Layout] + [CASES],
        help="problem layouts (one run each, in OUT/LAYOUT/ when more than one); cases: the paper's six",
    )
    ap.add_argument("--method", default="successive", choices=["successive", "routed"])
    ap.add_argument("--time-limit", type=float, default=0.0, help="also solve each problem with this wall budget (s)")
    ap.add_argument(
        "--near-bound",
        type=float,
        default=None,
        help="--method routed: stage 1 tries no further seed once a base path is within this multiple of "
        f"the lower bound (default {routed.NEAR_BOUND}; 0: every seed)",
    )
    args = ap.parse_args(argv)
    if args.near_bound is not None:  # refused here, not in every worker
        try:
            routed.check_near_bound(args.near_bound)
        except ValueError as e:
            raise SystemExit(f"--near-bound: {e}") from None
    overrides = json.loads(args.set)
    if not isinstance(overrides, dict):
        raise SystemExit(f"--set: expected a JSON object, got {args.set!r}")
    try:
        planner.PlannerSettings(**overrides)  # unknown fields or bad option values fail here, not in a worker
    except (TypeError, ValueError) as e:
        raise SystemExit(f"--set: {e}") from None
    if args.summarize:
        with open(args.summarize, encoding="utf-8") as f:
            recs = [json.loads(line) for line in f if line.strip()]
        print(summarize(recs, 0.96) if recs and recs[0]["shots"] else summarize_layout(recs, args.layout[0]))
        return 0
    for layout in args.layout:
        out = args.out if len(args.layout) == 1 else os.path.join(args.out, layout)
        records = _run_layout(args, overrides, layout, out)
        md = summarize(records, 0.96) if args.shots else summarize_layout(records, layout)
        write_text(os.path.join(out, "summary.md"), md)
        print(md, flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
