"""Summaries of sweep records: the paper tables' rows per method, and per target object (planning,
execution, the slip of lifted targets in the hand and the failed executions by status, no_goals with
their reasons, ungraspable targets counted apart)."""

from __future__ import annotations

import math
from collections import Counter
from typing import Dict, Iterable, Optional, Sequence

import numpy as np

from pickplan.omg.planner import PlanStatus

UNIT_ERROR = "error"  # the status of a sweep unit whose function raised (experiments.error_record)


def _mean(xs: Iterable[Optional[float]]) -> float:
    xs = [x for x in xs if x is not None and math.isfinite(x)]
    return float(np.mean(xs)) if xs else float("nan")


def _graspable(r: dict) -> bool:
    return r.get("graspable", True)  # records made before the verdict existed: graspable


SLIPPED = (0.01, 10.0)  # m, deg: a lifted target that moved or turned this much in the hand slipped
OUTCOMES = ("dropped", "missed", "collision", "blocked")  # failed executions of successful plans, by status


def execution_outcomes(rs: Sequence[dict]) -> dict:
    """Of units' records: the slip of the targets in the hand (median over lifted units, m and deg;
    None with no lifted unit, as for a column not run: nan would make two equal tables compare
    unequal), how many lifted targets slipped (``SLIPPED``), and the failed executions by status."""
    lifted = [r for r in rs if r.get("execution_success")]
    slips = [r.get("slip") for r in lifted]
    turns = [r.get("slip_rotation") for r in lifted]
    known = [(a, b) for a, b in zip(slips, turns) if a is not None and b is not None and math.isfinite(a)]
    return {
        "slip": float(np.median([a for a, _ in known])) if known else None,
        "slip_rotation": float(np.median([b for _, b in known])) if known else None,
        "slipped": sum(a > SLIPPED[0] or b > SLIPPED[1] for a, b in known),
        **{k: sum(r.get("execution_status") == k for r in rs) for k in OUTCOMES},
    }


def summarize(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, dict]:
    """Per method: units, valid units (grasp set available, target graspable), plans (a goal set
    existed), rates over valid units (no goals = failed plan = failed execution), means of the metrics
    over plans; units whose target no grasp of the gripper can hold (``ungraspable``) are counted apart."""
    out = {}
    for m in methods:
        rs = [r for r in records if r["method"] == m]
        valid = [r for r in rs if r.get("valid", True) and _graspable(r)]
        planned = [r for r in valid if r.get("planned")]
        n = len(valid)
        executed = any(r.get("execution_run", True) for r in valid)  # False: --no-execute, a column not run
        out[m] = {
            "units": len(rs),
            "valid": n,
            "planned": len(planned),
            "errors": sum(r["status"] == UNIT_ERROR for r in rs),
            "no_goals": sum(r["status"] == PlanStatus.no_goals for r in valid),
            "ungraspable": sum(not _graspable(r) for r in rs),
            "planning_successes": sum(r["planning_success"] for r in valid),
            "execution_successes": sum(r["execution_success"] for r in valid),
            "planning": sum(r["planning_success"] for r in valid) / n if n else float("nan"),
            "execution": (sum(r["execution_success"] for r in valid) / n if n else float("nan")) if executed else None,
            "execution_run": executed,
            "smoothness": _mean(r["smoothness"] for r in planned),
            "collision": _mean(r["collision"] for r in planned),
            "grasp": _mean(r["grasp_cost"] for r in planned),
            "time": _mean(r["plan_time"] for r in planned),
            "duration": _mean(r.get("trajectory_duration") for r in planned),
            "goal_set_time": _mean(r["goal_set_time"] for r in planned),
            "goal_set_size": _mean(r["goal_set_size"] for r in planned),
            **execution_outcomes(valid),
        }
    return out


def grasp_costs_by_object(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, Dict[str, float]]:
    """Table II's rows: mean f_grasp at the final goal per target object and method (plans only)."""
    objects = sorted({r["target"] for r in records if r.get("planned")})
    return {
        o: {
            m: _mean(r["grasp_cost"] for r in records if r["method"] == m and r["target"] == o and r.get("planned"))
            for m in methods
        }
        for o in objects
    }


def summarize_by_object(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, Dict[str, dict]]:
    """Per target object and method: units, graspable units, planning and execution rates over those,
    no_goals units with their grasps' rejection reasons summed, and ungraspable units with the verdict."""
    out: Dict[str, Dict[str, dict]] = {}
    for obj in sorted({r["target"] for r in records if r.get("target")}):
        out[obj] = {}
        for m in methods:
            rs = [r for r in records if r["method"] == m and r.get("target") == obj and r.get("valid", True)]
            ok = [r for r in rs if _graspable(r)]
            reasons: Counter = Counter()
            for r in ok:
                if r["status"] == PlanStatus.no_goals:
                    reasons.update(r.get("goal_reasons") or {})
            n = len(ok)
            executed = any(r.get("execution_run", True) for r in ok)
            out[obj][m] = {
                "units": len(rs),
                "graspable": n,
                "planning": sum(r["planning_success"] for r in ok) / n if n else float("nan"),
                "execution": (sum(r["execution_success"] for r in ok) / n if n else float("nan")) if executed else None,
                "no_goals": sum(r["status"] == PlanStatus.no_goals for r in ok),
                "no_goals_reasons": dict(reasons.most_common()),
                "ungraspable": len(rs) - n,
                "ungraspable_reasons": dict(Counter(r.get("reason", "") for r in rs if not _graspable(r))),
                **execution_outcomes(ok),
            }
    return out


def slip_cell(c: dict) -> str:
    """A table cell of ``execution_outcomes``' slip: "mm / deg (slipped units)", n/a with no lifted unit."""
    if c.get("slip") is None or not math.isfinite(c["slip"]):
        return "n/a"
    return f"{1000 * c['slip']:.1f} / {c['slip_rotation']:.1f} ({c['slipped']})"


def _percent(x: Optional[float]) -> str:
    return "n/a" if x is None or not math.isfinite(x) else f"{100 * x:.0f}%"


def _reasons(counts: Dict[str, int], top: int = 3) -> str:
    items = sorted(counts.items(), key=lambda kv: -kv[1])
    return ", ".join(f"{k} {v}" for k, v in items[:top]) + (", ..." if len(items) > top else "")


def object_markdown(by_object: Dict[str, Dict[str, dict]], methods: Sequence[str]) -> str:
    """Per target object: planning / execution rates (over graspable units) per method, the no-goal
    units with the grasps' rejection reasons, and the ungraspable units with the verdict."""
    lines = [
        "### Per target object",
        "",
        "Cells: planning / execution over the units whose target is graspable (units). Slip: mm / deg the "
        "lifted targets moved in the hand (median), per method. Failed: " + " / ".join(OUTCOMES) + ", summed "
        "over methods. No goals: units per method, then the grasps' rejection reasons summed. Ungraspable: "
        "units, not counted in any rate.",
        "",
        "| Object | " + " | ".join(methods) + " | Slip | Failed | No goals | Ungraspable |",
        "|---" * (len(methods) + 5) + "|",
    ]
    for obj, row in by_object.items():
        cells = []
        for m in methods:
            c = row[m]
            execution = "not run" if c["execution"] is None else _percent(c["execution"])
            cells.append(f"{_percent(c['planning'])} / {execution} ({c['graspable']})" if c["graspable"] else "-")
        no_goals = ", ".join(f"{m} {row[m]['no_goals']}" for m in methods if row[m]["no_goals"])
        reasons: Dict[str, int] = {}
        for m in methods:
            for k, v in row[m]["no_goals_reasons"].items():
                reasons[k] = reasons.get(k, 0) + v
        if no_goals:
            no_goals += f" ({_reasons(reasons)})"
        ungraspable = sum(row[m]["ungraspable"] for m in methods)
        why = next((r for m in methods for r in row[m]["ungraspable_reasons"]), "")
        slip = ", ".join(slip_cell(row[m]).split(" (")[0] for m in methods)
        failed = " / ".join(str(sum(row[m].get(k, 0) for m in methods)) for k in OUTCOMES)
        lines.append(
            f"| {obj} | "
            + " | ".join(cells)
            + f" | {slip} | {failed} | {no_goals or '0'} | "
            + (f"{ungraspable} ({why})" if ungraspable else "0")
            + " |"
        )
    return "\n".join(lines) + "\n"
