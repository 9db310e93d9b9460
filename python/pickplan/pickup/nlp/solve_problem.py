"""One problem file, solved and checked: the success surface it names, the solve (successive
refinement or a single shot), the dense checks of the solution and the files `pickplan pickup plan`
writes (trajectory JSON, metrics JSON, a speed plot like the paper's Fig. 5)."""

from __future__ import annotations

import logging
import math
import os
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.core.io import atomic_open, cache_dir, write_json
from pickplan.pickup.metamodel.build import build_metamodel
from pickplan.pickup.metamodel.model import BuildConfig, MetaModel
from pickplan.pickup.nlp import planner, routed
from pickplan.pickup.nlp.cases import METAMODEL_PART, cases_metamodel_config
from pickplan.pickup.nlp.planner import dense_checks  # noqa: F401 - part of this module's API since issue 23
from pickplan.pickup.nlp.problem_file import STANDIN, PickupProblemSpec, native_problem

log = logging.getLogger(__name__)


def builtin_metamodel_path(part: str) -> str:
    """Where the meta-model of a built-in part is cached ($PICKPLAN_CACHE_DIR or ~/.cache/pickplan)."""
    return cache_dir(f"metamodel_{part}.json")


def ensure_builtin_metamodel(
    part: str, path: Optional[str] = None, config=None, workers: int = 1, progress: bool = True
) -> str:
    """The meta-model file of a built-in part: reused when it loads, else built from simulation
    (seed 0; the box with the configuration the paper's cases are validated with)."""
    path = os.fspath(path or builtin_metamodel_path(part))
    if os.path.exists(path):
        mm = MetaModel.load(path)
        if mm.part_name != part:
            raise ValueError(f"{path}: a meta-model of {mm.part_name!r}, expected {part!r}")
        return path
    if progress:
        log.info(f"building the {part} meta-model from simulation ({workers} worker(s)) -> {path}")
    build_metamodel(part, config or BuildConfig(), seed=0, workers=workers, progress=progress).save(path)
    return path


def rho_for_spec(spec: PickupProblemSpec, metamodel: Optional[str] = None, workers: int = 1, progress: bool = True):
    """The native rho surface of the problem at its sigmas: from ``metamodel`` when given, else
    the file it names (a path, a built-in part built on first use, or the stand-in)."""
    source = metamodel or spec.metamodel_path()
    if source is None and spec.metamodel == STANDIN:
        return planner.synthetic_rho(spec.sigma_r, spec.sigma_phi)
    if source is None:
        config = cases_metamodel_config() if spec.metamodel == METAMODEL_PART else None
        source = ensure_builtin_metamodel(spec.metamodel, config=config, workers=workers, progress=progress)
    if not os.path.isfile(source):
        raise FileNotFoundError(
            f"meta-model file not found: {source} (part.metamodel of {spec.source or 'the problem'})"
        )
    return planner.load_rho(source, spec.sigma_r, spec.sigma_phi)


@dataclass
class ProblemSolution:
    spec: PickupProblemSpec
    problem: object  # the native PickupProblem
    plan: planner.PickupPlan
    metrics: Optional["_core.PickupMetrics"]  # dense re-sampling metrics (None: no stage solved)
    checks: dict  # check name -> passed

    @property
    def passed(self) -> bool:
        return self.plan.success and all(self.checks.values())


def solve(
    robot,
    spec: PickupProblemSpec,
    rho,
    settings: planner.PlannerSettings = planner.PlannerSettings(),
    method=planner.Method.successive,
    time_limit: float = 0.0,
) -> ProblemSolution:
    """Solves one problem and checks the solution densely (solver failures are statuses; method
    routed: ``routed.plan_routed`` with its certificate, lower bound and ``time_limit``)."""
    problem = native_problem(robot, spec, rho)
    if planner.Method.parse(method, "method") is planner.Method.routed:
        plan = routed.plan_routed(robot, problem, settings, time_limit=time_limit)
    else:
        plan = planner.plan(
            robot, problem, settings if not time_limit else replace(settings, time_limit=time_limit), method
        )
    metrics = planner.evaluate(robot, problem, plan) if plan.stages_completed > 0 else None
    return ProblemSolution(spec, problem, plan, metrics, dense_checks(problem, plan, metrics))


# ---- files ---------------------------------------------------------------------------------------
def trajectory_dict(sol: ProblemSolution, n: int = 401) -> dict:
    """Times, base (x, y, yaw) and arm states (positions and rates) over [0, T], the key times and
    speeds, and the polynomial coefficients (normalised time) for an exact re-evaluation."""
    d = sol.plan.to_dict(n)
    q, qd = np.asarray(d["q"]), np.asarray(d["qd"])
    d.update(
        base=q[:, :3].tolist(),
        base_rates=qd[:, :3].tolist(),
        arm=q[:, 3:].tolist(),
        arm_rates=qd[:, 3:].tolist(),
        problem=sol.spec.to_dict(),
        problem_file=sol.spec.source,
    )
    return d


def _finite(v):
    return v if math.isfinite(v) else None  # JSON has no NaN or inf


def metrics_dict(sol: ProblemSolution) -> dict:
    p = sol.plan
    return {
        "status": p.status,
        "success": p.success,
        "best_stage": p.stages_completed,
        "passed_dense_checks": sol.passed,
        "checks": sol.checks,
        "T": _finite(p.T),
        "T1": _finite(p.T1),
        "T2": _finite(p.T2),
        "S_g": _finite(p.S_g),
        "S_c": _finite(p.S_c),
        "cpu_seconds": p.total_cpu_seconds,
        "wall_seconds": p.total_seconds,
        "lower_bound": _finite(p.lower_bound),
        "reason": p.reason,
        "detail": p.detail,
        "seed": p.seed,
        "dense": {
            k: (None if isinstance(v, float) and math.isinf(v) else v)
            for k, v in ({} if sol.metrics is None else sol.metrics.to_dict()).items()
        },
        "stages": [{"stage": s.stage, "status": s.status, "ipopt": s.ipopt_status, "T": s.objective} for s in p.stages],
    }


def speed_profiles(robot, plan: planner.PickupPlan, n: int = 300):
    """Base and gripper speeds over [0, T] (the curves of Fig. 5)."""
    t = np.linspace(0.0, plan.T, n)
    q, qd, _ = plan.sample(t)
    tool = robot.link_index("tool")
    grip = np.array([np.linalg.norm(robot.jacobian(q[k], tool)[:3] @ qd[k]) for k in range(n)])
    return t, np.hypot(qd[:, 0], qd[:, 1]), grip


def plot_speeds(robot, sol: ProblemSolution, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t, base, grip = speed_profiles(robot, sol.plan)
    fig, ax = plt.subplots(figsize=(6, 3.6))
    try:
        ax.plot(t, base, label="mobile base")
        ax.plot(t, grip, label="gripper")
        ax.axvspan(sol.plan.T1, sol.plan.T2, color="0.85", label="grasping")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("speed (m/s)")
        ax.set_title(
            f"{os.path.basename(sol.spec.source or 'problem')}: T = {sol.plan.T:.2f} s, S_g = {sol.plan.S_g:.2f} m/s"
        )
        ax.legend()
        fig.tight_layout()
        with atomic_open(path, "wb") as f:
            fig.savefig(f, format="png", dpi=120)
    finally:
        plt.close(fig)


def write_solution(robot, sol: ProblemSolution, out: str) -> dict:
    """OUT/metrics.json always; OUT/trajectory.json and OUT/speeds.png when a stage solved."""
    os.makedirs(out, exist_ok=True)
    paths = {"metrics": os.path.join(out, "metrics.json")}
    write_json(paths["metrics"], metrics_dict(sol))
    if sol.plan.stages_completed > 0:
        paths["trajectory"] = os.path.join(out, "trajectory.json")
        write_json(paths["trajectory"], trajectory_dict(sol))
        paths["plot"] = os.path.join(out, "speeds.png")
        plot_speeds(robot, sol, paths["plot"])
    return paths
