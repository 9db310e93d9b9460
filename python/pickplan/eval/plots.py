"""A picture beside every sweep table: success per target object and the time per planning stage."""

from __future__ import annotations

from collections import defaultdict
from typing import Sequence

import numpy as np

STAGES = ("goal_set", "chomp", "costs", "selection", "isf", "metrics")  # PlanResult.timings' phases


def _object_label(name: str) -> str:
    words = name.split("_")
    return " ".join(words[1:] if words[0].isdigit() else words) or name


def plot_table(path: str, records: Sequence[dict], methods: Sequence[str], title: str) -> None:
    """``path`` (PNG): planning and execution success per target object and method (execution left
    out where it was not run), and each method's mean time per stage over its planned units."""
    import matplotlib  # an optional dependency: only the pictures need it

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    valid = [r for r in records if r.get("valid")]
    objects = sorted({r["target"] for r in valid if "target" in r})
    fig, (ax_obj, ax_time) = plt.subplots(
        1, 2, figsize=(max(9, 1.2 * len(objects) + 5), 4.5), gridspec_kw={"width_ratios": [max(len(objects), 1), 2]}
    )
    width = 0.8 / max(len(methods), 1)
    for k, m in enumerate(methods):
        rows = defaultdict(list)
        for r in valid:
            if r["method"] == m:
                rows[r.get("target", "?")].append(r)
        x = np.arange(len(objects)) + k * width
        plan = [np.mean([r["planning_success"] for r in rows[o]]) if rows[o] else np.nan for o in objects]
        bars = ax_obj.bar(x, plan, width, label=f"{m} planned", alpha=0.55)
        if any(r.get("execution_run", True) for rs in rows.values() for r in rs):
            lifted = [np.mean([r["execution_success"] for r in rows[o]]) if rows[o] else np.nan for o in objects]
            ax_obj.bar(
                x,
                lifted,
                width * 0.5,
                color=bars.patches[0].get_facecolor() if bars.patches else None,
                label=f"{m} lifted",
            )
    ax_obj.set_xticks(np.arange(len(objects)) + 0.4 - width / 2)
    ax_obj.set_xticklabels([_object_label(o) for o in objects], rotation=35, ha="right", fontsize=8)
    ax_obj.set_ylim(0, 1.05)
    ax_obj.set_ylabel("success rate")
    ax_obj.set_title("per target object (wide: planned, narrow: lifted)", fontsize=9)
    ax_obj.legend(fontsize=7, ncol=2)
    bottom = np.zeros(len(methods))
    for stage in STAGES:
        means = []
        for m in methods:
            ts = [r["stage_times"][stage] for r in valid if r["method"] == m and r.get("stage_times")]
            means.append(1000 * float(np.mean(ts)) if ts else 0.0)
        ax_time.bar(range(len(methods)), means, 0.6, bottom=bottom, label=stage)
        bottom += np.asarray(means)
    ax_time.set_xticks(range(len(methods)))
    ax_time.set_xticklabels(methods, rotation=35, ha="right", fontsize=8)
    ax_time.set_ylabel("ms per plan (mean over planned units)")
    ax_time.set_title("time per stage", fontsize=9)
    ax_time.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
