"""The main job (``make demo``): a generated cluttered scene with built-in objects, planned by the
OMG planner, executed in PyBullet (close, lift), a picture of the execution and a metrics table
beside the paper's."""

from __future__ import annotations

import logging
import os
import time
from dataclasses import dataclass
from typing import List, Optional

import numpy as np

from pickplan.sim import execution
from pickplan.sim import scenes
from pickplan.sim.view import view_folder
from pickplan.sim.view_page import write_html
from pickplan.core.io import write_json, write_text
from pickplan.core.timing import TimedTrajectory
from pickplan.omg.plan_file import plan_record
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanResult

log = logging.getLogger(__name__)

# OMG paper, Table III (100 scenes, 30 grasps, 10 runs), the OMG column.
PAPER_OMG = {"execution": "84%", "planning": "93%", "smoothness": 15.43, "collision": 3.92, "grasp": 3.04, "time": 0.42}


@dataclass(frozen=True)
class DemoSettings:
    seed: int = 1  # scene seed of the default demo
    planner: OMGSettings = OMGSettings(grasp_kind="antipodal")
    record_every: int = 24  # simulation steps between pictures (0.1 s)
    frames_in_sheet: int = 12
    timed_rate: float = 1000.0  # Hz of the exported timed trajectory (Franka's control rate)
    robot: str = "panda"  # the robot: a shipped description's name (or short name) or a .toml file


def metrics_table(
    result: PlanResult,
    executed: Optional[execution.ExecutionResult],
    timed: Optional[TimedTrajectory] = None,
    robot: str = "Panda",
) -> str:
    m = result.metrics
    planning_time = result.timings["total"] - result.timings["goal_set"]
    lifted = "not run" if executed is None else ("yes" if executed.success else "no")
    rows = [
        ("Execution (target lifted)", lifted, PAPER_OMG["execution"]),
        (
            "Planning success (collision-free, smoothness < 30)",
            "yes" if result.success else "no",
            PAPER_OMG["planning"],
        ),
        ("Smoothness (f_prior)", f"{getattr(m, 'smoothness', float('nan')):.2f}", PAPER_OMG["smoothness"]),
        (
            "Collision (sum of c(x) within 5 cm, 200 steps)",
            f"{getattr(m, 'collision', float('nan')):.2f}",
            PAPER_OMG["collision"],
        ),
        ("Grasp cost f_grasp", f"{result.grasp_cost:.2f}", PAPER_OMG["grasp"]),
        ("Planning time (s)", f"{planning_time:.3f}", PAPER_OMG["time"]),
        (
            f"Trajectory duration (s, timed within the {robot}'s velocity and acceleration limits)",
            f"{timed.duration:.3f}" if timed is not None else "not timed",
            "not reported",
        ),
    ]
    lines = ["| metric | this run | OMG paper (Table III, mean of 100 scenes) |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c} |" for a, b, c in rows]
    lines.append("")
    lines.append(
        f"Status: {result.status}; execution: {executed.status if executed else 'not run'}; "
        f"{result.iterations} iterations, {result.goal_set_size} goals "
        f"({result.history['switches']} goal switches), min clearance "
        f"{getattr(m, 'min_clearance', float('nan')) * 100:.1f} cm; goal set built in "
        f"{result.timings['goal_set']:.3f} s."
    )
    lines.append("One scene is one sample: the paper's rates are over 100 scenes (see `pickplan bench`).")
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class DemoRun:
    """What ``run_demo`` did: the metrics table, the files it wrote (names in ``out``), whether the
    target was lifted, and the wall time."""

    table: str
    files: List[str]
    lifted: bool
    seconds: float


def run_demo(out: str, settings: DemoSettings = DemoSettings()) -> DemoRun:
    """The demo into folder ``out``; progress goes to the ``pickplan.eval.demo`` logger."""
    t0 = time.perf_counter()
    os.makedirs(out, exist_ok=True)
    log.info(f"[1/4] generating a cluttered scene (seed {settings.seed}, built-in objects)")
    scene = scenes.generate_scene(settings.seed, settings=scenes.SceneSettings(robot=settings.robot))  # made for it
    scene.save(os.path.join(out, "scene.json"))
    log.info(f"      {len(scene.objects)} objects; target: {scene.target}")
    log.info(f"[2/4] planning for {settings.robot} with the OMG planner (MD selection, C-Space ISF)")
    planner = OMGPlanner(settings.robot, scene, settings.planner)
    result = planner.plan()
    log.info(f"      {result.status} in {result.iterations} iterations")
    executed = timed = None
    frames = []
    if result.planned:
        timed = result.timed(rate=settings.timed_rate)
        timed.save(os.path.join(out, "timed.json"))
        timed.save(os.path.join(out, "timed.npz"))
        log.info(f"[3/4] executing the timed plan ({timed.duration:.2f} s) in PyBullet: follow, close, lift")
        record = execution.RecordSettings(every=settings.record_every)
        executed = execution.execute_plan(
            scene, timed, execution.ExecutionSettings(robot=settings.robot), record=record
        )
        frames = executed.frames or []
        log.info(f"      {executed.status}: target lifted {executed.target_lift * 100:.1f} cm")
    log.info("[4/4] writing the picture, the 3D view and the metrics table")
    if frames:
        pick = np.linspace(0, len(frames) - 1, min(settings.frames_in_sheet, len(frames))).round().astype(int)
        execution.save_frames([frames[i] for i in pick], os.path.join(out, "demo.png"), columns=4)
    table = metrics_table(result, executed, timed, "Panda" if settings.robot == "panda" else settings.robot)
    write_text(os.path.join(out, "metrics.md"), table)
    record = plan_record(result, planner.world(), executed.to_dict() if executed else None)
    record["trajectory_duration"] = timed.duration if timed is not None else None
    write_json(os.path.join(out, "plan.json"), record)
    write_html(view_folder(out), os.path.join(out, "view.html"))
    files = (
        ["demo.png"] * bool(frames)
        + ["view.html", "metrics.md", "plan.json", "scene.json"]
        + ["timed.json", "timed.npz"] * (timed is not None)
    )
    return DemoRun(table, files, executed is not None and executed.success, time.perf_counter() - t0)
