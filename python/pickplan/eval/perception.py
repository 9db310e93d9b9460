"""``pickplan bench perception``: the OMG planner from depth cameras beside the same planner on known
meshes, on the same scenes (issue 22).

Per scene, one unit per setting: ``mesh`` (Table III's OMG unit, ``units.run_unit``: known
meshes and stored grasps) and ``<V>v/<S>mm`` for V views with depth noise sigma S (rendered in
PyBullet, seeded), planned in a ``PerceivedWorld`` (no mesh, no stored grasp). Successful plans are
executed in PyBullet on the true objects. Every plan's trajectory is measured against the true
meshes (the paper's collision cost and clearance, in the true scene's SDF, target left out), and its
time is split into field build, grasps, goal set and planning. Units are written as they finish
(``OUT/units``, atomically), so an interrupted bench resumes; ``OUT/table.md`` is the summary.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace
from typing import Dict, List, Optional, Sequence, TextIO, Tuple

import numpy as np

from pickplan.core.io import read_json, write_json, write_text
from pickplan.core.runner import JobFailure, OnError, Order, Runner
from pickplan.eval import experiments, units
from pickplan.eval.methods import Table, method_spec
from pickplan.eval.summaries import OUTCOMES, execution_outcomes, object_markdown, slip_cell, summarize_by_object
from pickplan.omg.chomp import Chomp
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.omg.planner import OMGSettings, PlanStatus
from pickplan.omg.world import World
from pickplan.sim.execution import ExecutionSettings, execute_plan
from pickplan.sim.observe import render_observation
from pickplan.sim.scenes import Scene

MESH = "mesh"
TIMES = ("field_time", "grasp_time", "goal_set_time", "plan_time")


def setting_name(views: int, noise: float) -> str:
    return f"{views}v/{1000 * noise:g}mm"


def parse_setting(name: str) -> Tuple[int, float]:
    views, noise = name.split("/")
    return int(views[:-1]), float(noise[:-2]) / 1000


@dataclass(frozen=True)
class PerceptionBenchSettings:
    out: str = "out/bench/perception"
    scenes: int = 100
    objects: Optional[str] = None  # generated scenes' objects: "builtin", "procedural" or a YCB folder
    poses: str = "upright"  # generated scenes' object poses (as the sweeps': upright, stable, resting)
    clutter: Tuple[int, int] = (3, 7)  # objects per generated scene, fewest-most
    views: Tuple[int, ...] = (1, 3)
    noises: Tuple[float, ...] = (0.0, 0.002, 0.005)  # depth sigma, m
    mesh: bool = True  # also plan every scene with known meshes
    mesh_grasps: Optional[str] = None  # the known-mesh column's grasps (None: Table III's, stored or simulated;
    #                                        "antipodal": generated per scene, for objects with no stored set)
    grasps: int = 30  # goal-set size
    grasp_candidates: int = 100
    iterations: int = 50
    execute: bool = True
    workers: int = 2
    seed: int = 0
    progress: Optional[bool] = None

    def __post_init__(self):
        for name in ("scenes", "grasps", "grasp_candidates", "iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.views or any(v not in (1, 2, 3) for v in self.views):
            raise ValueError(f"views: expected some of 1, 2, 3, got {self.views}")
        if not self.noises or any(not (np.isfinite(s) and 0 <= s < 0.05) for s in self.noises):
            raise ValueError(f"noises: expected depth sigmas in [0, 0.05) m, got {self.noises}")

    def methods(self) -> Tuple[str, ...]:
        return ((MESH,) if self.mesh else ()) + tuple(setting_name(v, s) for v in self.views for s in self.noises)

    def sweep(self) -> experiments.SweepSettings:
        """The Table III sweep whose scenes (and mesh-based OMG units) this bench shares."""
        return experiments.SweepSettings(
            "planners",
            out=self.out,
            scenes=self.scenes,
            objects=self.objects,
            poses=self.poses,
            clutter=tuple(self.clutter),
            grasp_kind=self.mesh_grasps,
            grasps=self.grasps,
            grasp_candidates=self.grasp_candidates,
            runs=1,
            methods=("OMG",),
            workers=self.workers,
            seed=self.seed,
            iterations=self.iterations,
            execute=self.execute,
            progress=self.progress,
        )


def _omg_settings(unit: dict) -> OMGSettings:
    """Table III's OMG settings (``units.run_unit``), so the two sides differ only in the world."""
    return method_spec(Table.planners, "OMG").omg_settings(
        unit["grasps"], unit["grasp_candidates"], unit["iterations"], int(unit["seed"])
    )


def true_metrics(true_world: World, trajectory: np.ndarray, settings: OMGSettings):
    """The paper's metrics of a trajectory (start first) in the true scene (its meshes' SDF)."""
    chomp = Chomp(true_world.robot, true_world.sdf, true_world.body, settings.chomp, exclude=(true_world.target,))
    tail = settings.goals.standoff_steps + 1
    return chomp.metrics(trajectory[1:], trajectory[0], replace(settings.metrics, tail_waypoints=tail))


def run_perceived_unit(unit: dict) -> dict:
    """Render the unit's views, plan in the perceived world, measure on and execute in the true scene."""
    t0 = time.perf_counter()
    views, noise = parse_setting(unit["method"])
    scene = Scene.from_dict(unit["scene"])
    record = {
        "scene": unit["scene_name"],
        "method": unit["method"],
        "target": scene.target,
        "views": views,
        "noise": noise,
        "seed": int(unit["seed"]),
        "valid": True,
    }
    settings = _omg_settings(unit)
    try:
        world = PerceivedWorld(render_observation(scene, views=views, noise=noise, seed=int(unit["seed"])))
    except ValueError as exc:  # e.g. the target hidden from every camera: a failed plan, said why
        record.update(
            status="no_world",
            reason=str(exc),
            planned=False,
            planning_success=False,
            execution_success=False,
            unit_seconds=time.perf_counter() - t0,
        )
        return record
    world.hand_sdf  # a robot constant, built before the grasp timing starts
    result = PerceivedPlanner(world, settings).plan()
    planned = result.status != PlanStatus.no_goals
    record.update(
        status=result.status,
        planned=planned,
        planning_success=bool(result.success),
        goal_reasons=dict(result.goal_reasons) if not planned else {},
        goal_set_size=result.goal_set_size,
        target_points=len(world.perceived.target_points),
        field_time=sum(world.seconds[k] for k in ("plane", "field", "scene", "world")),
        grasp_time=world.seconds["grasps"],
        goal_set_time=float(result.timings["goal_set"]),
        plan_time=float(result.timings["total"] - result.timings["goal_set"]),
    )
    if planned:
        m = true_metrics(World(scene), result.trajectory, settings)
        record.update(
            collision=float(m.collision),
            min_clearance=float(m.min_clearance),
            true_collision_free=bool(m.collision_free),
            smoothness=float(result.metrics.smoothness),
        )
    record.update(execution_success=False, execution_status="not_executed")
    if unit["execute"] and result.success:
        ex = execute_plan(
            scene, result.trajectory, ExecutionSettings(waypoint_dt=settings.chomp.duration / settings.chomp.n)
        )
        record.update(
            execution_success=bool(ex.success),
            execution_status=ex.status,
            slip=units.finite(ex.slip),
            slip_rotation=units.finite(ex.slip_rotation),
        )
    record["unit_seconds"] = time.perf_counter() - t0
    return record


def run_mesh_unit(unit: dict) -> dict:
    """Table III's OMG unit; its metrics are already measured against the true meshes."""
    record = units.run_unit(dict(unit, table="planners", method="OMG"))
    record["method"] = MESH
    if record.get("planned"):
        record["true_collision_free"] = record["status"] != PlanStatus.in_collision
        record.update(field_time=0.0, grasp_time=0.0)  # the meshes' SDFs and the stored grasps are cached
    return record


def run_bench_unit(unit: dict) -> dict:
    return run_mesh_unit(unit) if unit["method"] == MESH else run_perceived_unit(unit)


def unit_path(out: str, unit: dict) -> str:
    return os.path.join(out, "units", f"{unit['scene_name']}_{unit['method'].replace('/', '_')}.json")


def make_units(settings: PerceptionBenchSettings, files: Sequence[str]) -> List[dict]:
    sweep = settings.sweep()
    out = []
    for base in experiments.make_units(sweep, files):  # the scene and Table III's knobs, run 0
        for method in settings.methods():
            out.append(dict(base, method=method))
    return out


def run_perception_bench(settings: PerceptionBenchSettings, stream: Optional[TextIO] = None) -> List[dict]:
    """Run every unit not yet in ``OUT/units``; return all records in unit order."""
    sweep = settings.sweep()
    with Runner(settings.workers) as runner:
        files = experiments.scene_files(sweep, stream, runner)
        all_units = make_units(settings, files)
        todo = [u for u in all_units if not os.path.exists(unit_path(settings.out, u))]
        if settings.mesh:  # stored grasp sets built once, before the mesh units need them
            mesh_units = [dict(u, table="planners", method="OMG") for u in todo if u["method"] == MESH]
            for _ in runner.map(
                units._grasps_job,
                units.grasp_jobs(mesh_units),
                Order.COMPLETION,
                progress=settings.progress,
                label="grasps",
                stream=stream,
            ):
                pass
        for unit, out in runner.map(
            run_bench_unit,
            todo,
            Order.COMPLETION,
            OnError.RECORD,
            progress=settings.progress,
            label="perception units",
            stream=stream,
            done=len(all_units) - len(todo),
            total=len(all_units),
        ):
            if isinstance(out, JobFailure):
                out = {
                    "scene": unit["scene_name"],
                    "method": unit["method"],
                    "status": "error",
                    "error": out.error,
                    "valid": True,
                    "planned": False,
                    "planning_success": False,
                    "execution_success": False,
                }
            write_json(unit_path(settings.out, unit), out)
    return [read_json(unit_path(settings.out, u), "unit record") for u in all_units]


def _mean(values) -> float:
    xs = [float(x) for x in values if x is not None and np.isfinite(x)]
    return float(np.mean(xs)) if xs else float("nan")


def summarize(records: Sequence[dict], methods: Sequence[str]) -> Dict[str, dict]:
    # a target the known mesh shows no grasp of the gripper can hold is counted apart in every column
    # (as in the sweeps' tables): the observation cannot tell it, the truth can
    ungraspable = {r["scene"] for r in records if r.get("graspable") is False}
    out = {}
    for m in methods:
        rs = [r for r in records if r["method"] == m and r["scene"] not in ungraspable]
        n = len(rs)
        planned = [r for r in rs if r.get("planned")]
        ok = [r for r in rs if r.get("planning_success")]
        out[m] = {
            "units": n,
            "errors": sum(r.get("status") == "error" for r in rs),
            "ungraspable": sum(r["method"] == m and r["scene"] in ungraspable for r in records),
            "planning": sum(r["planning_success"] for r in rs) / n if n else float("nan"),
            "execution": sum(r["execution_success"] for r in rs) / n if n else float("nan"),
            "true_collision_free": (
                sum(r.get("true_collision_free", False) for r in ok) / len(ok) if ok else float("nan")
            ),
            "collision": _mean(r.get("collision") for r in planned),
            "min_clearance": _mean(r.get("min_clearance") for r in ok),
            **{k: _mean(r.get(k) for r in planned) for k in TIMES},
            **execution_outcomes(rs),
        }
    return out


ROWS = (
    ("execution", "Execution (lifted in PyBullet)", "{:.0%}"),
    ("planning", "Planning success", "{:.0%}"),
    ("true_collision_free", "Successful plans collision-free on the true meshes", "{:.0%}"),
    ("collision", "Collision cost on the true meshes (paper's metric)", "{:.2f}"),
    ("min_clearance", "Min clearance to the true meshes (m, successful plans)", "{:.3f}"),
    ("field_time", "Field build (s)", "{:.3f}"),
    ("grasp_time", "Grasps from points (s)", "{:.3f}"),
    ("goal_set_time", "Goal set (s)", "{:.3f}"),
    ("plan_time", "Planning (s)", "{:.3f}"),
)


def markdown(summary: Dict[str, dict], scenes: int, settings: PerceptionBenchSettings) -> str:
    methods = list(summary)
    lines = [
        f"## Planning from depth vs known meshes: {scenes} scenes "
        f"(objects: {settings.objects or 'built-in'}, poses: {settings.poses}), {settings.grasps} goals, "
        "OMG (MD + C-Space ISF)",
        "",
        "Columns: `mesh` = known meshes and stored grasps; `Vv/Smm` = V camera views with depth noise",
        "sigma S, no mesh and no stored grasp. Rates over all units but those whose target the mesh",
        "column's verdict calls ungraspable (counted apart); collisions measured on the true",
        "meshes. The mesh column's field and grasp times are 0: its SDFs and grasps are cached per object.",
        "",
        "| | " + " | ".join(methods) + " |",
        "|---" * (len(methods) + 1) + "|",
    ]
    for key, label, fmt in ROWS:
        cells = ["n/a" if not np.isfinite(summary[m][key]) else fmt.format(summary[m][key]) for m in methods]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines.append(
        "| Slip in the hand (mm / deg, median of lifted; slipped > 1 cm or 10 deg) | "
        + " | ".join(slip_cell(summary[m]) for m in methods)
        + " |"
    )
    lines.append(
        "| Failed executions: "
        + " / ".join(OUTCOMES)
        + " | "
        + " | ".join(" / ".join(str(summary[m][k]) for k in OUTCOMES) for m in methods)
        + " |"
    )
    lines.append(
        "| Units (errors) | " + " | ".join(f"{summary[m]['units']} ({summary[m]['errors']})" for m in methods) + " |"
    )
    lines.append(
        "| Ungraspable targets (units, by the known mesh; not in the rates) | "
        + " | ".join(str(summary[m]["ungraspable"]) for m in methods)
        + " |"
    )
    return "\n".join(lines) + "\n"


def write_report(settings: PerceptionBenchSettings, records: List[dict]) -> str:
    summary = summarize(records, settings.methods())
    text = markdown(summary, len({r["scene"] for r in records}), settings)
    text += "\n" + object_markdown(summarize_by_object(records, settings.methods()), settings.methods())
    write_text(os.path.join(settings.out, "table.md"), text)
    write_json(os.path.join(settings.out, "summary.json"), summary)
    write_json(os.path.join(settings.out, "runs.json"), records)
    return text
