"""The MotionBenchMaker benchmark (Chamzas et al., RA-L 2022), the field's comparison of manipulation
planners: shelves, boxes and tables of MoveIt primitives, a joint-space goal each, for the Panda.

``pickplan bench mbm --problems ARCHIVE|DIR`` reads the problem sets (``problems/<set>/sceneNNNN.yaml``
and ``requestNNNN.yaml``) from the archive as it is (tar, any compression) or a folder, and the Panda
model the problems were made for (``panda/`` beside it: URDF, SRDF, meshes). Every planner plans every
problem in the same run; every path, ours and the baselines', goes through one independent checker
(``trajectory_check``). ``runs.csv`` has one row per problem and planner; ``summary.md`` the table.

Planners: ``pickplan`` (straight line, else RRT-Connect + shortcuts, CHOMP-smoothed: ``omg.motion``),
its pieces (``pickplan-rrt``: no smoothing; ``chomp``: CHOMP from the straight line alone;
``chomp-multi``: CHOMP from several initializations), ``ompl`` (OMPL's RRT-Connect with its
simplification, on our FCL checker) and ``vamp`` (VAMP's RRT-Connect and simplification, when the
``vamp`` module imports: ``../shared/tools/vamp/build-vamp.sh``).
"""

from __future__ import annotations

import csv
import io
import os
import re
import tarfile
from dataclasses import dataclass
from typing import Dict, Iterator, List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core.errors import InputError
from pickplan.core.io import atomic_open
from pickplan.core.robots import Robot
from pickplan.core.runner import Runner
from pickplan.eval.mbm_planners import MbmPlanner, adapters, vamp_module
from pickplan.eval.mbm_report import summary_table
from pickplan.eval.trajectory_check import TrajectoryChecker
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.motion import MotionWorld, path_length, resample
from pickplan.sim.moveit import MotionRequest, MoveItScene, read_motion_request, read_moveit_scene, read_srdf_disabled

SETS = ("bookshelf_small_panda", "bookshelf_tall_panda", "box_panda", "table_pick_panda", "table_under_pick_panda")
_NAME = re.compile(r"(?:^|/)problems/([^/]+)/(scene|request)(\d+)\.yaml$")


DEFAULT_PLANNERS = (MbmPlanner.pickplan, MbmPlanner.ompl, MbmPlanner.vamp)


@dataclass(frozen=True)
class Problem:
    set: str
    index: int
    scene: MoveItScene
    request: MotionRequest


@dataclass(frozen=True)
class MbmSettings:
    problems: str  # archive or folder holding problems/<set>/...
    sets: Tuple[str, ...] = SETS
    planners: Tuple[MbmPlanner, ...] = DEFAULT_PLANNERS
    robot_dir: Optional[str] = None  # the Panda model folder (default: panda/ beside the problems)
    out: str = "out/bench/mbm"
    workers: int = 1
    limit: int = 0  # problems per set (0: all)
    time_limit: float = 10.0  # s per problem for every planner
    seed: int = 0
    progress: Optional[bool] = None

    def __post_init__(self):
        object.__setattr__(self, "planners", tuple(MbmPlanner.parse(p, "planner") for p in self.planners))


def read_problems(source: str, sets: Sequence[str] = SETS, limit: int = 0) -> Iterator[Problem]:
    """The problems of ``sets`` from an archive (read in place) or a folder, in set and index order;
    only those with an index below ``limit`` when it is > 0."""
    texts: Dict[Tuple[str, str, int], Tuple[str, str]] = {}
    for name, text in _members(source):
        m = _NAME.search(name)
        if m and m.group(1) in sets and (limit <= 0 or int(m.group(3)) < limit):
            texts[(m.group(1), m.group(2), int(m.group(3)))] = (name, text)
    found = {s for s, _, _ in texts}
    missing = [s for s in sets if s not in found]
    if missing:
        raise InputError(f"no problems of sets {missing} (found {sorted(found)})", path=source, field="--sets")
    for s, kind, i in sorted(k for k in texts if k[1] == "scene"):
        if (s, "request", i) not in texts:
            raise InputError(f"scene {i} of {s} has no request{i:04d}.yaml", path=source)
        scene_name, scene_text = texts[(s, "scene", i)]
        request_name, request_text = texts[(s, "request", i)]
        yield Problem(
            s,
            i,
            read_moveit_scene(f"{source}:{scene_name}", scene_text),
            read_motion_request(f"{source}:{request_name}", request_text),
        )


def _members(source: str) -> Iterator[Tuple[str, str]]:
    if os.path.isdir(source):
        for root, _, files in os.walk(source):
            for f in files:
                if f.endswith(".yaml"):
                    path = os.path.join(root, f)
                    with open(path, encoding="utf-8") as fh:
                        yield os.path.relpath(path, os.path.dirname(source.rstrip("/"))), fh.read()
        return
    if not os.path.isfile(source):
        raise FileNotFoundError(f"MBM problems not found: {source}")
    try:
        with tarfile.open(source, "r:*") as tar:
            for member in tar:
                if member.isfile() and member.name.endswith(".yaml"):
                    yield member.name, tar.extractfile(member).read().decode("utf-8")
    except (tarfile.TarError, EOFError, OSError) as exc:
        raise InputError(f"not a readable tar archive ({exc})", path=source) from None


def robot_dir_for(settings: MbmSettings) -> str:
    folder = settings.robot_dir or os.path.join(
        os.path.dirname(os.path.abspath(settings.problems.rstrip("/"))), "panda"
    )
    if not os.path.isfile(os.path.join(folder, "panda.urdf")):
        raise InputError(
            "no panda.urdf there (give --robot-dir, the Panda model the problems were made for)",
            path=folder,
            field="--robot-dir",
        )
    return folder


def smoothness(path: np.ndarray, segments: int = 64) -> float:
    """Sum of squared turning angles (rad^2) of the path resampled at ``segments`` equal joint-space
    arc lengths: a polyline's corners count in full whatever the resampling, a smooth curve's bends
    only as they turn (0 for a straight line)."""
    P = np.asarray(path, dtype=float)
    if len(P) < 3 or path_length(P) <= 0:
        return 0.0
    d = np.diff(resample(P, segments + 1), axis=0)
    u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    return float((np.arccos(np.clip(np.sum(u[:-1] * u[1:], axis=1), -1.0, 1.0)) ** 2).sum())


class _Context:
    """The robot, the SRDF pairs and the planners' adapters: built once per job (a chunk of problems)."""

    def __init__(self, settings: MbmSettings):
        folder = robot_dir_for(settings)
        self.robot = Robot.from_urdf(os.path.join(folder, "panda.urdf"), package_dirs=[folder])
        srdf = os.path.join(folder, "panda.srdf")
        self.srdf = read_srdf_disabled(srdf) if os.path.isfile(srdf) else ()
        self.settings = settings
        self.cache = ModelCache()  # the robot's meshes, body points and FCL shapes, shared by the chunk's worlds
        self.planners = adapters(settings.planners, settings.time_limit, settings.seed)


def run_problems(job: Tuple[MbmSettings, Sequence[Problem]]) -> List[dict]:
    settings, problems = job
    ctx = _Context(settings)
    return [row for p in problems for row in run_problem(ctx, p)]


def run_problem(ctx: _Context, problem: Problem) -> List[dict]:
    """Every planner on one problem, each path through the independent checker: one row each."""
    robot = ctx.robot
    joints = robot.joint_names
    start = np.array([problem.request.start[j] for j in joints])
    goal = np.array([problem.request.goal[j] for j in joints])
    pairs = tuple(ctx.srdf) + tuple(problem.scene.allowed_collisions)
    world = MotionWorld(robot, problem.scene.obstacles, allowed_pairs=pairs, cache=ctx.cache)
    checker = TrajectoryChecker(robot, problem.scene.obstacles, pairs, cache=ctx.cache)
    rows = []
    for name, plan in ctx.planners.items():
        out = plan(world, problem, start, goal)
        report = checker.check(out.path) if out.solved and len(out.path) else None
        valid = bool(report and report.valid)
        rows.append(
            {
                "set": problem.set,
                "problem": problem.index,
                "planner": name,
                "solved": int(out.solved),
                "valid": int(valid),
                "success": int(out.solved and valid),
                "time_ms": 1e3 * out.wall,
                "cpu_ms": 1e3 * out.cpu,
                "path_length": path_length(out.path) if out.solved else float("nan"),
                "smoothness": smoothness(out.path) if out.solved else float("nan"),
                "min_clearance": report.min_clearance if valid else float("nan"),
                "waypoints": len(out.path),
                "source": out.source,
                "checker": "" if report is None else report.reason,
                **out.detail,
            }
        )
    return rows


CHUNK = 10  # problems per job: the robot and its meshes are loaded once per job
FIELDS = (
    "set",
    "problem",
    "planner",
    "solved",
    "valid",
    "success",
    "time_ms",
    "cpu_ms",
    "path_length",
    "smoothness",
    "min_clearance",
    "waypoints",
    "source",
    "checker",
)


def run_mbm(settings: MbmSettings) -> List[dict]:
    """Every planner on every problem (``--workers`` processes); writes runs.csv and summary.md."""
    problems = list(read_problems(settings.problems, settings.sets, settings.limit))
    robot_dir_for(settings)  # a clear error before any worker starts
    rows: List[dict] = []
    chunks = [problems[i : i + CHUNK] for i in range(0, len(problems), CHUNK)]
    with Runner(settings.workers) as runner:
        for _, result in runner.map(
            run_problems, [(settings, c) for c in chunks], progress=settings.progress, label="mbm"
        ):
            rows.extend(result)
    os.makedirs(settings.out, exist_ok=True)
    write_rows(os.path.join(settings.out, "runs.csv"), rows)
    with atomic_open(os.path.join(settings.out, "summary.md"), "w") as f:
        f.write(summary_table(rows, [p.value for p in settings.planners], vamp_module() is not None))
    return rows


def write_rows(path: str, rows: List[dict]) -> None:
    extra = sorted({k for r in rows for k in r} - set(FIELDS))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(FIELDS) + extra, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    with atomic_open(path, "w") as f:
        f.write(buf.getvalue())
