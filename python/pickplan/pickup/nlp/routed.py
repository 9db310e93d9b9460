"""Pick-up on the move for any layout (issue 37): the certificate and lower bound of
``feasibility``, stage-1 runs from the heuristic seed and from the car-like route seeds of ``route``,
successive refinement from the fastest base path, and a wall-clock budget.

1. ``feasibility.certify``: a problem the geometry rules out (gamma unattainable, the part out of
   reach from every free base position, T's bound above the horizon) gets its reason, no solve.
2. Stage 1 (the base path: non-holonomic, limits, grasping area, goal, base collisions) from the
   heuristic seed and from up to ``routes`` route seeds; the solved ones are ranked by their T.
3. The five stages (native ``solve_successive``: arm seeds) from the best stage-1 solution; on
   failure (or a plan that fails the dense checks, ``planner.dense_checks``) from the next, while
   the budget lasts. The first plan that passes is returned.
4. No success: the reason is ``solver_failed`` (the certificate found nothing against the problem)
   and the plan that went furthest is returned as the closest; ``time_limit`` when the budget ran
   out first. With a budget the native runs get the time left (``PlannerSettings.time_limit``), and
   a plan found before the deadline is returned with status ``time_limit`` when later runs were cut.

Ipopt 3.11 with MUMPS is not thread-safe (``planner``), so the stage-1 runs and the candidates run
one after another in this thread (the GIL is released in each native solve); the route geometry is
milliseconds.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.pickup.nlp import planner, route
from pickplan.pickup.nlp.feasibility import Certificate, Reason, base_geometry, certify

ROUTES = 3   # route seeds tried in stage 1 beside the heuristic seed
# Base polynomial degrees tried in stage 1 (when the settings leave the degrees to the default): the
# paper's quintic from the heuristic seed, then degree 7 from every seed. A quintic base path cannot
# hold a detour with a turn back (issue 37: side and behind layouts, stage 1 at T = 50-100 s); degree
# 7 can, at 6 more variables. The fastest stage-1 path wins.
BASE_DEGREES = (5, 7)


def _left(deadline: Optional[float]) -> float:
    return math.inf if deadline is None else deadline - time.monotonic()


def _with_budget(settings: planner.PlannerSettings, deadline: Optional[float]) -> planner.PlannerSettings:
    return settings if deadline is None else replace(settings, time_limit=max(1e-3, _left(deadline)))


def _variants(robot, settings: planner.PlannerSettings) -> list:
    """The settings stage 1 is tried with: one per base degree (BASE_DEGREES), or the caller's degrees."""
    if len(settings.degrees):
        return [settings]
    arm = [5 if i < 6 else 3 for i in range(3, robot.dof)]  # native default_degrees
    return [replace(settings, degrees=[d, d, d] + arm) for d in BASE_DEGREES]


def _stage1(robot, problem, settings, deadline, routes) -> list:
    """Stage 1 from every seed at every base degree while time is left: [(T, label, settings, x)]
    of the solved runs, fastest first (the lower degree first among equal T)."""
    solved = []
    variants = _variants(robot, settings)
    for k, variant in enumerate(variants):
        for label, x0 in seeds(robot, problem, variant, routes if k == len(variants) - 1 else 0):
            if _left(deadline) <= 0:
                return sorted(solved, key=lambda s: s[0])
            r = planner.solve_stage(robot, problem, x0, 1, _with_budget(variant, deadline))
            if r.success:
                name = label if len(variant.degrees) == 0 or k == 0 else f"{label}, base degree {variant.degrees[0]}"
                solved.append((r.objective * (1 + 1e-3 * k), name, variant, np.asarray(r.x)))
    return sorted(solved, key=lambda s: s[0])


def _no_solve(cert: Certificate, status: planner.SolveStatus) -> planner.PickupPlan:
    return planner.PickupPlan(status=status, success=False, stages_completed=0, stages=[], T=math.nan, T1=math.nan,
                              T2=math.nan, S_g=math.nan, S_c=math.nan, total_seconds=0.0, lower_bound=cert.lower_bound,
                              reason=cert.reason, detail=cert.detail, seed="none")


def seeds(robot, problem, settings: planner.PlannerSettings, routes: int = ROUTES):
    """(label, x0) stage-1 seeds, one at a time (the caller checks its deadline between them): the
    native heuristic seed, then the route seeds, shortest first."""
    template = np.array(_core.pickup_heuristic_seed(robot.native, problem, settings.native()))
    yield "heuristic", template
    if routes:
        geo = base_geometry(robot, problem, settings)
        for r in route.candidate_routes(geo, routes):
            yield f"route {r.label}", route.route_seed(r, geo, template, settings, robot.dof, problem.stroke)


def plan_routed(robot, problem, settings: planner.PlannerSettings = planner.PlannerSettings(),
                time_limit: float = 0.0, routes: int = ROUTES, direct_track: bool = False) -> planner.PickupPlan:
    """Plans any layout (module doc). ``time_limit`` > 0: wall-clock seconds for the whole call.
    ``direct_track`` (settings.direct_track is replaced by it): the native all-constraint hedge after
    the five stages; off here, where the next stage-1 solution is the hedge (issue 37's benchmark,
    paper and side layouts: the direct track won 1 of 20 problems each, at 0.2-1.2 s of CPU each)."""
    settings = replace(settings, direct_track=direct_track)
    if not (time_limit >= 0 and math.isfinite(time_limit)):
        raise ValueError(f"time_limit: expected a finite number >= 0 (0: none), got {time_limit}")
    t0, c0 = time.monotonic(), time.thread_time()
    deadline = t0 + time_limit if time_limit > 0 else None
    problem.validate(robot.native)
    cert = certify(robot, problem, settings)
    if not cert.feasible:
        p = _no_solve(cert, planner.SolveStatus.infeasible)
        p.total_seconds, p.total_cpu_seconds = time.monotonic() - t0, time.thread_time() - c0
        return p
    ranked = _stage1(robot, problem, settings, deadline, routes)
    best, closest = None, None
    for _, label, variant, x1 in ranked:
        if _left(deadline) <= 0:
            break
        p = planner.plan(robot, problem, _with_budget(variant, deadline), planner.Method.successive, x0=x1)
        p.seed = label
        if p.success and planner.passes_dense_checks(robot, problem, p):
            best = p
            break
        if closest is None or p.stages_completed > closest.stages_completed:
            closest = p
    out = best or closest
    timed_out = deadline is not None and _left(deadline) <= 0 and best is None
    if out is None:  # no stage-1 solution (or no time for one)
        out = _no_solve(cert, planner.SolveStatus.time_limit if timed_out else planner.SolveStatus.infeasible)
    out.lower_bound = cert.lower_bound
    if best is None:
        if out.success:  # converged, but failed the dense checks between the samples: not a feasible plan
            out.success, out.status = False, planner.SolveStatus.violation_between_samples
        out.reason = Reason.time_limit if timed_out else Reason.solver_failed
        out.detail = (f"the time limit of {time_limit:g} s ran out before a feasible plan" if timed_out else
                      f"no solver run succeeded although the geometry allows T >= {cert.lower_bound:.2f} s; "
                      f"the closest plan reached stage {out.stages_completed} of 5")
        if timed_out:
            out.status = planner.SolveStatus.time_limit
    out.total_seconds, out.total_cpu_seconds = time.monotonic() - t0, time.thread_time() - c0
    return out
