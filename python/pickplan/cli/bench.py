"""``pickplan bench selection|refinement|planners|ablation``: the OMG paper's Tables I, II, III and
Fig. 8 with one command each; Markdown tables with the paper's numbers beside ours, CSV/JSON of
every run, the Fig. 8 plot.

Wired into ``pickplan.cli`` through ``add_bench_commands``; also runs on its own:
``python -m pickplan.experiments_cli bench selection --quick --out /tmp/t1``.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import os
import sys
from typing import Dict, List, Optional, Sequence

from pickplan.cli.output import add_verbosity_options, configure_logging, level_of
from pickplan.eval.experiments import SweepSettings, methods_for, run_sweep
from pickplan.eval.methods import TABLES
from pickplan.eval.summaries import (
    OUTCOMES,
    grasp_costs_by_object,
    object_markdown,
    slip_cell,
    summarize,
    summarize_by_object,
)
from pickplan.cli.scenes import clutter_range
from pickplan.sim.layouts import Layout
from pickplan.sim.scenes import ORIENTATIONS
from pickplan.cli.exit_codes import run_command
from pickplan.cli.bench_mbm import add_mbm_command
from pickplan.cli.bench_moving import add_moving_command
from pickplan.cli.robots import ROBOT_HELP
from pickplan.core.io import write_json, write_text
from pickplan.eval.plots import plot_table
from pickplan.eval.pickplace_bench import run_pickplace_bench
from pickplan.eval.perception import PerceptionBenchSettings, run_perception_bench, write_report as perception_report

# The paper's numbers (100 scenes, 30 grasps, 10 runs; Table II: 60 grasps, 30 refinement iterations).
PAPER: Dict[str, Dict[str, dict]] = {
    "selection": {
        "execution": dict(Fixed=0.74, Proj=0.75, FTC=0.81, FTL=0.79, EXP=0.80, MD=0.81),
        "planning": dict(Fixed=0.78, Proj=0.79, FTC=0.91, FTL=0.89, EXP=0.90, MD=0.92),
        "smoothness": dict(Fixed=18.87, Proj=11.24, FTC=15.78, FTL=15.86, EXP=15.71, MD=15.54),
        "collision": dict(Fixed=5.97, Proj=12.06, FTC=4.68, FTL=4.10, EXP=4.95, MD=3.87),
        "time": dict(Fixed=0.18, Proj=0.15, FTC=0.20, FTL=0.22, EXP=0.23, MD=0.30),
    },
    "planners": {
        "execution": {"CHOMP": 0.77, "CHOMP-C": 0.75, "FMT": 0.66, "RRT-C": 0.64, "OMG": 0.84},
        "planning": {"CHOMP": 0.82, "CHOMP-C": 0.79, "FMT": 0.80, "RRT-C": 0.78, "OMG": 0.93},
        "smoothness": {"CHOMP": 19.12, "CHOMP-C": 11.24, "FMT": 27.21, "RRT-C": 26.45, "OMG": 15.43},
        "collision": {"CHOMP": 4.78, "CHOMP-C": 12.06, "FMT": 6.37, "RRT-C": 6.52, "OMG": 3.92},
        "grasp": {"CHOMP": 3.43, "CHOMP-C": 3.35, "FMT": 3.49, "RRT-C": 3.48, "OMG": 3.04},
        "time": {"CHOMP": 0.25, "CHOMP-C": 0.15, "FMT": 0.67, "RRT-C": 0.22, "OMG": 0.42},
    },
    "refinement": {
        "mean": {"S": 3.62, "S+ISF": 2.77, "G": 4.72, "G+ISF": 3.63, "A": 7.83, "A+ISF": 5.43},
        "planning": {"S": 0.92, "S+ISF": 0.93, "G": 0.84, "G+ISF": 0.84, "A": 0.71, "A+ISF": 0.73},
        "execution": {"S": 0.80, "S+ISF": 0.82, "G": 0.56, "G+ISF": 0.59, "A": 0.26, "A+ISF": 0.33},
    },
}
PAPER_GRASP_COSTS = {  # Table II rows: S, S refined, G, G refined, A, A refined
    "003_cracker_box": (2.47, 2.32, 4.27, 3.31, 6.58, 4.36),
    "025_mug": (5.11, 3.93, 7.24, 5.55, 9.05, 5.18),
    "005_tomato_soup_can": (2.38, 2.27, 3.15, 2.83, 7.06, 6.27),
    "006_mustard_bottle": (4.40, 3.19, 4.91, 3.79, 8.15, 5.73),
    "010_potted_meat_can": (2.96, 1.95, 3.08, 2.54, 7.47, 4.91),
    "019_pitcher_base": (4.41, 2.97, 5.68, 3.76, 8.69, 6.14),
}
ROWS = {
    "selection": ("execution", "planning", "smoothness", "collision", "time", "goal_set_time", "duration"),
    "planners": ("execution", "planning", "smoothness", "collision", "grasp", "time", "goal_set_time", "duration"),
    "refinement": ("planning", "execution", "time", "goal_set_time", "duration"),
    "ablation": ("execution", "planning", "smoothness", "collision", "grasp", "time", "goal_set_time", "duration"),
}
LABELS = {
    "execution": "Execution",
    "planning": "Planning",
    "smoothness": "Smoothness",
    "collision": "Collision",
    "grasp": "Grasp",
    "time": "Time (s, planning)",
    "goal_set_time": "Goal-set time (s)",
    "mean": "Mean",
    "duration": "Trajectory duration (s, timed within the joint limits)",
}
RATES = ("execution", "planning")


def _fmt(key: str, value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "n/a"
    return f"{100 * value:.0f}%" if key in RATES else f"{value:.2f}"


def _cell(table: str, key: str, method: str, ours, run: bool = True) -> str:
    """Ours (paper); a column that was not run (execution with --no-execute) says so, never a zero."""
    paper = PAPER.get(table, {}).get(key, {}).get(method)
    return (_fmt(key, ours) if run else "not run") + (f" ({_fmt(key, paper)})" if paper is not None else "")


def _object_label(name: str) -> str:
    return " ".join(w.capitalize() for w in name.split("_")[1:]) or name


def markdown(table: str, summary: Dict[str, dict], records: Sequence[dict], header: str) -> str:
    methods = list(summary)
    lines = [
        header,
        "",
        "Cells: ours (paper). Rates over all valid units: a scene without goals or a failed",
        "plan is a failed execution. Means over units that produced a trajectory.",
        "",
    ]
    lines += ["| Algorithm | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    if table == "refinement":
        costs = grasp_costs_by_object(records, methods)
        order = ["S", "S+ISF", "G", "G+ISF", "A", "A+ISF"]
        for obj, row in costs.items():
            paper = PAPER_GRASP_COSTS.get(obj)
            cells = []
            for m in methods:
                p = paper[order.index(m)] if paper and m in order else None
                cells.append(_fmt("grasp", row[m]) + (f" ({p:.2f})" if p is not None else ""))
            lines.append(f"| {_object_label(obj)} | " + " | ".join(cells) + " |")
        lines.append("| Mean | " + " | ".join(_cell(table, "mean", m, summary[m]["grasp"]) for m in methods) + " |")
    for key in ROWS[table]:
        lines.append(
            f"| {LABELS[key]} | "
            + " | ".join(
                _cell(table, key, m, summary[m][key], key != "execution" or summary[m].get("execution_run", True))
                for m in methods
            )
            + " |"
        )
    lines.append(
        "| Units (valid / planned) | "
        + " | ".join(f"{summary[m]['valid']}/{summary[m]['units']} ({summary[m]['planned']})" for m in methods)
        + " |"
    )
    lines.append(
        "| Slip in the hand (mm / deg, median of lifted; slipped > 1 cm or 10 deg) | "
        + " | ".join(slip_cell(summary[m]) for m in methods)
        + " |"
    )
    lines.append(
        "| Failed executions: "
        + " / ".join(OUTCOMES)
        + " | "
        + " | ".join(" / ".join(str(summary[m].get(k, 0)) for k in OUTCOMES) for m in methods)
        + " |"
    )
    failed_plans = ("in_collision", "not_smooth")  # planned, the success test failed
    lines.append(
        "| Failed plans: "
        + " / ".join(failed_plans)
        + " | "
        + " | ".join(
            " / ".join(str(sum(r.get("method") == m and r.get("status") == k for r in records)) for k in failed_plans)
            for m in methods
        )
        + " |"
    )
    lines.append("| No goals (units) | " + " | ".join(str(summary[m].get("no_goals", 0)) for m in methods) + " |")
    lines.append(
        "| Ungraspable targets (units, not in the rates) | "
        + " | ".join(str(summary[m].get("ungraspable", 0)) for m in methods)
        + " |"
    )
    return "\n".join(lines) + "\n"


def object_rows(by_object: Dict[str, Dict[str, dict]]) -> List[dict]:
    """objects.csv: one row per target object and method."""
    return [
        {
            "object": obj,
            "method": m,
            **{k: v for k, v in c.items() if not k.endswith("_reasons")},
            "no_goals_reasons": ";".join(f"{k}:{v}" for k, v in c["no_goals_reasons"].items()),
            "ungraspable_reason": ";".join(c["ungraspable_reasons"]),
        }
        for obj, row in by_object.items()
        for m, c in row.items()
    ]


def write_csv(path: str, records: Sequence[dict]) -> None:
    keys = sorted({k for r in records for k in r})
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys)
    w.writeheader()
    for r in records:
        w.writerow(r)
    write_text(path, buf.getvalue())


def plot_ablation(path: str, summary: Dict[str, dict]) -> None:
    """Fig. 8: metrics against n and lambda, each scaled to [0, 1] by its maximum (planning rate as is)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, prefix, label in ((axes[0], "n=", "n"), (axes[1], "lambda=", "lambda")):
        ms = [m for m in summary if m.startswith(prefix)]
        if not ms:
            ax.set_visible(False)
            continue
        xs = [float(m[len(prefix) :]) for m in ms]
        for key in ("planning", "execution", "smoothness", "collision", "time"):
            ys = [math.nan if summary[m][key] is None else summary[m][key] for m in ms]  # None: not run
            top = max((y for y in ys if y == y), default=0.0)
            if key not in RATES and top > 0:
                ys = [y / top for y in ys]
            ax.plot(xs, ys, marker="o", label=key)
        if prefix == "lambda=":
            ax.set_xscale("log")
        ax.set_xlabel(label)
        ax.set_ylim(-0.05, 1.05)
        ax.legend(fontsize=8)
    fig.suptitle("Ablation of n and lambda (OMG, metrics except planning scaled to [0, 1])")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def write_report(settings: SweepSettings, records: List[dict]) -> str:
    """table.md with table.png beside it, runs.csv, runs.json, summary.json (and fig8.png for the
    ablation) in ``settings.out``."""
    s = settings.effective()
    methods = methods_for(s)
    summary = summarize(records, methods)
    scenes = len({r["scene"] for r in records})
    titles = {
        "selection": "Table I: grasp selection",
        "refinement": "Table II: grasp refinement",
        "planners": "Table III: planners",
        "ablation": "Fig. 8: ablation of n and lambda",
    }
    objects = s.objects or (f"as in the scenes of {s.scene_dir}" if s.scene_dir else "built-in")
    poses = (
        ""
        if s.scene_dir
        else f", poses: {s.poses}, {s.clutter[0]}-{s.clutter[1]} objects per scene"
        if s.layout is Layout.table
        else f", {s.layout.value} layouts"
    )
    poses += f", {s.grasp_kind} grasps" if s.grasp_kind else ""
    header = (
        f"## {titles[s.table]}: {scenes} scenes, {s.grasps} grasps each scene, {s.runs} runs"
        f" (objects: {objects}{poses})"
    )
    by_object = summarize_by_object(records, methods)
    text = markdown(s.table, summary, records, header) + "\n" + object_markdown(by_object, methods)
    errors = {m: row["errors"] for m, row in summary.items() if row["errors"]}
    if errors:
        text += (
            "\nUnits that raised an error (counted as failed plans; reasons in runs.json): "
            + ", ".join(f"{m} {n}" for m, n in errors.items())
            + "\n"
        )
    write_text(os.path.join(s.out, "table.md"), text)
    write_csv(os.path.join(s.out, "runs.csv"), records)
    write_csv(os.path.join(s.out, "objects.csv"), object_rows(by_object))
    write_json(os.path.join(s.out, "objects.json"), by_object)
    write_json(os.path.join(s.out, "runs.json"), records)
    write_json(os.path.join(s.out, "summary.json"), summary)
    if s.table == "ablation":
        plot_ablation(os.path.join(s.out, "fig8.png"), summary)
    plot_table(os.path.join(s.out, "table.png"), records, methods, header.lstrip("# "))
    return text


def settings_from_args(args: argparse.Namespace) -> SweepSettings:
    return SweepSettings(
        args.table,
        out=args.out or os.path.join("out", "bench", args.table),
        scenes=args.scenes,
        scene_dir=args.scene_dir,
        objects=args.objects,
        grasps=args.grasps,
        grasp_candidates=args.grasp_candidates,
        runs=args.runs,
        methods=tuple(args.methods) if args.methods else None,
        quick=args.quick,
        workers=args.workers,
        ray=args.ray,
        seed=args.seed,
        iterations=args.iterations,
        execute=not args.no_execute,
        timed_execution=args.timed_execution,
        time_limit=args.time_limit,
        max_goals_tried=args.max_goals_tried,
        robot=args.robot,
        poses=args.poses,
        clutter=tuple(args.clutter),
        layout=args.layout,
        grasp_kind=getattr(args, "grasp_kind", None),
        progress=False if args.no_progress else None,
    )


def run_bench(args: argparse.Namespace) -> int:
    settings = settings_from_args(args)
    if settings.table == "pickplace":
        print(run_pickplace_bench(settings, write_csv))
        return 0
    records = run_sweep(settings)
    print(write_report(settings, records))
    print(
        f"wrote {settings.out}/table.md, table.png, runs.csv, runs.json, summary.json, objects.csv, objects.json"
        + (", fig8.png" if settings.table == "ablation" else "")
    )
    return 0


def add_bench_commands(subparsers) -> None:
    """Add ``bench selection|refinement|planners|ablation`` to a ``pickplan`` sub-parser set."""
    bench = subparsers.add_parser("bench", help="reproduce the OMG paper's tables (I, II, III, Fig. 8)")
    sub = bench.add_subparsers(dest="table", required=True)
    helps = {
        "selection": "Table I: goal selection (Fixed, Proj, FTC, FTL, EXP, MD; no refinement)",
        "refinement": "Table II: grasp sets S/G/A with and without C-Space ISF",
        "planners": "Table III: CHOMP, CHOMP-C, FMT, RRT-C, OMG",
        "ablation": "Fig. 8: OMG over the discretization n and the smoothness weight lambda",
        "pickplace": "pick and place: OMG's pick, then OMG / Fixed / CHOMP / RRT-C on the place (issue 34)",
    }
    for table in TABLES:
        p = sub.add_parser(table, help=helps[table])
        p.add_argument("--scenes", type=int, default=100, help="generated scenes (default 100)")
        p.add_argument("--scene-dir", default=None, help="load scene JSON files from here instead")
        p.add_argument(
            "--objects",
            default=None,
            help="generated scenes' objects: builtin, procedural or a YCB-layout folder "
            "(default: $PICKPLAN_YCB_DIR if set, else builtin)",
        )
        p.add_argument(
            "--poses",
            choices=ORIENTATIONS,
            default="upright",
            help="generated scenes' object poses: upright (the paper's), stable (drawn by drop "
            "probability: lying bottles, boxes on any face) or resting",
        )
        p.add_argument(
            "--clutter",
            type=clutter_range,
            default=(3, 7),
            metavar="N-M",
            help="objects per generated scene, fewest-most (default 3-7, the paper's)",
        )
        p.add_argument(
            "--layout",
            choices=[k.value for k in Layout],
            default=Layout.table.value,
            help="generated scenes' family: table (the paper's), shelf, bin or cabinet "
            "(pickplan scenes --layout; --poses and --clutter are the table's)",
        )
        if table != "refinement":
            p.add_argument(
                "--grasp-kind",
                default=None,
                choices=("simulated", "graspit", "approach", "antipodal"),
                help="every method's grasp set (default: simulated, stored or physics-verified); "
                "antipodal: generated per scene, aware of the table under the target",
            )
        p.add_argument("--grasps", type=int, default=30, help="goal-set size per scene (default 30)")
        p.add_argument(
            "--grasp-candidates",
            type=int,
            default=100,
            help="grasps generated per object without a stored set (default 100)",
        )
        p.add_argument("--runs", type=int, default=10, help="runs per scene and method (default 10)")
        p.add_argument("--methods", nargs="+", default=None, help="subset of the table's methods")
        p.add_argument("--quick", action="store_true", help="CI setting: <= 4 scenes, 1 run, 10 goals")
        p.add_argument(
            "--out",
            default=os.path.join("out", "bench", table),
            help="output folder (default out/bench/TABLE); resumes there",
        )
        p.add_argument("--workers", type=int, default=2, help="local worker processes (<= 1: serial)")
        p.add_argument("--ray", default=None, help="Ray cluster address, or 'local' to start Ray here")
        p.add_argument("--seed", type=int, default=0)
        p.add_argument("--robot", default="panda", help=ROBOT_HELP)
        p.add_argument("--iterations", type=int, default=50)
        p.add_argument("--time-limit", type=float, default=1.0, help="OMPL seconds per goal")
        p.add_argument("--max-goals-tried", type=int, default=5, help="ranked goals tried by the baselines")
        p.add_argument("--no-execute", action="store_true", help="skip PyBullet execution")
        p.add_argument(
            "--timed-execution",
            action="store_true",
            help="execute the plans timed within the Panda's limits (default: 0.1 s per waypoint)",
        )
        p.add_argument("--no-progress", action="store_true")
        p.set_defaults(handler=run_bench)
    add_perception_command(sub)
    add_mbm_command(sub)
    add_moving_command(sub)


def run_perception(args: argparse.Namespace) -> int:
    settings = PerceptionBenchSettings(
        out=args.out,
        scenes=args.scenes,
        objects=args.objects,
        poses=args.poses,
        clutter=tuple(args.clutter),
        mesh_grasps=args.mesh_grasps,
        views=tuple(args.views),
        noises=tuple(n / 1000 for n in args.noise_mm),
        mesh=not args.no_mesh,
        grasps=args.grasps,
        iterations=args.iterations,
        execute=not args.no_execute,
        workers=args.workers,
        seed=args.seed,
        progress=False if args.no_progress else None,
    )
    print(perception_report(settings, run_perception_bench(settings)))
    print(f"wrote {settings.out}/table.md, summary.json, runs.json")
    return 0


def add_perception_command(sub) -> None:
    p = sub.add_parser("perception", help="OMG from depth cameras (1 and 3 views, depth noise) beside known meshes")
    p.add_argument("--scenes", type=int, default=100, help="generated scenes (default 100)")
    p.add_argument("--objects", default=None, help="generated scenes' objects: builtin, procedural or a YCB folder")
    p.add_argument("--poses", choices=ORIENTATIONS, default="upright", help="generated scenes' object poses")
    p.add_argument("--clutter", type=clutter_range, default=(3, 7), metavar="N-M", help="objects per scene")
    p.add_argument(
        "--mesh-grasps",
        default=None,
        choices=("simulated", "antipodal"),
        help="the known-mesh column's grasps (default: stored or simulated; antipodal: generated per scene)",
    )
    p.add_argument("--views", type=int, nargs="+", default=[1, 3], help="camera counts (default 1 3)")
    p.add_argument("--noise-mm", type=float, nargs="+", default=[0.0, 2.0, 5.0], help="depth sigmas (default 0 2 5)")
    p.add_argument("--no-mesh", action="store_true", help="skip the known-mesh column")
    p.add_argument("--grasps", type=int, default=30, help="goal-set size per scene (default 30)")
    p.add_argument("--iterations", type=int, default=50)
    p.add_argument("--out", default="out/bench/perception", help="output folder; resumes there")
    p.add_argument("--workers", type=int, default=2, help="local worker processes (<= 1: serial)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-execute", action="store_true", help="skip PyBullet execution")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(handler=run_perception)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="pickplan", description=__doc__.splitlines()[0])
    add_bench_commands(parser.add_subparsers(dest="command", required=True))
    add_verbosity_options(parser)
    args = parser.parse_args(argv)
    configure_logging(level_of(args))
    code = run_command("bench", args.handler, args)
    if code:  # as argparse does for its own errors: the stand-alone entry exits
        raise SystemExit(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
