"""Pick-up on the move for any layout (issue 37): the certificate and lower bound of
``feasibility``, stage-1 runs from the heuristic seed and from the car-like route seeds of ``route``,
successive refinement from the fastest base path, and a wall-clock budget.

1. ``feasibility.certify``: a problem the geometry rules out (gamma unattainable, the part out of
   reach from every free base position, T's bound above the horizon) gets its reason, no solve.
2. Stage 1 (the base path: non-holonomic, limits, grasping area, goal, base collisions) from the
   heuristic seed and from up to ``routes`` route seeds at base degree 7, the seed with the shortest
   T first (``seeds``), until one's T is within NEAR_BOUND of the lower bound; the solved ones are
   ranked by their T. The quintic base from the heuristic seed, then degree 12 from every seed, run
   only when their plans are spent.
3. The stage-1 solutions less repeats (two seeds that reach the same optimum); from each in turn,
   the five stages (native ``solve_successive``: arm seeds; the base path lifted to
   LATER_BASE_DEGREE, so stage 3 can slow it round the grasp alone), and when their plan fails (or
   fails the dense checks, ``planner.dense_checks``) all constraints at once (the native direct
   track, on its own) from the same solution (first, where the base path reverses: ``_jobs``),
   while the budget lasts; an all-constraint plan that converged is solved again from itself lifted
   to LATER_BASE_DEGREE (``_lifted_if_better``). The first plan that passes is returned; above
   SECOND_OPINION times the bound it gets a second opinion first (a five-stage plan: all
   constraints from its solution, then from the later ones; an all-constraint plan: the next
   solutions' plans). When none does: the plans (of either method) that held their rows at the
   samples but not between them (a long T leaves a second or more between samples, where the base
   polynomial slides sideways) are solved again, the same method from the same stage-1 solution,
   with the samples refined (``REFINE``), the shortest first. No stage-1 solution at all: stage 1
   again at the refined samples.
4. No success: the reason is ``solver_failed`` (the certificate found nothing against the problem)
   and the plan that went furthest is returned as the closest; ``time_limit`` when the budget ran
   out first. With a budget the native runs get the time left (``PlannerSettings.time_limit``), and
   a plan found before the deadline is returned with status ``time_limit`` when later runs were cut.

Ipopt 3.11 with MUMPS is not thread-safe (``planner``), so the stage-1 runs and the candidates run
one after another in this thread (the GIL is released in each native solve); the route geometry is
milliseconds (up to 0.2 s in clutter, where many routes collide).
"""

from __future__ import annotations

import enum
import math
import time
from dataclasses import replace
from typing import Optional

import numpy as np

from pickplan import _core
from pickplan.pickup.nlp import planner, route
from pickplan.pickup.nlp.budget import Budget
from pickplan.pickup.nlp.feasibility import Certificate, Reason, base_geometry, certify

ROUTES = 3  # route seeds tried in stage 1 beside the heuristic seed
# Base polynomial degrees tried in stage 1 (when the settings leave the degrees to the default):
# degree 7 from every seed first, the paper's quintic from the heuristic seed only when no plan from
# those base paths passes. A quintic base path cannot hold a detour with a turn back (issue 37: side
# and behind layouts, stage 1 at T = 50-100 s); degree 7 can, at 6 more variables, and holds every
# quintic. Run first, the quintic won 1 of 157 solved problems (none of the paper's, side or case
# problems) and cost 0.2-0.7 s of CPU on each of 12 behind problems profiled, where it never
# converged (bench/PICKUP.md, session 23). Degree 12 last, from every seed: a route that weaves
# between pillars needs it (cluttered layout: 3 of the 9 problems of 100 that failed at 7 and 5 were
# solved, at 16-45 s of CPU; it runs only where the others' plans are spent).
BASE_DEGREES = (7, 5, 12)
ROUTE_MIN_DEGREE = 7  # the later base degrees that can hold a detour get route seeds (not the quintic)
# The base degree of the five stages from a stage-1 solution (with the default degrees): the same path
# at this degree (its coefficients padded with zeros). Stage 3's grasp timing slows the base round the
# window, and a degree-7 path could only slow all of it: paper layout, 40 problems, T / bound median
# 1.55 -> 1.37 (p90 1.99 -> 1.51), CPU median 0.38 -> 0.46 s (degree 10: 1.44). 12 is the highest
# PolyTraj takes. The all-constraint fallback keeps the stage-1 degree.
LATER_BASE_DEGREE = 12
# ... and its samples per interval, scaled by this: a degree-12 base path has more room to slide
# sideways between 8 samples, and its plans failed the dense checks there and were solved again
# refined (behind layout, 40 problems: CPU median 10.0 -> 4.1 s, solved 38 -> 39; paper 0.47 -> 0.58 s).
LATER_SAMPLES = 1.5
# A five-stage plan whose T exceeds this multiple of the lower bound (issue 37's worst-case target)
# gets a second opinion: all constraints at once from the same stage-1 solution, kept when shorter.
# The five stages commit the arm to one IK branch and grasp timing; far from the bound that is
# where the time went (behind layout: 23 s -> 11 s against a bound of 6 s). An all-constraint plan
# (the fallback, already lifted to LATER_BASE_DEGREE by ``_lifted_if_better``) so far from the bound
# gets the next base paths' plans as its second opinion.
SECOND_OPINION = 3.0
# When no plan passes and some held their rows at the samples but not between them (the base slides
# sideways between samples a second or more apart when T is long), the five stages again with
# the samples per interval scaled by these factors in turn (issue 37, behind layout: 8 -> 12 or 16);
# the all-constraint plans that failed so are solved again likewise.
REFINE = (1.5, 2.0)
# Stage 1 tries no further seed once a base path's T is within this multiple of the lower bound: no
# other base path can be more than that much faster, and each further stage-1 run costs 0.1-1.6 s
# of CPU (most in clutter, where route seeds often converge at 2-5x the bound or fail at the
# horizon). 40 problems each, against every seed: at 1.25, CPU median cluttered 1.57 -> 1.07 s with
# every plan the same, behind 1.81 -> 1.52 s with 2 plans changed (1.471 -> 1.49, 1.394 -> 1.392);
# at 1.15, cluttered 1.06 s and behind 1.76 s; at 1.4, cluttered 1.00 s and behind 1.54 s. At 1.25,
# 100 problems each: cluttered 1.90 -> 1.13 s (3 plans changed), behind 1.94 -> 1.50 s (6 changed);
# T / bound medians 1.454 and 1.523 -> 1.527.
NEAR_BOUND = 1.25


def _variants(robot, settings: planner.PlannerSettings) -> list:
    """The settings stage 1 is tried with: one per base degree (BASE_DEGREES), or the caller's degrees."""
    if len(settings.degrees):
        return [settings]
    arm = [5 if i < 6 else 3 for i in range(3, robot.dof)]  # native default_degrees
    return [replace(settings, degrees=[d, d, d] + arm) for d in BASE_DEGREES]


class Part(enum.Enum):
    """Which of stage 1's base degrees (BASE_DEGREES) a call runs: every one, the first, or the later
    ones (nothing with the caller's degrees)."""

    every = "every"
    first = "first"
    later = "later"


def _stage1(
    robot, problem, settings, budget: Budget, routes, factor: float = 1.0, part: Part = Part.every, enough: float = 0.0
) -> list:
    """Stage 1 from every seed (the first base degree and those >= ROUTE_MIN_DEGREE) and from the
    heuristic seed (the quintic) while time is left, and until a base path's T is at most ``enough``
    (s): [(T, label, settings, x, later)] of the solved runs, fastest first (the first degree first
    among equal T); ``later``: (settings, x) of the same path at LATER_BASE_DEGREE for the five
    stages, None with the caller's degrees. ``factor`` scales the samples per interval (the later
    stages from such a solution keep them)."""
    solved = []
    if factor != 1:
        settings = replace(settings, samples_per_interval=int(round(settings.samples_per_interval * factor)))
    variants = _variants(robot, settings)
    chosen = {Part.every: range(len(variants)), Part.first: range(1), Part.later: range(1, len(variants))}[part]
    for k in chosen:
        if budget.spent():  # (the seeds' route search takes up to 0.2 s in clutter)
            break
        variant = variants[k]
        with_routes = k == 0 or variant.degrees[0] >= ROUTE_MIN_DEGREE  # (the caller's degrees: k = 0)
        for label, x0 in seeds(robot, problem, variant, routes if with_routes else 0, budget.spent_at()):
            if budget.spent() or (solved and min(s[0] for s in solved) <= enough):
                break
            t = time.monotonic()
            r = planner.solve_stage(robot, problem, x0, 1, budget.settings(variant))
            budget.note(r.status, time.monotonic() - t, r.iterations)
            if r.success:
                name = (  # the native default's quintic keeps the plain label
                    label
                    if len(settings.degrees) or variant.degrees[0] == 5
                    else f"{label}, base degree {variant.degrees[0]}"
                )
                name += f", {variant.samples_per_interval} samples per interval" if factor != 1 else ""
                x = np.asarray(r.x)
                # the five stages' base degree (the caller's degrees stay)
                later = None if len(settings.degrees) else _raised(variant, x, robot.dof)
                solved.append((r.objective * (1 + 1e-3 * k), name, variant, x, later))
    return sorted(solved, key=lambda s: s[0])


def _raised(variant: planner.PlannerSettings, x: np.ndarray, dof: int) -> tuple:
    """(settings, x) of the same plan with the base polynomials at LATER_BASE_DEGREE (the monomial
    coefficients padded with zeros: exactly the same path), sampled LATER_SAMPLES times as densely."""
    degrees = list(variant.degrees)
    parts, off = [], 0
    for i in range(dof):
        c = x[off : off + degrees[i] + 1]
        off += degrees[i] + 1
        parts.append(np.concatenate([c, np.zeros(max(0, LATER_BASE_DEGREE - degrees[i]))]) if i < 3 else c)
    raised = [max(d, LATER_BASE_DEGREE) if i < 3 else d for i, d in enumerate(degrees)]
    samples = int(round(variant.samples_per_interval * LATER_SAMPLES))
    return replace(variant, degrees=raised, samples_per_interval=samples), np.concatenate(parts + [x[off:]])


def _no_solve(cert: Certificate, status: planner.SolveStatus) -> planner.PickupPlan:
    return planner.PickupPlan(
        status=status,
        success=False,
        stages_completed=0,
        stages=[],
        T=math.nan,
        T1=math.nan,
        T2=math.nan,
        S_g=math.nan,
        S_c=math.nan,
        total_seconds=0.0,
        lower_bound=cert.lower_bound,
        reason=cert.reason,
        detail=cert.detail,
        seed="none",
    )


def seeds(robot, problem, settings: planner.PlannerSettings, routes: int = ROUTES, deadline: Optional[float] = None):
    """[(label, x0)] stage-1 seeds: the native heuristic seed and the route seeds (their search stops
    at ``deadline``, a time.monotonic() instant), by their own T, shortest first. Each seed's T is its
    estimate of the base path's duration (a route's length at the speed and yaw-rate limits, the
    heuristic's straight path at the seed speed), so stage 1, which stops near the bound, starts
    from the likeliest short base path: behind the start the heuristic's path runs past the part and
    back at 3-10x a route's T; beside the line it is about as short as the best route (issue 37, 40
    problems: CPU median behind 1.22 -> 1.17 s, cluttered 1.07 -> 1.01 s, within the run-to-run
    noise; of 80 plans 4 longer, 1 shorter)."""
    template = np.array(_core.pickup_heuristic_seed(robot.native, problem, settings.to_native()))
    out = [("heuristic", template)]
    if routes:
        geo = base_geometry(robot, problem, settings)
        for r in route.candidate_routes(geo, routes, deadline=deadline):
            out.append((f"route {r.label}", route.route_seed(r, geo, template, settings, robot.dof, problem.stroke)))
    return sorted(out, key=lambda seed: seed[1][-3])  # x0[-3]: T


def _solve_one(robot, problem, entry: tuple, budget: Budget, method: planner.Method, factor: float = 1.0) -> tuple:
    """(plan, whether it passes the dense checks) of ``method`` from one stage-1 solution, with the
    samples per interval scaled by ``factor``. single_shot: the all-constraint NLP from it (the
    native direct track on its own). Here it is a method of its own, not the native track's hedge, so
    it gets a stage's Ipopt iterations (``max_iter``), not the hedge's ``direct_max_iter``: from
    reversing base paths it stopped at that cap where it converges (behind, 100 problems: T / bound
    median 1.56 -> 1.52, CPU median 1.97 -> 1.81 s; cluttered 96, headings 99 and paper 100 of 100
    the same plans)."""
    _, label, variant, x1, later = entry
    if later is not None and method is planner.Method.successive:
        variant, x1 = later
    if method is planner.Method.single_shot:
        label = f"{label}, direct"
    if factor != 1:
        variant = replace(variant, samples_per_interval=int(round(variant.samples_per_interval * factor)))
        label = f"{label}, {variant.samples_per_interval} samples per interval"
    return _run(robot, problem, variant, method, x1, label, budget)


def _run(robot, problem, settings, method: planner.Method, x0, label: str, budget: Budget) -> tuple:
    """(plan, whether it passes the dense checks) of one native plan within the budget, labelled."""
    t = time.monotonic()
    p = planner.plan(robot, problem, budget.settings(settings), method, x0=x0)
    p.seed = label
    budget.note(p.status, time.monotonic() - t, sum(s.iterations for s in p.stages))
    return p, bool(p.success and planner.passes_dense_checks(robot, problem, p))


def _lifted_plan(robot, problem, plan: planner.PickupPlan, variant, budget: Budget) -> tuple:
    """(plan, whether it passes the dense checks) of the all-constraint NLP from an all-constraint
    ``plan`` (made with ``variant``) lifted to LATER_BASE_DEGREE: it starts at (or, when ``plan``
    failed between the samples, near) a feasible point and the base can then slow round the grasp
    alone and turn back more sharply."""
    lifted, x = _raised(variant, np.asarray(plan.native.x), robot.dof)
    label = f"{plan.seed}, base degree {LATER_BASE_DEGREE}"
    return _run(robot, problem, lifted, planner.Method.single_shot, x, label, budget)


def _lifted_if_better(robot, problem, p: planner.PickupPlan, ok: bool, entry: tuple, factor: float, budget: Budget):
    """(plan, whether it passes) of an all-constraint plan ``p`` from the stage-1 solution ``entry``
    (samples per interval scaled by ``factor``): when it converged at the stage-1 degree, itself
    lifted (``_lifted_plan``) is kept if it passes and is shorter, or passes where ``p`` failed the
    dense checks (then the lift's samples are also refined by REFINE[0]: the degree-7 base slid
    sideways between them). A degree-7 base turns back only slowly: behind layout, a plan at 11.7 s
    came to 8.8 s (1.80 -> 1.36x its bound) in 0.1 s of CPU; 20 problems: T / bound median 1.71 with
    the passing plans lifted, 1.57 with the failing ones too (behind 1, 8, 11: 1.95 / 1.71 / 1.93 ->
    1.55 / 1.63 / 1.79), each lift 0.1-0.4 s of CPU."""
    if not p.success or entry[4] is None or budget.spent():  # entry[4] None: the caller's degrees
        return p, ok
    refine = factor * (1.0 if ok else REFINE[0])
    variant = replace(entry[2], samples_per_interval=int(round(entry[2].samples_per_interval * refine)))
    lifted, lifted_ok = _lifted_plan(robot, problem, p, variant, budget)
    if lifted_ok and (not ok or lifted.T < p.T):
        return lifted, True
    return p, ok


def _solve_lifted(robot, problem, entry: tuple, budget: Budget, method: planner.Method, factor: float = 1.0):
    """``_solve_one``, and an all-constraint plan then ``_lifted_if_better``."""
    p, ok = _solve_one(robot, problem, entry, budget, method, factor)
    if method is planner.Method.single_shot:
        p, ok = _lifted_if_better(robot, problem, p, ok, entry, factor, budget)
    return p, ok


def _second_opinion(robot, problem, best: planner.PickupPlan, entries: list, budget: Budget, target: float):
    """The shortest passing plan of ``best`` (a five-stage plan above ``target``) and the all-constraint
    plans (``_lifted_if_better``) from the stage-1 solutions ``entries`` in turn, until one is within
    ``target`` or the budget is spent."""
    for entry in entries:
        if best.T <= target or budget.spent():
            break
        p, ok = _solve_lifted(robot, problem, entry, budget, planner.Method.single_shot)
        if ok and p.T < best.T:
            best = p
    return best


def _between_samples(p: planner.PickupPlan) -> bool:
    """The plan holds its rows at the samples but not between them: it converged yet failed a dense
    check, or the native active set gave up on the rows between the samples."""
    return p.success or p.status is planner.SolveStatus.violation_between_samples


def _solve_ranked(robot, problem, jobs: list, budget: Budget, factor: float = 1.0, more=None) -> tuple:
    """(the first plan that passes the dense checks or None, its (stage-1 solution, method), the
    plan that went furthest, [(T, stage-1 solution, method)] of the plans that failed only between
    the samples) of the jobs (stage-1 solution, method) in their order, while the budget lasts.
    ``more``: called once when the jobs run out, its jobs are appended to ``jobs`` and run (the
    later base degrees' stage-1 solutions, ``_LaterPaths``). The furthest plan is a five-stage one
    when there is any."""
    closest, direct, between = None, None, []
    i = 0
    while not budget.spent():
        if i == len(jobs) and more is not None:
            jobs.extend(more())
            more = None
        if i == len(jobs):
            break
        entry, method = jobs[i]
        i += 1
        p, ok = _solve_lifted(robot, problem, entry, budget, method, factor)
        if ok:
            return p, (entry, method), closest or direct, between
        if _between_samples(p):
            between.append((p.T if math.isfinite(p.T) else math.inf, entry, method))
        if method is planner.Method.single_shot:
            direct = direct or p
        elif closest is None or p.stages_completed > closest.stages_completed:
            closest = p
    return None, None, closest or direct, between


def _jobs(entries: list, methods: tuple) -> list:
    """(stage-1 solution, method) in the order they run: per solution ``methods`` (the five stages,
    then the all-constraint plan), the all-constraint plan first from a base path that reverses
    (``route.reverses``). The five stages fix the base path before the arm: stage 3 can slow it
    round the grasp but not move its reversal, and from such paths their plans looped round the
    part forwards instead (issue 37, behind layout, 20 problems: T / bound median 1.52 -> 1.46, CPU
    median 4.39 -> 2.63 s; the paper, headings and cluttered layouts' plans the same but one
    shorter, headings 11: 1.48 -> 1.43)."""
    return [
        (e, m)
        for e in entries
        for m in (methods[::-1] if len(methods) > 1 and route.reverses(e[3], e[2].degrees) else methods)
    ]


def _distinct(ranked: list, tol: float) -> list:
    """The stage-1 solutions less those that repeat an earlier one (same degrees, every variable
    within ``tol`` of the larger's scale): two seeds that converge to the same local optimum would
    give the same later stages twice (issue 37, behind layout: two route seeds, 2 s of CPU)."""
    out = []
    for entry in ranked:
        x = entry[3]
        if not any(len(x) == len(e[3]) and np.abs(x - e[3]).max() <= tol * max(1.0, np.abs(x).max()) for e in out):
            out.append(entry)
    return out


class _LaterPaths:
    """The jobs of the later base degrees' stage-1 solutions (``Part.later``), computed on the first
    call only (an empty list after it): they run when the first degree's plans are spent."""

    def __init__(self, robot, problem, settings, budget: Budget, methods: tuple, routes: int):
        self.args, self.methods, self.done = (robot, problem, settings, budget, routes), methods, False

    def __call__(self) -> list:
        if self.done:
            return []
        self.done = True
        robot, problem, settings, budget, routes = self.args
        later = _stage1(robot, problem, settings, budget, routes, part=Part.later)
        return _jobs(_distinct(later, settings.tol), self.methods)


def _refined(robot, problem, between: list, budget: Budget):
    """The first plan that passes with the samples refined (REFINE, each factor in turn), re-solving
    the plans that held their rows at the samples only, shortest T first: more rows lengthen T
    little, so the shortest such plan is the likeliest short feasible one (issue 37, behind layout:
    all constraints at once at T = 23 s where the five stages, first before, ended at 54 s). None
    when none passes."""
    for factor in REFINE:
        jobs = [(entry, method) for _, entry, method in sorted(between, key=lambda b: b[0])]
        best, _, _, between = _solve_ranked(robot, problem, jobs, budget, factor)
        if best is not None or not between:
            return best
    return None


def check_near_bound(near_bound: float) -> None:
    """ValueError unless ``near_bound`` (plan_routed's stage-1 stop) is a finite number >= 0."""
    if not (near_bound >= 0 and math.isfinite(near_bound)):
        raise ValueError(f"near_bound: expected a finite number >= 0 (0: every seed), got {near_bound}")


def plan_routed(
    robot,
    problem,
    settings: planner.PlannerSettings = planner.PlannerSettings(),
    time_limit: float = 0.0,
    routes: int = ROUTES,
    direct_track: bool = False,
    fallback: bool = True,
    refine: bool = True,
    near_bound: float = NEAR_BOUND,
) -> planner.PickupPlan:
    """Plans any layout (module doc). ``time_limit`` > 0: wall-clock seconds for the whole call.
    ``direct_track`` (settings.direct_track is replaced by it): the native all-constraint hedge after
    the five stages; off here, where the next stage-1 solution is the hedge (issue 37's benchmark,
    paper and side layouts: the direct track won 1 of 20 problems each, at 0.2-1.2 s of CPU each).
    ``fallback``: when no five-stage plan passes, the all-constraint NLP from each stage-1 solution
    in turn (issue 37, behind layout: it found feasible plans where the five stages ended with the
    base sliding sideways between the samples or past the horizon); and from the plan's own
    stage-1 solution when its T is above SECOND_OPINION times the lower bound. ``near_bound``: stage 1
    tries no further seed once a base path's T is within this multiple of the lower bound (0: every
    seed, for the fastest base path at more CPU)."""
    settings = replace(settings, direct_track=direct_track)
    if not (time_limit >= 0 and math.isfinite(time_limit)):
        raise ValueError(f"time_limit: expected a finite number >= 0 (0: none), got {time_limit}")
    check_near_bound(near_bound)
    t0, c0 = time.monotonic(), time.thread_time()
    budget = Budget(time_limit)
    problem.validate(robot.native)
    cert = certify(robot, problem, settings)
    if not cert.feasible:
        p = _no_solve(cert, planner.SolveStatus.infeasible)
        p.total_seconds, p.total_cpu_seconds = time.monotonic() - t0, time.thread_time() - c0
        return p
    methods = (planner.Method.successive, planner.Method.single_shot) if fallback else (planner.Method.successive,)
    later = _LaterPaths(robot, problem, settings, budget, methods, routes)
    # (the later degrees and the refined samples run where these base paths failed: every seed there)
    ranked = _stage1(robot, problem, settings, budget, routes, part=Part.first, enough=near_bound * cert.lower_bound)
    # Each solution's fallback comes before the next solution's five stages: it is cheaper (behind
    # layout: 0.3-1.3 s against 1-4 s) and the plans tried before the refinement are the same.
    jobs = _jobs(_distinct(ranked, settings.tol), methods) or later()
    ranked = ranked or [e for e, m in jobs if m is methods[0]]
    for factor in REFINE if refine and not ranked else ():  # no base path: stage 1 again at refined samples
        ranked = _stage1(robot, problem, settings, budget, routes, factor)
        jobs = _jobs(_distinct(ranked, settings.tol), methods)
        if ranked:
            break
    best, found, closest, between = _solve_ranked(robot, problem, jobs, budget, more=later)
    far = best is not None and fallback and best.T > SECOND_OPINION * cert.lower_bound and not budget.spent()
    after = next(i for i, j in enumerate(jobs) if j[0] is found[0] and j[1] is found[1]) + 1 if far else 0
    if far and found[1] is planner.Method.successive:  # its second opinion
        entries = [found[0]] + [e for e, m in jobs[after:] if m is planner.Method.single_shot and e is not found[0]]
        best = _second_opinion(robot, problem, best, entries, budget, SECOND_OPINION * cert.lower_bound)
    elif far:
        # An all-constraint plan (already lifted, _lifted_if_better) far from the bound: the next base paths' plans.
        other, *_ = _solve_ranked(robot, problem, jobs[after:], budget, more=later)
        if other is not None and other.T < best.T:
            best = other
    elif best is None and between and refine:
        best = _refined(robot, problem, between, budget)
    out = best or closest
    timed_out = budget.deadline is not None and budget.spent() and best is None
    if out is None:  # no stage-1 solution (or no time for one)
        out = _no_solve(cert, planner.SolveStatus.time_limit if timed_out else planner.SolveStatus.infeasible)
    out.lower_bound = cert.lower_bound
    if best is None:
        if out.success:  # converged, but failed the dense checks between the samples: not a feasible plan
            out.success, out.status = False, planner.SolveStatus.violation_between_samples
        out.reason = Reason.time_limit if timed_out else Reason.solver_failed
        closest_text = (
            f"the closest plan reached stage {out.stages_completed} of 5"
            if ranked
            else "no base path (stage 1) converged from any seed, so there is no closest plan"
        )
        out.detail = (
            f"the time limit of {time_limit:g} s ran out before a feasible plan"
            if timed_out
            else f"no solver run succeeded although the geometry allows T >= {cert.lower_bound:.2f} s; {closest_text}"
        )
        if timed_out:
            out.status = planner.SolveStatus.time_limit
    out.total_seconds, out.total_cpu_seconds = time.monotonic() - t0, time.thread_time() - c0
    return out
