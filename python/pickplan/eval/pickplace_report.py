"""The ``bench pickplace`` table: per method (and per region kind, per target object) the pick, the
place planning, the complete executed pick and place, the held object's collisions on the true meshes
and the place planning time."""

from __future__ import annotations

import math
import os
from collections import Counter
from typing import Dict, List, Sequence

import numpy as np

from pickplan.core.io import write_json, write_text


def _rate(hits: int, n: int) -> float:
    return hits / n if n else float("nan")


def _median(xs) -> float:
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return float(np.median(xs)) if xs else float("nan")


def summarize_group(rs: Sequence[dict]) -> dict:
    """Rates of one group of unit records (graspable targets only; errors count as failures)."""
    valid = [r for r in rs if r.get("valid", True) and r.get("graspable", True)]
    picked = [r for r in valid if r.get("pick_success")]
    planned = [r for r in picked if r.get("place_success") and r.get("status") == "success"]
    executed = any(r.get("execution_run", True) for r in valid)
    return {
        "units": len(rs),
        "graspable": len(valid),
        "ungraspable": sum(not r.get("graspable", True) for r in rs),
        "errors": sum(r.get("status") == "error" for r in rs),
        "pick": _rate(len(picked), len(valid)),
        "place": _rate(sum(r.get("place_success", False) for r in picked), len(picked)),
        "plan": _rate(len(planned), len(valid)),
        "complete": _rate(sum(r.get("complete", False) for r in valid), len(valid)) if executed else None,
        "complete_of_planned": _rate(sum(r.get("complete", False) for r in planned), len(planned))
        if executed
        else None,
        "held_collisions": sum(bool(r.get("held_collision")) for r in planned),
        "robot_collisions": sum(bool(r.get("robot_collision")) for r in planned),
        "place_time_median": _median(r.get("place_time") for r in picked if r.get("place_goals")),
        "attach_time_median": _median(r.get("attach_time") for r in picked),
        "pick_time_median": _median(
            r.get("pick_time") for r in valid if r.get("pick_status") not in (None, "no_goals")
        ),
        "place_goals_mean": float(np.mean([r["place_goals"] for r in picked if "place_goals" in r] or [float("nan")])),
        "no_place_goals": dict(Counter(r.get("place_verdict") for r in picked if r.get("place_goals") == 0)),
        "failures": dict(Counter(r.get("execution_status") for r in planned if not r.get("complete"))),
        "replanned": sum(bool(r.get("replanned")) for r in planned),
    }


def summarize(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, dict]:
    return {m: summarize_group([r for r in records if r["method"] == m]) for m in methods}


def _pct(x) -> str:
    return "not run" if x is None else ("n/a" if x != x else f"{100 * x:.0f}%")


ROWS = (
    ("pick", "Pick planned (of graspable)", _pct),
    ("place", "Place planned (of picks planned)", _pct),
    ("plan", "Pick and place planned (of graspable)", _pct),
    ("complete", "Complete, executed (of graspable)", _pct),
    ("complete_of_planned", "Complete, executed (of planned)", _pct),
    ("held_collisions", "Held object in collision, true meshes (planned units)", str),
    ("robot_collisions", "Robot in collision on the carry, true meshes (planned units)", str),
    ("place_time_median", "Place planning, median (ms CPU: goal set + transfer)", lambda x: f"{1000 * x:.1f}"),
    (
        "attach_time_median",
        "Held world per grasp, median (ms CPU: FCL models, CHOMP problem)",
        lambda x: f"{1000 * x:.1f}",
    ),
    ("pick_time_median", "Pick planning, median (ms CPU: goal set + plan; for scale)", lambda x: f"{1000 * x:.1f}"),
    ("place_goals_mean", "Place goals, mean", lambda x: f"{x:.1f}"),
    ("replanned", "Replanned for the executed grasp (units)", str),
)


def markdown(summary: Dict[str, dict], by_region: Dict[str, Dict[str, dict]], header: str) -> str:
    methods = list(summary)
    lines = [header, "", "| | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
    for key, label, fmt in ROWS:
        lines.append(f"| {label} | " + " | ".join(fmt(summary[m][key]) for m in methods) + " |")
    lines.append(  # an error (an exception in a unit) is a failure to see at once, not a footnote
        "| Units (graspable / all; errors) | "
        + " | ".join(f"{summary[m]['graspable']}/{summary[m]['units']}; {summary[m]['errors']}" for m in methods)
        + " |"
    )
    lines.append(
        "| Execution failures | "
        + " | ".join(", ".join(f"{k} {v}" for k, v in summary[m]["failures"].items()) or "-" for m in methods)
        + " |"
    )
    lines.append(
        "| Empty place goal sets | "
        + " | ".join(", ".join(f"{k} {v}" for k, v in summary[m]["no_place_goals"].items()) or "-" for m in methods)
        + " |"
    )
    lines += [
        "",
        "### Per region (complete / place planned of picks planned)",
        "",
        "| Region | " + " | ".join(methods) + " |",
        "|---" * (len(methods) + 1) + "|",
    ]
    for region, row in by_region.items():
        lines.append(
            f"| {region} | "
            + " | ".join(
                f"{_pct(row[m]['complete'])} / {_pct(row[m]['place'])} ({row[m]['graspable']})" for m in methods
            )
            + " |"
        )
    return "\n".join(lines) + "\n"


def by_key(records: Sequence[dict], methods: Sequence[str], key: str) -> Dict[str, Dict[str, dict]]:
    return {
        v: summarize(records_with, methods)
        for v in sorted({r.get(key) for r in records if r.get(key)})
        for records_with in [[r for r in records if r.get(key) == v]]
    }


def object_markdown(by_object: Dict[str, Dict[str, dict]], methods: Sequence[str]) -> str:
    lines = [
        "### Per target object (complete / place planned of picks planned (graspable units))",
        "",
        "| Object | " + " | ".join(methods) + " |",
        "|---" * (len(methods) + 1) + "|",
    ]
    for obj, row in by_object.items():
        lines.append(
            f"| {obj} | "
            + " | ".join(
                f"{_pct(row[m]['complete'])} / {_pct(row[m]['place'])} ({row[m]['graspable']})" for m in methods
            )
            + " |"
        )
    return "\n".join(lines) + "\n"


def write_report(out: str, records: List[dict], methods: Sequence[str], header: str, write_csv) -> str:
    """table.md, runs.csv (one row per unit), runs.json, summary.json, objects.json in ``out``."""
    summary = summarize(records, methods)
    by_region = by_key(records, methods, "region")
    by_object = by_key(records, methods, "target")
    text = markdown(summary, by_region, header) + "\n" + object_markdown(by_object, methods)
    write_text(os.path.join(out, "table.md"), text)
    write_csv(os.path.join(out, "runs.csv"), records)
    write_json(os.path.join(out, "runs.json"), records)
    write_json(os.path.join(out, "summary.json"), {"methods": summary, "regions": by_region})
    write_json(os.path.join(out, "objects.json"), by_object)
    return text
