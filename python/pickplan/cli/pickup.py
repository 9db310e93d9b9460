"""`pickplan pickup plan --problem P.json --out DIR`: solves one problem file (pickup/nlp/problem_file.py)
and writes the trajectory, the metrics with their dense checks and a speed plot; exit 1 with the
status and the best stage reached when there is no solution. `pickplan pickup problems --n N --seed S
--out DIR` writes seeded random problem files; `pickplan pickup replay TRAJECTORY.json [--gui]`
plays a written trajectory back in PyBullet.

`pickplan pickup cases [--out DIR] [--quick] [--metamodel FILE|standin] [--workers N] [--replay NAME [--gui]]`:
runs the Sec. VI experiments on the rho_sigma of a part-1 meta-model (by default the box model, built
from simulation on the first run and cached as OUT/metamodel_box.json) and writes Tables I-IV (Markdown, the paper's numbers beside ours), the
Fig. 5 speed plots and every trajectory as JSON + NPZ (atomic writes). `--replay NAME` plays one
written trajectory (e.g. case5_sequential) back in PyBullet (DIRECT, or the GUI with --gui) and
prints PyBullet's independent tool-pose error at T2 and least link-obstacle distance;
`--replay-only` replays from an earlier run's OUT/trajectories without solving again."""

from __future__ import annotations

import argparse
import math
import os
from typing import Optional

from pickplan.cli.output import add_verbosity_options, configure_logging, level_of
from pickplan.cli.exit_codes import ExitCode
from pickplan.core.errors import InputError
from pickplan.core.io import atomic_open, write_text
from pickplan.core.io import read_json
from pickplan.pickup.metamodel.validate import validate_metamodel
from pickplan.pickup.nlp import cases
from pickplan.pickup.nlp.feasibility import Reason
from pickplan.pickup.nlp import planner
from pickplan.pickup.nlp import problem_file
from pickplan.pickup.nlp import random_problems
from pickplan.pickup.nlp import replay
from pickplan.pickup.nlp import solve_problem


def add_pickup_commands(subparsers, help: Optional[str] = None) -> None:
    """Adds `pickup cases` to an argparse subparsers object (the pickplan CLI's)."""
    pk = subparsers.add_parser("pickup", help=help)
    sub = pk.add_subparsers(dest="pickup_command", required=True)
    c = sub.add_parser("cases", help="Tables I-IV and Fig. 5 of Sec. VI")
    c.add_argument("--out", default="out/pickup_cases", help="output folder")
    c.add_argument("--quick", action="store_true", help="fewer samples per interval, one single-shot seed")
    c.add_argument(
        "--metamodel",
        default=None,
        help="part-1 meta-model JSON; default OUT/metamodel_box.json, built from simulation when "
        f"missing; '{cases.STANDIN}' for the labelled stand-in surface (no physics)",
    )
    c.add_argument("--workers", type=int, default=1, help="solver processes (Ipopt is not thread-safe)")
    c.add_argument("--shots", type=int, default=3, help="single-shot random seeds per case")
    c.add_argument(
        "--replay",
        default=None,
        metavar="NAME",
        help="replay OUT/trajectories/NAME.json in PyBullet (e.g. case1_sequential)",
    )
    c.add_argument("--replay-only", action="store_true", help="only replay (no solving); needs --replay")
    c.add_argument("--gui", action="store_true", help="replay in the PyBullet GUI, in real time")
    c.set_defaults(func=run_cases)
    p = sub.add_parser("plan", help="solve one problem file")
    p.add_argument("--problem", required=True, help="problem JSON (pickplan.pickup_problem)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--metamodel", default=None, help="meta-model JSON replacing the one the problem names")
    p.add_argument(
        "--method",
        default="routed",
        choices=[m.value for m in planner.Method],
        help="routed (default): route seeds, lower bound, reasons; successive: the paper's five stages",
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (single shot)")
    p.add_argument(
        "--time-limit",
        type=float,
        default=0.0,
        help="wall-clock seconds for the solve (0: none); the best feasible plan so far is kept",
    )
    p.add_argument("--workers", type=int, default=1, help="simulation processes if a built-in meta-model is built")
    p.set_defaults(func=run_plan)
    g = sub.add_parser("problems", help="write seeded random problem files")
    g.add_argument("--n", type=int, required=True, help="how many")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--out", required=True, help="output folder (problem_0000.json, ...)")
    g.add_argument("--metamodel", default="box", help="what the problems name: a built-in part, 'standin' or a file")
    g.add_argument(
        "--layout",
        default="paper",
        choices=[x.value for x in random_problems.Layout],
        help="where the part stands relative to the route (random_problems.Layout)",
    )
    g.set_defaults(func=run_problems)
    r = sub.add_parser("replay", help="replay a written trajectory in PyBullet")
    r.add_argument("trajectory", help="trajectory JSON written by pickup plan or pickup cases")
    r.add_argument("--gui", action="store_true", help="the PyBullet GUI, in real time")
    r.set_defaults(func=run_replay)


def run_plan(args: argparse.Namespace) -> int:
    spec = problem_file.load_problem(args.problem)
    rho = solve_problem.rho_for_spec(spec, args.metamodel, workers=args.workers)
    robot = planner.mobile_ur5()
    if not (args.time_limit >= 0 and math.isfinite(args.time_limit)):
        raise InputError(f"expected a finite number >= 0, got {args.time_limit}", field="--time-limit")
    settings = planner.PlannerSettings(seed=args.seed)
    sol = solve_problem.solve(robot, spec, rho, settings, args.method, time_limit=args.time_limit)
    paths = solve_problem.write_solution(robot, sol, args.out)
    p = sol.plan
    bound = f"; lower bound on T {p.lower_bound:.2f} s" if math.isfinite(p.lower_bound) else ""
    if not p.success:
        why = f", reason {p.reason}: {p.detail}" if p.reason is not Reason.none else ""
        print(
            f"no solution: status {p.status}{why}; best stage reached {p.stages_completed} of 5 "
            f"(CPU {p.total_cpu_seconds:.2f} s){bound}; wrote {paths['metrics']}"
        )
        return ExitCode.NO_PLAN
    failed = [k for k, ok in sol.checks.items() if not ok]
    cut = (
        " (the time limit cut later runs: the best plan found before it)"
        if p.status is planner.SolveStatus.time_limit
        else ""
    )
    print(
        f"solved{cut}: T = {p.T:.2f} s{bound}, grasping [{p.T1:.2f}, {p.T2:.2f}] s at S_g = {p.S_g:.3f} m/s, "
        f"rho = {sol.metrics.success_probability:.4f} (gamma {spec.gamma}); CPU {p.total_cpu_seconds:.2f} s"
    )
    print(f"dense checks: {'all passed' if not failed else 'FAILED ' + ', '.join(failed)}")
    print(f"wrote {', '.join(paths.values())}")
    print(f"replay: pickplan pickup replay {paths['trajectory']} --gui")
    return ExitCode.OK if not failed else ExitCode.NO_PLAN


def run_problems(args: argparse.Namespace) -> int:
    named = args.metamodel in (problem_file.STANDIN, *problem_file.BUILTIN_PARTS)
    ws = random_problems.Workspace(
        metamodel=args.metamodel if named else os.path.abspath(args.metamodel),
        layout=random_problems.Layout(args.layout),
    )
    specs = random_problems.random_problems(args.n, args.seed, ws)
    os.makedirs(args.out, exist_ok=True)
    for i, spec in enumerate(specs):
        problem_file.dump_problem(spec, os.path.join(args.out, f"problem_{i:04d}.json"))
    print(f"wrote {len(specs)} problems to {args.out} (seed {args.seed}; workspace: {ws.describe()})")
    return 0


def run_replay(args: argparse.Namespace) -> int:
    r = replay.replay_file(args.trajectory, gui=args.gui)
    print(
        f"replayed {args.trajectory} in PyBullet ({r['frames']} frames): tool error at T2 "
        f"{r['tool_error_T2'][0]:.2e} m / {r['tool_error_T2'][1]:.2e} rad, least link-obstacle distance "
        f"{r['min_distance']:.3f} m at t = {r['min_distance_t']:.2f} s"
    )
    return 0


def _f(x, fmt="{:.2f}"):
    return "fail" if x is None else fmt.format(x)


def _m(p, key):
    return None if not p.get("metrics") else p["metrics"][key]


def tables_markdown(main: dict, t4: dict, rho_source: str) -> str:
    L = [
        f"# Pick-up on the move: Sec. VI experiments\n\nrho_sigma source: {rho_source}. "
        "Each cell: paper / ours. Sequential = five stages of successive refinement; without sequencing = "
        "all constraints at once from random seeds (best solved seed). `fail` = no solution (status in the JSON).\n"
    ]
    L.append(
        "## Table I: speeds (m/s)\n\n| Case | S_mb seq | S_mb w/o seq | S_g seq | S_g w/o seq | S_c seq | S_c w/o seq |\n|---|---|---|---|---|---|---|"
    )
    for c in range(1, 7):
        s, w = main[c]["successive"], main[c]["single_shot"]
        (pm, pg, pc) = cases.PAPER_T1[c]
        ours = [
            (_m(s, "base_speed_grasp_mean"), _m(w, "base_speed_grasp_mean")),
            (s["S_g"] if s["success"] else None, w["S_g"] if w["success"] else None),
            (s["S_c"] if s["success"] else None, w["S_c"] if w["success"] else None),
        ]
        cells = []
        for paper, mine in zip((pm, pg, pc), ours):
            cells += [f"{paper[0]:.2f} / {_f(mine[0])}", f"{paper[1]:.2f} / {_f(mine[1])}"]
        L.append(f"| {c} | " + " | ".join(cells) + " |")
    L.append("\nS_mb: mean base speed during grasping [T1, T2].\n")
    L.append(
        "## Table II: errors\n\n| Case | pos. err seq (mm) | pos. err w/o seq (mm) | orient. err seq | orient. err w/o seq | "
        "avg. non-holonomic seq | avg. non-holonomic w/o seq | drift seq (m) | drift w/o seq (m) |\n"
        "|---|---|---|---|---|---|---|---|---|"
    )
    for c in range(1, 7):
        s, w = main[c]["successive"], main[c]["single_shot"]
        pp, po, pn = cases.PAPER_T2[c]
        g = lambda p, k, sc=1.0: None if (_m(p, k) is None or not p["success"]) else _m(p, k) * sc  # noqa: E731
        L.append(
            f"| {c} | {pp[0]:.1e} / {_f(g(s, 'pose_error_position', 1e3), '{:.1e}')} | "
            f"{pp[1]:.1e} / {_f(g(w, 'pose_error_position', 1e3), '{:.1e}')} | "
            f"{po[0]:.1e} / {_f(g(s, 'pose_error_orientation', 1e3), '{:.1e}')} | "
            f"{po[1]:.1e} / {_f(g(w, 'pose_error_orientation', 1e3), '{:.1e}')} | "
            f"{pn[0]:.1e} / {_f(g(s, 'nonholonomic_mean'), '{:.1e}')} | {pn[1]:.1e} / {_f(g(w, 'nonholonomic_mean'), '{:.1e}')} | "
            f"{_f(g(s, 'nonholonomic_drift'), '{:.1e}')} | {_f(g(w, 'nonholonomic_drift'), '{:.1e}')} |"
        )
    L.append(
        "\nOurs: position error of the tool at T2 by dense re-sampling (mm); orientation error as the rotation "
        "angle (mrad; the paper labels it mm); avg. non-holonomic error as the mean of |x' sin phi - y' cos phi| "
        "over 2001 instants in [0, T] (m/s; the paper labels it m and does not define it); drift (ours only): "
        "its integral over [0, T], the lateral slip of the whole trajectory (m).\n"
    )
    L.append(
        "## Table III: times and probability\n\n| Case | grasp time seq (s) | grasp time w/o seq (s) | T seq (s) | "
        "T w/o seq (s) | rho seq | rho w/o seq | solve seq (s) | solve w/o seq (s) |\n|---|---|---|---|---|---|---|---|---|"
    )
    for c in range(1, 7):
        s, w = main[c]["successive"], main[c]["single_shot"]
        pg, pt, pr = cases.PAPER_T3[c]
        ok = lambda p, v: v if p["success"] else None  # noqa: E731
        L.append(
            f"| {c} | {pg[0]:.2f} / {_f(ok(s, s['T2'] - s['T1']))} | {pg[1]:.2f} / {_f(ok(w, w['T2'] - w['T1']))} | "
            f"{pt[0]:.2f} / {_f(ok(s, s['T']))} | {pt[1]:.2f} / {_f(ok(w, w['T']))} | "
            f"{pr[0]:.2%} / {_f(ok(s, _m(s, 'success_probability')), '{:.2%}')} | "
            f"{pr[1]:.2%} / {_f(ok(w, _m(w, 'success_probability')), '{:.2%}')} | "
            f"- / {s['total_seconds']:.2f} | - / {w['total_seconds']:.2f} |"
        )
    solved_w = [sum(r["success"] for r in main[c]["single_shot_all"]) for c in range(1, 7)]
    direct = [c for c in range(1, 7) if main[c]["successive"].get("direct_chosen")]
    L.append(
        f"\nSingle-shot seeds solved per case: {solved_w}. Sequential solutions from the direct track "
        f"(all constraints from the stage-1 solution, shorter than the five stages'): cases {direct or 'none'}. "
        "Solve times: the five stages (from both arm seeds) plus the direct track.\n"
    )
    L.append(
        "## Table IV: low vs high uncertainty (sequential)\n\n| Case | base speed in grasp low | high | S_g low | high | "
        "rho low | high |\n|---|---|---|---|---|---|---|"
    )
    for c in cases.TABLE4_CASES:
        lo, hi = t4[(c, "low")], t4[(c, "high")]
        pb, pg, pr = cases.PAPER_T4[c]
        okm = lambda p, k: _m(p, k) if p["success"] else None  # noqa: E731
        L.append(
            f"| {c} | {pb[0]:.2f} / {_f(okm(lo, 'base_speed_grasp_mean'))} | {pb[1]:.2f} / {_f(okm(hi, 'base_speed_grasp_mean'))} | "
            f"{pg[0]:.2f} / {_f(lo['S_g'] if lo['success'] else None)} | {pg[1]:.2f} / {_f(hi['S_g'] if hi['success'] else None)} | "
            f"{pr[0]:.2%} / {_f(okm(lo, 'success_probability'), '{:.2%}')} | {pr[1]:.2%} / {_f(okm(hi, 'success_probability'), '{:.2%}')} |"
        )
    L.append(
        f"\ngamma: low {cases.TABLE4_GAMMA['low']}, high {cases.TABLE4_GAMMA['high']} (the paper does not state it).\n"
    )
    return "\n".join(L) + "\n"


def plot_fig5(fig5: dict, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(fig5), figsize=(11, 3.6), sharey=True)
    for ax, (name, p) in zip(axes, fig5.items()):
        if p["stages_completed"] == 0:
            ax.set_title(f"{name}: {p['status']}")
            continue
        t, base, grip = cases.speed_profiles(p)
        ax.plot(t, base, label="mobile base")
        ax.plot(t, grip, label="gripper")
        ax.axvspan(p["T1"], p["T2"], color="0.85", label="grasping")
        ax.set_title(f"Case 1, joint rates {name}")
        ax.set_xlabel("t (s)")
        ax.legend()
    axes[0].set_ylabel("speed (m/s)")
    fig.tight_layout()
    try:
        with atomic_open(path, "wb") as f:
            fig.savefig(f, format="png", dpi=120)
    finally:
        plt.close(fig)


def _replay(args: argparse.Namespace) -> int:
    path = os.path.join(args.out, "trajectories", f"{args.replay}.json")
    if not os.path.exists(path):
        raise FileNotFoundError(f"no trajectory {path} (names: caseN_sequential, caseN_single_shot_seedK, ...)")
    r = replay.replay_file(path, gui=args.gui)
    print(
        f"replayed {path} in PyBullet ({r['frames']} frames): tool error at T2 {r['tool_error_T2'][0]:.2e} m / "
        f"{r['tool_error_T2'][1]:.2e} rad, least link-obstacle distance {r['min_distance']:.3f} m "
        f"at t = {r['min_distance_t']:.2f} s"
    )
    return 0


def run_cases(args: argparse.Namespace) -> int:
    if getattr(args, "replay_only", False):
        if not args.replay:
            raise ValueError("--replay-only needs --replay NAME")
        return _replay(args)
    os.makedirs(args.out, exist_ok=True)
    metamodel = args.metamodel
    if metamodel is None:
        metamodel = cases.ensure_metamodel(
            os.path.join(args.out, f"metamodel_{cases.METAMODEL_PART}.json"), workers=args.workers
        )
    elif metamodel != cases.STANDIN:  # checked at the door: a NaN sigma_r must not reach the solver
        validate_metamodel(read_json(metamodel, "meta-model file"), metamodel)
    cfg = cases.CaseRunConfig(quick=args.quick, shots=args.shots, workers=args.workers, metamodel=metamodel)
    main = cases.run_main_cases(cfg)
    t4 = cases.run_table4(cfg)
    fig5 = cases.run_fig5(cfg)
    traj = os.path.join(args.out, "trajectories")
    for c, r in main.items():
        planner.save_plan(r["successive"], os.path.join(traj, f"case{c}_sequential"))
        for p in r["single_shot_all"]:
            planner.save_plan(p, os.path.join(traj, f"case{c}_single_shot_seed{p['seed']}"))
    for (c, lv), p in t4.items():
        planner.save_plan(p, os.path.join(traj, f"case{c}_{lv}_uncertainty"))
    for i, (name, p) in enumerate(fig5.items()):
        planner.save_plan(p, os.path.join(traj, f"fig5_case1_{'high' if i == 0 else 'low'}_rates"))
    src = (
        "STAND-IN surface planner.synthetic_rho (no physics behind it)"
        if cfg.metamodel == cases.STANDIN
        else f"meta-model {cfg.metamodel} (part-1 simulation)"
    )
    md = tables_markdown(main, t4, src)
    write_text(os.path.join(args.out, "tables.md"), md)
    plot_fig5(fig5, os.path.join(args.out, "fig5_speeds.png"))
    print(md)
    print(f"wrote {args.out}/tables.md, fig5_speeds.png and trajectories/")
    return _replay(args) if args.replay else 0


def main(argv=None) -> int:
    """Stand-alone entry (`python -m pickplan.pickup.cases_cli cases ...`) until the pickplan CLI wires
    in add_pickup_commands."""
    parser = argparse.ArgumentParser(prog="pickplan")
    add_pickup_commands(parser.add_subparsers(dest="command", required=True))
    add_verbosity_options(parser)
    args = parser.parse_args(["pickup"] + list(argv) if argv is not None else None)
    configure_logging(level_of(args))
    return args.func(args)


if __name__ == "__main__":
    import sys

    raise SystemExit(main(sys.argv[1:]))
