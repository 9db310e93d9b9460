"""``pickplan bench moving`` (issue 36): moving targets picked in PyBullet by the closed loop
(``eval.moving``), with its baselines in the same run.

Cases: a conveyor at each of ``speeds`` (m/s; along the table's width, away from the middle, so the
target crosses the workspace from near the middle outwards), and ``nudge``: a still target displaced once
by ``nudge`` m along the width during the approach. Per case and generated scene, the belt brings the
target to its scene pose ``meet_time`` s after the start (the objects in its lane are left out,
``sim.conveyor.conveyor_scene``) and each method picks it: closed_loop (warm replans), fresh (replans from
scratch at the same rate), open_loop (one plan to the predicted pose).

A unit is a case and a method: ``OUT/units/<case>_<method>/runs.csv`` (one row per scene, rewritten
atomically as scenes finish; a rerun skips the scenes there). ``OUT/summary.md``: lifted % per case and
method, with the median plan time.
"""

from __future__ import annotations

import csv
import os
from dataclasses import dataclass, field, replace
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core.io import atomic_open, write_text
from pickplan.core.runner import OnError, Order, Runner
from pickplan.eval.moving import EpisodeStatus, LoopSettings, MovingMethod, run_episode
from pickplan.sim import scenes
from pickplan.sim.conveyor import TargetPath, conveyor_scene

NUDGE = "nudge"
FIELDS = (
    "scene",
    "case",
    "method",
    "status",
    "lifted",
    "plans",
    "plan_ms_median",
    "plan_ms_max",
    "planner_ms_median",
    "arrival",
    "miss",
    "target_lift",
    "max_penetration",
    "sim_time",
)


@dataclass(frozen=True)
class MovingBenchSettings:
    out: str = "out/bench/moving"
    speeds: Tuple[float, ...] = (0.0, 0.05, 0.10, 0.20)  # m/s
    nudge: float = 0.04  # m; 0: no nudge case
    nudge_after: float = 0.5  # s after the first plan (during the approach)
    scenes: int = 100
    seed: int = 0
    methods: Tuple[MovingMethod, ...] = tuple(MovingMethod)
    meet_time: float = 2.7  # s from the start to the target at its scene pose
    workers: int = 1
    loop: LoopSettings = field(default_factory=LoopSettings)
    progress: Optional[bool] = None

    def __post_init__(self):
        if not self.speeds and not self.nudge:
            raise ValueError("moving bench: no case (no speed and no nudge)")
        for v in self.speeds:
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"moving bench: speeds must be finite and >= 0 m/s, got {v}")
        if not (np.isfinite(self.nudge) and self.nudge >= 0):
            raise ValueError(f"moving bench: nudge must be a finite distance >= 0 m, got {self.nudge}")
        if self.scenes < 1:
            raise ValueError(f"moving bench: scenes must be >= 1, got {self.scenes}")
        object.__setattr__(self, "methods", tuple(MovingMethod.parse(m, "method") for m in self.methods))

    def cases(self) -> List[str]:
        return [case_name(v) for v in self.speeds] + ([NUDGE] if self.nudge else [])


def case_name(speed: float) -> str:
    return f"speed{round(100 * speed):02d}"  # cm/s


def case_path(case: str, scene, s: MovingBenchSettings) -> TargetPath:
    """The case's belt or nudge for ``scene``: along the width (y), away from the table's middle."""
    y = float(np.asarray(scene.object(scene.target).pose)[1, 3])
    direction = np.array([0.0, 1.0 if y >= 0 else -1.0, 0.0])
    if case == NUDGE:
        return TargetPath(nudge=s.nudge * direction, nudge_time=s.loop.observe_time + s.nudge_after)
    return TargetPath(velocity=float(case[len("speed") :]) / 100 * direction)


def run_job(job: dict) -> List[dict]:
    """One case and scene, every method: their rows."""
    s: MovingBenchSettings = job["settings"]
    from pickplan.omg.model_cache import ModelCache

    scene = scenes.generate_scene(job["scene"])
    path = case_path(job["case"], scene, s)
    moving = conveyor_scene(scene, path, s.meet_time, s.loop.max_time)
    cache, rows = ModelCache(), []
    for method in job["methods"]:
        r = run_episode(moving, path, method, replace(s.loop, seed=job["scene"]), cache=cache)
        rows.append({"scene": job["scene"], "case": job["case"], **r.row()})
    return rows


def unit_csv(out: str, case: str, method) -> str:
    return os.path.join(out, "units", f"{case}_{method}", "runs.csv")


def _read(path: str) -> List[dict]:
    if not os.path.exists(path):
        return []
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _write(path: str, rows: Sequence[dict]) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with atomic_open(path, "w", newline="") as f:
        w = csv.DictWriter(f, FIELDS)
        w.writeheader()
        w.writerows(sorted(rows, key=lambda r: int(r["scene"])))


def run_moving_bench(s: MovingBenchSettings) -> Dict[Tuple[str, str], List[dict]]:
    """Runs the cases' scenes not in their units' runs.csv yet; returns every unit's rows."""
    seeds = range(s.seed, s.seed + s.scenes)
    units = {
        (c, str(m)): {r["scene"]: r for r in _read(unit_csv(s.out, c, m)) if int(r["scene"]) in seeds}
        for c in s.cases()
        for m in s.methods
    }
    jobs = []
    for seed in seeds:  # scene by scene: a run stopped early has every case on the same scenes
        for case in s.cases():
            todo = [m for m in s.methods if str(seed) not in units[(case, str(m))]]
            if todo:
                jobs.append({"settings": s, "case": case, "scene": seed, "methods": todo})
    with Runner(s.workers) as runner:
        for job, rows in runner.map(
            run_job, jobs, order=Order.COMPLETION, errors=OnError.RAISE, progress=s.progress, label="moving scenes"
        ):
            for row in rows:
                unit = units[(job["case"], row["method"])]
                unit[str(row["scene"])] = row
                _write(unit_csv(s.out, job["case"], row["method"]), list(unit.values()))
    return {k: list(v.values()) for k, v in units.items()}


def _true(value) -> bool:
    return value is True or str(value) == "True"


def summary(s: MovingBenchSettings, units: Dict[Tuple[str, str], List[dict]]) -> str:
    """Lifted % per case and method, beside the median plan CPU time and the statuses."""
    lines = [
        "| case | method | lifted | median ms per replan (CPU): all / planner | median plans | statuses |",
        "|---|---|---|---|---|---|",
    ]
    for case in s.cases():
        for m in s.methods:
            rows = units.get((case, str(m)), [])
            if not rows:
                continue
            lifted = sum(_true(r["lifted"]) for r in rows)
            ms, planner = (
                [float(r[k]) for r in rows if r[k] not in ("", "nan")] for k in ("plan_ms_median", "planner_ms_median")
            )
            counts = {st: sum(r["status"] == str(st) for r in rows) for st in EpisodeStatus}
            statuses = ", ".join(f"{k} {v}" for k, v in counts.items() if v)
            label = case if case == NUDGE else f"{int(case[len('speed') :])} cm/s"
            lines.append(
                f"| {label} | {m} | {100 * lifted / len(rows):.0f} % ({lifted}/{len(rows)}) | "
                f"{np.median(ms) if ms else float('nan'):.0f} / "
                f"{np.median(planner) if planner else float('nan'):.0f} | "
                f"{np.median([int(r['plans']) for r in rows]):.0f} | {statuses} |"
            )
    text = "\n".join(lines) + "\n"
    write_text(os.path.join(s.out, "summary.md"), text)
    return text
