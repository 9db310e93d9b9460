"""``pickplan bench pickplace``: the sweep (``experiments.run_sweep`` with the pick-and-place unit of
``eval.pickplace``: resumable, one file per unit, a process pool or Ray) and its report."""

from __future__ import annotations

import time
from typing import Callable, List

from pickplan.eval import experiments
from pickplan.eval.pickplace import PERCEPTION_METHOD, run_pickplace_unit
from pickplan.eval.pickplace_perceived import run_perceived_pickplace_unit
from pickplan.eval.pickplace_report import write_report


def run_unit(unit: dict) -> dict:
    return run_perceived_pickplace_unit(unit) if unit["method"] == PERCEPTION_METHOD else run_pickplace_unit(unit)


def run_pickplace_bench(settings: experiments.SweepSettings, write_csv: Callable) -> str:
    """Run (or resume) the sweep and write its report; the table and the files written, as text."""
    t0 = time.perf_counter()
    s = settings.effective()
    records: List[dict] = experiments.run_sweep(s, unit_fn=run_unit)
    objects = s.objects or (f"as in {s.scene_dir}" if s.scene_dir else "built-in")
    header = (
        f"## Pick and place: {len({r['scene'] for r in records})} scenes, {s.runs} run(s), robot {s.robot} "
        f"(objects: {objects}, poses: {s.poses}, {s.clutter[0]}-{s.clutter[1]} objects per scene; "
        f"regions free / cluttered / bin in turn)"
    )
    return (
        write_report(s.out, records, experiments.methods_for(s), header, write_csv)
        + f"wrote {s.out}/table.md, runs.csv, runs.json, summary.json, objects.json ({time.perf_counter() - t0:.0f} s)"
    )
