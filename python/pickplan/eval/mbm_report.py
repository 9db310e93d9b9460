"""The ``bench mbm`` tables: per set and planner, success (planner solved and the independent checker
accepts), planning time (median, mean, 95th percentile, CPU of the planning thread and wall clock), path
length, smoothness and clearance; then per-problem ratios of pickplan to each baseline."""

from __future__ import annotations

from typing import Dict, List, Sequence

import numpy as np

OURS = "pickplan"


def _stats(values) -> tuple:
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=float)
    if len(v) == 0:
        return (float("nan"),) * 3
    return float(np.median(v)), float(np.mean(v)), float(np.percentile(v, 95))


def _median(values) -> float:
    v = np.asarray([x for x in values if np.isfinite(x)], dtype=float)
    return float(np.median(v)) if len(v) else float("nan")


def _groups(rows: List[dict]) -> Dict[tuple, List[dict]]:
    out: Dict[tuple, List[dict]] = {}
    for r in rows:
        out.setdefault((r["set"], r["planner"]), []).append(r)
        out.setdefault(("all", r["planner"]), []).append(r)
    return out


def summary_table(rows: List[dict], planners: Sequence[str], vamp_available: bool) -> str:
    lines = ["# MotionBenchMaker", ""]
    if "vamp" in planners and not vamp_available:
        lines += [
            "VAMP: not importable in this environment (build it with ../shared/tools/vamp/build-vamp.sh); "
            "its rows are absent.",
            "",
        ]
    lines += [
        "success: the planner solved the problem and the independent checker (FCL on the URDF's meshes, "
        "<= 2 mm of robot motion between checked states) accepts the path. Times over successful problems, "
        "in ms: CPU of the planning thread (wall clock in brackets). Path length: joint-space (rad); "
        "smoothness: sum of squared turning angles at 64 equal-length segments (rad^2, 0 for a straight "
        "line); clearance: smallest robot-obstacle distance (m). Medians unless said.",
        "",
        "| set | planner | success | solved, rejected | time median | mean | p95 | length | smoothness | clearance |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    groups = _groups(rows)
    sets = sorted({s for s, _ in groups if s != "all"}) + ["all"]
    for s in sets:
        for p in planners:
            g = groups.get((s, p))
            if not g:
                continue
            ok = [r for r in g if r["success"]]
            cpu, wall = _stats(r["cpu_ms"] for r in ok), _stats(r["time_ms"] for r in ok)
            solved = sum(r["solved"] for r in g)
            lines.append(
                f"| {s} | {p} | {100 * len(ok) / len(g):.1f} % ({len(ok)}/{len(g)}) | {solved}, {solved - len(ok)} "
                f"| {cpu[0]:.2f} ({wall[0]:.2f}) | {cpu[1]:.2f} ({wall[1]:.2f}) | {cpu[2]:.2f} ({wall[2]:.2f}) "
                f"| {_median(r['path_length'] for r in ok):.3f} | {_median(r['smoothness'] for r in ok):.3f} "
                f"| {_median(r['min_clearance'] for r in ok):.4f} |"
            )
    lines += ["", ratios(rows, planners)]
    return "\n".join(lines) + "\n"


def ratios(rows: List[dict], planners: Sequence[str]) -> str:
    """Medians over the problems both planners solve of pickplan's value divided by the baseline's."""
    by = {(r["set"], r["problem"], r["planner"]): r for r in rows}
    lines = [
        "## pickplan / baseline, per problem (medians over problems both succeed on)",
        "",
        "| set | baseline | problems | time (CPU) | time (wall) | path length | smoothness (ours - theirs) |",
        "|---|---|---|---|---|---|---|",
    ]
    sets = sorted({r["set"] for r in rows}) + ["all"]
    for base in [p for p in planners if p != OURS]:
        for s in sets:
            keys = [(k[0], k[1]) for k in by if k[2] == OURS and (s == "all" or k[0] == s)]
            pairs = [(by[(a, b, OURS)], by[(a, b, base)]) for a, b in keys if (a, b, base) in by]
            pairs = [(o, t) for o, t in pairs if o["success"] and t["success"]]
            if not pairs:
                continue

            def ratio(key):
                return _median(o[key] / t[key] if t[key] > 0 else float("nan") for o, t in pairs)

            lines.append(
                f"| {s} | {base} | {len(pairs)} | {ratio('cpu_ms'):.2f} | {ratio('time_ms'):.2f} "
                f"| {ratio('path_length'):.3f} | {_median(o['smoothness'] - t['smoothness'] for o, t in pairs):.3f} |"
            )
    return "\n".join(lines)
