"""Sweeps that reproduce the OMG paper's Tables I, II, III and Fig. 8 (Sec. IV).

A sweep is a list of units, one per (scene, method, run). A unit plans one scene with one method
(OMG with some settings, or a baseline), executes successful plans in PyBullet (failed plans count
as failed executions, as in the paper) and returns one flat record. Every finished unit is written
at once to ``OUT/units/<scene>_<method>_r<run>.json`` (atomically), so an interrupted sweep resumes
where it stopped with nothing counted twice (also after a SIGKILL of the whole process group or a
lost Ray worker, whose task Ray re-runs); each record carries its sweep's fingerprint, so units of
another sweep are never mixed in. Units run through ``pickplan.core.runner``: serially
(``workers`` <= 1), over a local process pool (default), or as Ray tasks (``ray="local"`` or a
cluster address).

>>> settings = SweepSettings("selection", scenes=4, runs=1, out="/tmp/t1", quick=True)
>>> records = run_sweep(settings)
>>> summary = summarize(records, methods_for(settings))
"""

from __future__ import annotations

import contextlib
import json
import os
import warnings
from dataclasses import dataclass, replace
from typing import Callable, List, Optional, Sequence, TextIO, Tuple

from pickplan.core import objects as objects_mod
from pickplan.core.errors import InputError
from pickplan.core.io import read_json, write_json
from pickplan.core.runner import JobFailure, OnError, Order, Runner
from pickplan.eval.methods import OPTIONAL_METHODS, Table, all_methods
from pickplan.eval.summaries import UNIT_ERROR
from pickplan.eval.units import _grasps_job, grasp_jobs, run_unit
from pickplan.omg.grasps import KINDS, GraspKind
from pickplan.sim.layouts import Layout, LayoutSettings, generate_layout
from pickplan.sim.scene_sets import scene_seeds
from pickplan.sim.scenes import Orientation, SceneSettings, generate_scene


@dataclass(frozen=True)
class SweepSettings:
    """One sweep; defaults are the paper's (100 scenes, 30 grasps, 10 runs)."""

    table: Table  # selection | refinement | planners | ablation (a spelling converts)
    out: str = "out/bench"
    scenes: int = 100  # generated scenes (ignored with scene_dir)
    scene_dir: Optional[str] = None  # load scene_*.json from here instead
    # generated scenes' objects: "builtin", "procedural" or a YCB-layout folder (None: $PICKPLAN_YCB_DIR if set, else
    # the built-ins)
    objects: Optional[str] = None
    poses: Orientation = Orientation.upright  # generated scenes' object poses
    clutter: Tuple[int, int] = (3, 7)  # objects per generated scene, fewest-most (the paper's 3-7)
    # generated scenes' family: the tabletop, or a shelf, bin or cabinet (``sim.layouts``; poses and clutter are the
    # tabletop's)
    layout: Layout = Layout.table
    # The grasp set of every method (None: the table's, "simulated"); "antipodal" is generated per unit,
    # aware of the table under the target as it lies (physics-verified sets take minutes per new object).
    grasp_kind: Optional[GraspKind] = None
    grasps: int = 30  # goal-set size (the paper's "30 grasps each scene")
    grasp_candidates: int = 100  # grasps generated per object when it has no stored set
    runs: int = 10
    methods: Optional[Tuple[str, ...]] = None  # None: every method of the table
    quick: bool = False  # CI setting: see ``effective``
    workers: int = 2  # local processes (<= 1: serial, in this process)
    ray: Optional[str] = None  # "local" or a Ray cluster address
    seed: int = 0  # scene set seed; run r of every scene uses seed + r
    iterations: int = 50  # OMG / CHOMP iterations N
    execute: bool = True  # execute successful plans in PyBullet
    timed_execution: bool = False  # execute them timed within the robot's limits (else 0.1 s per waypoint)
    robot: str = "panda"  # the robot planned for and executed (a shipped name, short name or .toml)
    time_limit: float = 1.0  # OMPL seconds per goal
    max_goals_tried: int = 5  # ranked goals tried by CHOMP / FMT / RRT-C
    progress: Optional[bool] = None  # None: a progress bar only on a terminal

    def __post_init__(self):
        object.__setattr__(self, "table", Table.parse(self.table, "table"))
        for name in ("scenes", "grasps", "grasp_candidates", "runs", "iterations"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.grasp_kind is not None and (self.table is Table.refinement or self.grasp_kind not in KINDS):
            raise ValueError(
                f"grasp_kind: expected one of simulated, graspit, approach, antipodal (not with the "
                f"refinement table, whose methods are grasp sets), got {self.grasp_kind!r}"
            )
        if self.grasp_kind is not None:
            object.__setattr__(self, "grasp_kind", GraspKind(self.grasp_kind))
        object.__setattr__(self, "poses", Orientation.parse(self.poses, "poses"))
        object.__setattr__(self, "layout", Layout.parse(self.layout, "layout"))
        if len(self.clutter) != 2 or not 1 <= self.clutter[0] <= self.clutter[1]:
            raise ValueError(f"clutter: expected (fewest, most) with 1 <= fewest <= most, got {self.clutter!r}")
        if self.methods is not None:
            known = all_methods(self.table) + OPTIONAL_METHODS.get(self.table, ())
            bad = [m for m in self.methods if m not in known]
            if bad:
                raise ValueError(f"unknown methods {bad} for table {self.table!r}; expected some of {list(known)}")

    def effective(self) -> "SweepSettings":
        """``quick`` shrinks the sweep for CI: <= 4 scenes, 1 run, 10 goals, 30 candidates, 0.5 s OMPL."""
        if not self.quick:
            return self
        return replace(
            self,
            scenes=min(self.scenes, 4),
            runs=1,
            grasps=min(self.grasps, 10),
            grasp_candidates=min(self.grasp_candidates, 30),
            time_limit=min(self.time_limit, 0.5),
        )


def methods_for(settings: SweepSettings) -> Tuple[str, ...]:
    if settings.methods:
        return tuple(settings.methods)
    return all_methods(settings.table, settings.quick)


# --- scenes ----------------------------------------------------------------------------------------
def _make_scene(job: dict) -> dict:

    path = job["path"]
    if not os.path.exists(path):
        (fewest, most), poses = job.get("clutter", (3, 7)), job.get("poses", "upright")
        robot, layout = job.get("robot", "panda"), Layout.parse(job.get("layout", "table"), "layout")
        lib = objects_mod.library(job["objects"])
        if layout is Layout.table:
            settings = SceneSettings(orientation=poses, min_objects=int(fewest), max_objects=int(most), robot=robot)
            generate_scene(job["seed"], lib, settings).save(path)
        else:
            generate_layout(layout, job["seed"], lib, LayoutSettings(robot=robot)).save(path)
    return {"path": path}


def scene_files(settings: SweepSettings, stream: Optional[TextIO] = None, runner: Optional[Runner] = None) -> List[str]:
    """The sweep's scene files: those of ``scene_dir``, or generated once into ``OUT/scenes``
    (with ``runner``, else the sweep's own back end)."""
    s = settings.effective()
    if s.scene_dir:
        files = sorted(f for f in os.listdir(s.scene_dir) if f.endswith(".json") and f != "index.json")
        if not files:
            raise FileNotFoundError(f"no scene JSON files in {s.scene_dir}")
        return [os.path.join(s.scene_dir, f) for f in files]

    folder = os.path.join(s.out, "scenes")
    os.makedirs(folder, exist_ok=True)
    jobs = [
        {
            "path": os.path.join(folder, f"scene_{i:04d}.json"),
            "seed": seed,
            "objects": s.objects,
            "poses": s.poses,
            "clutter": tuple(s.clutter),
            "robot": s.robot,
            "layout": s.layout.value,
        }
        for i, seed in enumerate(scene_seeds(s.seed, s.scenes))
    ]
    todo = [j for j in jobs if not os.path.exists(j["path"])]
    with sweep_runner(s) if runner is None else contextlib.nullcontext(runner) as backend:
        for _ in backend.map(_make_scene, todo, Order.COMPLETION, progress=s.progress, label="scenes", stream=stream):
            pass
    return [j["path"] for j in jobs]


# --- units -----------------------------------------------------------------------------------------
def unit_key(unit: dict) -> str:
    return f"{unit['scene_name']}_{unit['method']}_r{unit['run']}".replace("=", "-").replace("+", "p")


def make_units(settings: SweepSettings, files: Sequence[str]) -> List[dict]:
    s = settings.effective()
    knobs = {
        k: getattr(s, k)
        for k in (
            "grasps",
            "grasp_candidates",
            "iterations",
            "execute",
            "time_limit",
            "max_goals_tried",
            "timed_execution",
            "robot",
            "grasp_kind",
        )
    }
    units = []
    for path in files:
        with open(path) as f:
            scene = json.load(f)
        name = os.path.splitext(os.path.basename(path))[0]
        for method in methods_for(s):
            for run in range(s.runs):
                units.append(
                    {
                        "table": s.table,
                        "scene_name": name,
                        "scene": scene,
                        "method": method,
                        "run": run,
                        "seed": s.seed + run,
                        **knobs,
                    }
                )
    return units


def unit_path(settings: SweepSettings, unit: dict) -> str:
    return os.path.join(settings.out, "units", unit_key(unit) + ".json")


def error_record(unit: dict, failure: JobFailure) -> dict:
    """The record of a unit whose function raised: status "error", counted as a failed plan."""
    return {
        "table": unit["table"],
        "scene": unit["scene_name"],
        "method": unit["method"],
        "run": unit["run"],
        "seed": int(unit["seed"]),
        "status": UNIT_ERROR,
        "error": failure.error,
        "valid": True,
        "planned": False,
        "planning_success": False,
        "execution_success": False,
        "execution_run": bool(unit.get("execute", True)),
    }


def sweep_runner(settings: SweepSettings) -> Runner:
    """The sweep's back end: serial (workers <= 1), a local process pool, or Ray."""
    return Runner(settings.workers, settings.ray)


def run_sweep(
    settings: SweepSettings,
    stream: Optional[TextIO] = None,
    unit_fn: Callable[[dict], dict] = run_unit,
    warm_grasps: bool = True,
) -> List[dict]:
    """Run every unit not yet on disk (each written as soon as it finishes, an exception recorded as
    an "error" unit; interrupts stop the sweep); return all records in unit order. ``warm_grasps``:
    first build the targets' simulated grasp sets on the runner (one job per object, not one race per
    unit); a ``unit_fn`` that plans nothing (a test's stand-in) has no use for them."""
    s = settings.effective()
    check_resumable(s)
    stamp = {FINGERPRINT_FIELD: sweep_fingerprint(s)}  # in every unit: a resume never mixes sweeps
    with sweep_runner(s) as runner:
        files = scene_files(s, stream, runner)
        units = make_units(s, files)
        todo = [u for u in units if not _finished(s, u)]
        for _ in runner.map(
            _grasps_job,
            grasp_jobs(todo) if warm_grasps else [],
            Order.COMPLETION,
            progress=s.progress,
            label="grasps",
            stream=stream,
        ):
            pass
        for unit, out in runner.map(
            unit_fn,
            todo,
            Order.COMPLETION,
            OnError.RECORD,
            progress=s.progress,
            label=f"{s.table} units",
            stream=stream,
            done=len(units) - len(todo),
            total=len(units),
        ):
            write_json(
                unit_path(s, unit), {**(error_record(unit, out) if isinstance(out, JobFailure) else out), **stamp}
            )
    return load_records(s, units)


# Settings a finished unit (or a generated scene) depends on; methods, runs and scene count only
# add units, and workers / Ray / progress do not change results.
RESUME_KEYS = (
    "table",
    "seed",
    "objects",
    "scene_dir",
    "grasps",
    "grasp_candidates",
    "iterations",
    "execute",
    "time_limit",
    "max_goals_tried",
    "timed_execution",
    "robot",
    "poses",
    "clutter",
    "grasp_kind",
    "layout",
)
# What a sweep made before a key existed had (its records and sweep.json lack the key).
RESUME_DEFAULTS = {"poses": "upright", "clutter": [3, 7], "grasp_kind": None, "layout": Layout.table.value}


def sweep_fingerprint(settings: SweepSettings) -> dict:
    s = settings.effective()
    fp = {k: getattr(s, k) for k in RESUME_KEYS}
    fp["clutter"] = list(s.clutter)  # as JSON reads it back
    fp["layout"] = s.layout.value
    for k in ("objects", "scene_dir"):
        named = k == "objects" and fp[k] in ("builtin", "procedural")
        fp[k] = fp[k] if named else os.path.realpath(fp[k]) if fp[k] else None
    return fp


FINGERPRINT_FIELD = "sweep"  # the unit record's copy of its sweep's fingerprint


def _fingerprint_diff(record: dict, fp: dict) -> List[str]:
    """The fingerprint fields on which ``record`` (a unit's) differs from ``fp``."""
    theirs = record.get(FINGERPRINT_FIELD)
    if not isinstance(theirs, dict):
        return [f"{FINGERPRINT_FIELD}: none in the unit (written by another sweep or an older pickplan)"]
    return [
        f"{k}: {theirs.get(k)!r} there, {fp[k]!r} now"
        for k in RESUME_KEYS
        if theirs.get(k, RESUME_DEFAULTS["layout"] if k == "layout" else None) != fp[k]
    ]


def _refuse_foreign_unit(settings: SweepSettings, path: str, diff: List[str]) -> None:
    raise InputError(
        f"{os.path.basename(path)} was made by a sweep with other settings ({'; '.join(diff)}); "
        "use another --out or delete that folder",
        path=os.path.join(settings.out, "units"),
    )


def check_resumable(settings: SweepSettings) -> None:
    """OUT/sweep.json records the settings its units were made with. Resuming with other settings
    would mix incomparable units (or reuse scenes of another seed or object set), so it is refused;
    without sweep.json (deleted), the fingerprint in each unit record decides before any is written."""
    path = os.path.join(settings.out, "sweep.json")
    fp = sweep_fingerprint(settings)
    if not os.path.exists(path):
        units = os.path.join(settings.out, "units")
        for name in sorted(os.listdir(units)) if os.path.isdir(units) else ():
            try:
                record = read_json(os.path.join(units, name), "unit record")
            except (InputError, OSError):
                continue  # damaged: redone with a warning when its unit comes up
            diff = _fingerprint_diff(record, fp) if isinstance(record, dict) else []
            if diff:
                _refuse_foreign_unit(settings, name, diff)
    else:
        with open(path) as f:
            old = json.load(f)
        defaults = RESUME_DEFAULTS  # sweeps made before these existed
        diff = [k for k in RESUME_KEYS if old.get(k, defaults.get(k)) != fp[k] and (k in old or k in defaults)]
        if diff:
            detail = ", ".join(f"{k}: {old[k]!r} there, {fp[k]!r} now" for k in diff)
            raise ValueError(
                f"{settings.out} holds a sweep made with other settings ({detail}); "
                "use another --out or delete that folder"
            )
        return
    write_json(path, fp)


def _finished(settings: SweepSettings, unit: dict) -> bool:
    """Whether ``unit``'s file holds its finished record. Files are written atomically, but a damaged
    one (a disk error, a hand edit, another unit's record) is redone with a warning naming it."""
    path = unit_path(settings, unit)
    if not os.path.exists(path):
        return False
    try:
        record = read_json(path, "unit record")
    except (InputError, OSError) as exc:
        warnings.warn(f"{path}: damaged unit record, redone ({exc})", stacklevel=2)
        return False
    mine = {"scene": unit["scene_name"], "method": unit["method"], "run": unit["run"]}
    if not isinstance(record, dict) or any(record.get(k) != v for k, v in mine.items()):
        warnings.warn(f"{path}: not the record of unit {mine}, redone", stacklevel=2)
        return False
    diff = _fingerprint_diff(record, sweep_fingerprint(settings))
    if diff:
        _refuse_foreign_unit(settings, path, diff)
    return True


def load_records(settings: SweepSettings, units: Sequence[dict]) -> List[dict]:
    """The units' records, without their sweep fingerprint (sweep.json holds it once)."""
    records = (read_json(unit_path(settings, u), "unit record") for u in units)
    return [{k: v for k, v in r.items() if k != FINGERPRINT_FIELD} for r in records]
