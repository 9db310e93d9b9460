"""Summaries of sweep records: the paper tables' rows per method, and per target object (planning,
execution, no_goals with their reasons, ungraspable targets counted apart)."""
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
            "units": len(rs), "valid": n, "planned": len(planned), "errors": sum(r["status"] == UNIT_ERROR for r in rs),
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
        }
    return out


def grasp_costs_by_object(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, Dict[str, float]]:
    """Table II's rows: mean f_grasp at the final goal per target object and method (plans only)."""
    objects = sorted({r["target"] for r in records if r.get("planned")})
    return {o: {m: _mean(r["grasp_cost"] for r in records if r["method"] == m and r["target"] == o and r.get("planned"))
                for m in methods} for o in objects}


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
                "units": len(rs), "graspable": n,
                "planning": sum(r["planning_success"] for r in ok) / n if n else float("nan"),
                "execution": (sum(r["execution_success"] for r in ok) / n if n else float("nan")) if executed else None,
                "no_goals": sum(r["status"] == PlanStatus.no_goals for r in ok),
                "no_goals_reasons": dict(reasons.most_common()),
                "ungraspable": len(rs) - n,
                "ungraspable_reasons": dict(Counter(r.get("reason", "") for r in rs if not _graspable(r))),
            }
    return out
