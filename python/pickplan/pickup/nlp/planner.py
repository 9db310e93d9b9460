"""Time-optimal pick-up on the move (Thakar et al., Sec. V): the native Ipopt NLP in five stages
of successive refinement, the single-shot baseline, STOMP refinement of the arm tails, and the
success-probability surface rho_sigma(S_g, S_c) read from a part-1 meta-model file.

Ipopt + MUMPS are not thread-safe: never solve in two threads of one process. ``cases.solve_many``
runs independent solves in separate processes.

>>> from pickplan.pickup.nlp import planner
>>> robot = planner.mobile_ur5()
>>> robot.dof
9
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import asdict, dataclass, field
from typing import Optional, Sequence, Tuple, Union

import numpy as np

from pickplan import _core
from pickplan.core.io import write_bytes
from pickplan.core.paths import assets_dir
from pickplan.core.robots import Robot
from pickplan.core.settings import Option, native_defaults, to_native
from pickplan.pickup.nlp.feasibility import Reason
from pickplan.pickup.metamodel.model import FORMAT as METAMODEL_FORMAT, load_surface  # noqa: F401 - the format, re-exported


def mobile_ur5() -> Robot:
    """The 9-DOF mobile manipulator of assets/mobile_ur5.urdf (planar base + UR5 + gripper)."""
    return Robot.from_urdf(os.path.join(assets_dir(), "mobile_ur5.urdf"))


# ---- settings and results ----------------------------------------------------------------------
class HessianMode(Option):
    """The NLP's Hessian (native ``HessianMode``; the values are Ipopt's spellings)."""

    exact = "exact"  # eval_hessian
    limited_memory = "limited-memory"  # Ipopt's L-BFGS


class CoefficientBasis(Option):
    """Ipopt's coefficient variables (native ``CoefficientBasis``); results are monomial either way."""

    bernstein = "bernstein"
    monomial = "monomial"


class MuStrategy(Option):
    """Ipopt's barrier update (native ``MuStrategy``)."""

    monotone = "monotone"
    adaptive = "adaptive"


class RateRows(Option):
    """Yaw and arm rate limits (native ``RateRows``): on the Bernstein points of each rate
    polynomial (they then hold on all of [0, T]) or at the samples only."""

    hull = "hull"
    sampled = "sampled"


class SolveStatus(Option):
    """How a stage or a whole solve ended (native ``SolveStatus``): Ipopt's return codes shortened,
    plus bounded (a search run not below the best T), violation_between_samples /
    constraint_violation (rows still fail after the active-set rounds) and not_run."""

    not_run = "not_run"
    solved = "solved"
    solved_acceptable = "solved_acceptable"
    infeasible = "infeasible"
    diverging = "diverging"
    max_iterations = "max_iterations"
    max_cpu_time = "max_cpu_time"
    restoration_failed = "restoration_failed"
    step_too_small = "step_too_small"
    invalid_number = "invalid_number"
    solver_error = "solver_error"
    bounded = "bounded"
    violation_between_samples = "violation_between_samples"
    constraint_violation = "constraint_violation"
    time_limit = "time_limit"  # the wall-clock budget ran out (success: a feasible plan is still held)


class Method(Option):
    """How a problem is solved: the five stages of successive refinement from the heuristic seed
    (the paper's scheme), all constraints at once from a random seed, or the layout-aware scheme
    of ``routed.plan_routed`` (route seeds, certificate and lower bound, time budget)."""

    successive = "successive"
    single_shot = "single_shot"
    routed = "routed"


_OPTIONS = {"hessian": HessianMode, "basis": CoefficientBasis, "mu_strategy": MuStrategy, "rate_rows": RateRows}


@dataclass
@native_defaults(_core.PickupSettings)
class PlannerSettings:
    """Mirrors the native PickupSettings (same field names and defaults; a test checks them
    field by field). Options take their enums or their spellings ("limited-memory")."""

    samples_per_interval: int
    degrees: Sequence[int]  # empty: quintic base and arm joints 1-3, cubic wrists
    nonholonomic_tol: float
    velocity_tol: float
    angular_velocity_tol: float
    collision_margin: float
    joint_limit_margin: float
    t_min: float
    t_max: float
    rate_rows: RateRows
    rate_hull_degree: int  # Bernstein degree of the rate hull
    tol: float
    constr_viol_tol: float
    max_iter: int
    max_cpu_time: float
    print_level: int
    derivative_test: bool  # Ipopt's first-order derivative checker
    ipopt_options: Sequence[Tuple[str, str]]  # extra Ipopt options (name, value)
    output_file: str  # non-empty: Ipopt's log (print level 5) goes to this file
    hessian: HessianMode
    basis: CoefficientBasis
    active_set: bool  # joint/collision rows only where needed, re-solve on violation
    active_joint_window: float
    active_collision_window: float
    active_max_rounds: int
    mu_resolve: float
    warm_start_push: float
    dense_subdivisions: int  # collision check between samples (0: samples only)
    dense_nonholonomic: float  # ... and lateral base speed above this (m/s; 0: not)
    mu_strategy: MuStrategy
    mu_init: float
    seed: int
    arm_seed_noise: float
    seed_speed: float  # heuristic seed: T = path length / seed_speed
    timing_seed: bool  # stage 3 starts from the grasp-timing seed ...
    timing_fraction: float  # ... with this fraction (log T) of the full slow-down
    direct_track: bool  # also solve all constraints from the stage-1 solution, keep the shorter
    direct_max_iter: int  # its Ipopt iterations
    arm_seeds: int  # stages 2-5 from up to this many arm configurations at T2, keep the shortest
    warm_start_stages: bool  # stages 4 and 5 start from the previous stage's multipliers
    time_limit: float  # wall-clock budget of one native solve (s; 0: none)

    def __post_init__(self):
        for name, option in _OPTIONS.items():
            setattr(self, name, option.parse(getattr(self, name), name))

    def to_native(self) -> "_core.PickupSettings":
        return to_native(
            self,
            _core.PickupSettings,
            degrees=list(self.degrees),
            ipopt_options=[(str(k), str(v)) for k, v in self.ipopt_options],
        )


@dataclass(frozen=True)
@native_defaults(_core.StompSettings)
class StompSettings:
    """Mirrors the native StompSettings (same field names and defaults)."""

    iterations: int
    rollouts: int
    noise_stddev: float  # scales the smooth exploration noise N(0, R^-1)
    temperature: float  # h of the per-timestep softmax
    control_weight: float  # smoothness (squared acceleration) cost
    obstacle_weight: float  # hinge obstacle cost per waypoint
    limit_weight: float  # joint position / rate limit hinge costs
    margin: float  # m, obstacle clearance wanted
    seed: int

    def to_native(self) -> "_core.StompSettings":
        return to_native(self, _core.StompSettings)


@dataclass
class StageInfo:
    stage: int
    status: SolveStatus
    ipopt_status: str
    success: bool
    seconds: float
    iterations: int
    objective: float
    max_violation: float
    cpu_seconds: float = 0.0  # thread CPU time (the machine may be shared)
    rounds: int = 1  # Ipopt runs (active-set re-solves + 1)
    rows: int = 0  # constraint rows of the last run


@dataclass
class PickupPlan:
    """A planned pick-up: status, per-stage records and the polynomial trajectory."""

    status: SolveStatus
    success: bool
    stages_completed: int
    stages: list
    T: float
    T1: float
    T2: float
    S_g: float
    S_c: float
    total_seconds: float
    native: object = field(repr=False, default=None)  # _core.PickupResult
    total_cpu_seconds: float = 0.0
    direct: Optional[StageInfo] = None  # the direct track's solve (successive only)
    direct_chosen: bool = False  # its solution is the one returned
    arm_seed_T: list = field(default_factory=list)  # final T of each arm seed's run (nan: failed or bounded)
    arm_seed_chosen: int = 0  # the run the stage records come from
    lower_bound: float = math.nan  # T >= this by the geometry (routed; feasibility.lower_bound)
    reason: Reason = Reason.none  # why there is no plan (routed; none when solved)
    detail: str = ""  # the reason in words (numbers included)
    seed: str = "heuristic"  # the stage-1 seed the plan comes from (routed: a route's label)

    @classmethod
    def from_native(cls, r) -> "PickupPlan":
        info = lambda s: StageInfo(
            s.stage,
            SolveStatus.from_native(s.status),
            s.ipopt_status,
            s.success,
            s.seconds,
            s.iterations,  # noqa: E731
            s.objective,
            s.max_violation,
            s.cpu_seconds,
            s.rounds,
            s.rows,
        )
        stages = [info(s) for s in r.stages]
        direct = info(r.direct) if r.direct.status != _core.SolveStatus.not_run else None
        return cls(
            SolveStatus.from_native(r.status),
            r.success,
            r.stages_completed,
            stages,
            r.T,
            r.T1,
            r.T2,
            r.S_g,
            r.S_c,
            r.total_seconds,
            r,
            r.total_cpu_seconds,
            direct,
            r.direct_chosen,
            list(r.arm_seed_T),
            r.arm_seed_chosen,
        )

    def sample(self, times) -> tuple:
        """(q, q', q'') at the given times (s), each of shape (len(times), 9)."""
        return self.native.sample(np.asarray(times, dtype=float))

    def to_dict(self, n: int = 201) -> dict:
        t = np.linspace(0.0, self.T, n)
        q, qd, _ = self.sample(t)
        return {
            "status": self.status,
            "success": self.success,
            "stages_completed": self.stages_completed,
            "T": self.T,
            "T1": self.T1,
            "T2": self.T2,
            "S_g": self.S_g,
            "S_c": self.S_c,
            "total_seconds": self.total_seconds,
            "total_cpu_seconds": self.total_cpu_seconds,
            "stages": [asdict(s) for s in self.stages],
            "direct": asdict(self.direct) if self.direct else None,
            "direct_chosen": self.direct_chosen,
            "arm_seed_T": [None if math.isnan(t) else t for t in self.arm_seed_T],
            "arm_seed_chosen": self.arm_seed_chosen,
            "lower_bound": None if math.isnan(self.lower_bound) or math.isinf(self.lower_bound) else self.lower_bound,
            "reason": self.reason,
            "detail": self.detail,
            "seed": self.seed,
            "degrees": list(self.native.degrees),
            "x": np.asarray(self.native.x).tolist(),
            "t": t.tolist(),
            "q": q.tolist(),
            "qd": qd.tolist(),
        }


# ---- rho ---------------------------------------------------------------------------------------
def rho_from_surface(surface) -> "_core.RhoPoly":
    """A native surface from any object with ``coeffs``, ``sg_range``, ``sc_range`` (a RhoSurface)."""
    return _core.RhoPoly(np.asarray(surface.coeffs, float), tuple(surface.sg_range), tuple(surface.sc_range))


def load_rho(path, sigma_r: float, sigma_phi: float) -> "_core.RhoPoly":
    """rho_sigma, native, from a meta-model file written by pickplan.pickup.metamodel (part 1)."""
    return rho_from_surface(load_surface(path, sigma_r, sigma_phi))


_SYNTH_ANCHORS = ((0.002, 0.035), (0.007, 0.22), (0.012, 1.2))  # (sigma_r, slope a)


def synthetic_rho(sigma_r: float, sigma_phi: float) -> "_core.RhoPoly":
    """A STAND-IN surface (no physics behind it) for runs without a meta-model file: a monotone
    Bernstein surface rho = sum c_ij B_i(u) B_j(v), c_ij = clip(1 - a(sigma) (i/3) (1 - 0.3 j/2)),
    on S_g in [0.05, 1.2], S_c in [0.05, 0.15] m/s; a(sigma) interpolates log-linearly between
    anchors chosen so the paper's low/medium/high gripper speeds come out at gamma."""
    if not (sigma_r > 0 and sigma_phi > 0):
        raise ValueError(f"sigma_r and sigma_phi must be > 0, got {sigma_r}, {sigma_phi}")
    xs = np.log([a[0] for a in _SYNTH_ANCHORS])
    ys = np.log([a[1] for a in _SYNTH_ANCHORS])
    a = float(np.exp(np.interp(np.log(sigma_r), xs, ys)))
    i = np.arange(4)[:, None] / 3.0
    j = np.arange(3)[None, :] / 2.0
    c = np.clip(1.0 - a * i * (1.0 - 0.3 * j), 0.0, 1.0)
    return _core.RhoPoly(c, (0.05, 1.2), (0.05, 0.15))


# ---- solving -----------------------------------------------------------------------------------
def _check(problem, robot: Robot):
    problem.validate(robot.native)


def plan(
    robot: Robot,
    problem,
    settings: PlannerSettings = PlannerSettings(),
    method: Union[Method, str] = Method.successive,
    x0=None,
) -> PickupPlan:
    """Solve: method "successive" (the five stages, from ``x0`` when given, else the heuristic seed)
    or "single_shot" (all constraints at once, from ``x0`` when given, else from a random seed,
    settings.seed); "routed" is ``routed.plan_routed``. Solver failures are statuses; bad input
    raises ValueError."""
    method = Method.parse(method, "method")
    if method is Method.routed:
        raise ValueError("method routed: call pickplan.pickup.nlp.routed.plan_routed")
    _check(problem, robot)
    x0 = np.zeros(0) if x0 is None else np.asarray(x0, dtype=float)
    if method is Method.single_shot:
        return PickupPlan.from_native(_core.pickup_solve_single_shot(robot.native, problem, settings.to_native(), x0))
    return PickupPlan.from_native(_core.pickup_solve_successive(robot.native, problem, settings.to_native(), x0))


def solve_stage(robot: Robot, problem, x0, stage: int, settings: PlannerSettings = PlannerSettings()):
    """One stage (1..5, or 0 = all constraints) from the variable vector x0 (coefficients of the
    normalised-time polynomials, then T1/T, T2/T, T, S_g, S_c)."""
    return _core.pickup_solve_stage(
        robot.native, problem, settings.to_native(), int(stage), np.asarray(x0, dtype=float)
    )


def seed_from_times(
    robot: Robot, problem, T: float, T1: float, T2: float, settings: PlannerSettings = PlannerSettings()
) -> np.ndarray:
    """The heuristic seed with its times replaced; checks 0 <= T1 <= T2 <= T (ValueError)."""
    if not (np.isfinite([T, T1, T2]).all() and 0.0 <= T1 <= T2 <= T and T > 0):
        raise ValueError(f"inconsistent time ordering: expected 0 <= T1 <= T2 <= T, got T1={T1}, T2={T2}, T={T}")
    x = np.array(_core.pickup_heuristic_seed(robot.native, problem, settings.to_native()))
    n = len(x) - 5
    x[n], x[n + 1], x[n + 2] = T1 / T, T2 / T, T
    return x


def evaluate(robot: Robot, problem, result: PickupPlan, n: int = 2001) -> "_core.PickupMetrics":
    """Native dense re-sampling metrics (pose error at T2, non-holonomic error, limits, clearance)."""
    return _core.pickup_evaluate(robot.native, problem, result.native, int(n))


# ---- dense checks ------------------------------------------------------------------------------
# Dense checks of a solution (2001 instants over [0, T]; the NLP enforces its rows at samples, so
# these leave room for what happens between them).
POSE_POSITION_TOL = 1e-3  # m, tool position at T2
POSE_ORIENTATION_TOL = 1e-2  # rad
NONHOLONOMIC_MEAN_TOL = 0.02  # m/s, mean lateral base speed
NONHOLONOMIC_DRIFT_TOL = 0.2  # m, its integral over [0, T]
JOINT_OVERSHOOT_TOL = 0.03  # rad past a joint limit between samples
VELOCITY_ERROR_TOL = 0.05  # m/s, |J q' - S_g n_g| during grasping


def dense_checks(problem, plan: PickupPlan, metrics: Optional["_core.PickupMetrics"]) -> dict:
    """The checks a solution must pass by dense re-sampling (names -> bool; empty: no solution)."""
    if not plan.success or metrics is None:
        return {}
    return {
        "pose_error_at_T2": metrics.pose_error_position <= POSE_POSITION_TOL
        and metrics.pose_error_orientation <= POSE_ORIENTATION_TOL,
        "nonholonomic": metrics.nonholonomic_mean <= NONHOLONOMIC_MEAN_TOL
        and metrics.nonholonomic_drift <= NONHOLONOMIC_DRIFT_TOL,
        "clearance": metrics.min_clearance >= 0.0,
        "joint_limits": metrics.joint_limit_violation <= JOINT_OVERSHOOT_TOL,
        "grasp_velocity": metrics.velocity_error_max <= VELOCITY_ERROR_TOL,
        "rho_at_least_gamma": metrics.success_probability >= problem.gamma - 1e-6,
    }


def passes_dense_checks(robot: Robot, problem, plan: PickupPlan) -> bool:
    """A converged plan that also passes every dense check (what counts as a feasible plan)."""
    checks = dense_checks(problem, plan, evaluate(robot, problem, plan) if plan.success else None)
    return bool(checks) and all(checks.values())


# ---- STOMP -------------------------------------------------------------------------------------
def refine_tails(robot: Robot, problem, result: PickupPlan, n: int = 30, iterations: int = 40, seed: int = 0) -> dict:
    """STOMP on the arm over [0, T1] and [T2, T] (n waypoints each); base unchanged. Returns
    {"pre": (t, Q, info), "post": (t, Q, info)} with info the native StompResult."""
    out = {}
    for name, (a, b) in (("pre", (0.0, result.T1)), ("post", (result.T2, result.T))):
        if b - a < 1e-6:
            continue
        t = np.linspace(a, b, n)
        q, _, _ = result.sample(t)
        st = StompSettings(iterations=int(iterations), seed=int(seed)).to_native()
        info = _core.stomp_refine(
            robot.native,
            q,
            float(t[1] - t[0]),
            np.asarray(problem.arm_rate_limits),
            problem.body_spheres,
            problem.obstacles,
            st,
        )
        out[name] = (t, np.array(info.q), info)
    return out


# ---- files -------------------------------------------------------------------------------------
def save_plan(plan_dict: dict, path_stem) -> None:
    """<stem>.json (everything) and <stem>.npz (t, q, qd, x) written atomically."""
    import io

    write_bytes(f"{path_stem}.json", json.dumps(plan_dict, indent=1).encode())
    buf = io.BytesIO()
    np.savez(
        buf,
        t=np.asarray(plan_dict["t"]),
        q=np.asarray(plan_dict["q"]),
        qd=np.asarray(plan_dict["qd"]),
        x=np.asarray(plan_dict["x"]),
    )
    write_bytes(f"{path_stem}.npz", buf.getvalue())
