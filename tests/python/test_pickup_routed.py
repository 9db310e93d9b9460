"""Pick-up on the move for any layout (issue 37): the lower bound on T (closed form on a straight line,
never above a solved T), every infeasibility reason on a constructed problem, the time budget, the
order of the plans tried (stage-1 degrees, fallbacks, lifts, second opinions, refined samples), and the
benchmark layouts. The route seeds are tested in test_pickup_route.py."""

import copy
import math
import time
from dataclasses import replace

import numpy as np
import pytest

from pickplan import _core
from pickplan.pickup.nlp import budget, planner, problem_file, random_problems, route, routed, solve_problem
from pickplan.pickup.nlp.feasibility import Reason, base_geometry, certify, lower_bound
from routed_fixtures import FAST, _native, _part_on_pillar, _spec


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


# ---- the lower bound --------------------------------------------------------------------------------
def test_the_bound_equals_the_closed_form_on_a_straight_line(robot):
    # Start, grasp and goal on one line, no obstacle on it: the base drives straight at its limit,
    # through the grasping annulus (its chord is longer than v W), and stops goal_tol short of the goal.
    for v, D in ((2.0, 8.0), (0.5, 6.0), (1.2, 10.0)):
        spec = _spec(
            base_goal=(D, 0.0, 0.0),
            part_position=(D / 2, 0.5, 0.5),
            obstacles=(problem_file.SphereObstacle((D / 2, 0.5, 0.15), 0.15),),
            base_speed_limit=v,
        )
        problem = _native(robot, spec)
        geo = base_geometry(robot, problem, FAST)
        W = geo.window
        assert W * v < 2 * math.sqrt(geo.r_max**2 - 0.5**2)  # the chord holds the window
        closed = (D - spec.goal_tol_pos) / v
        # Any route start -> p -> q -> goal ball is at least D - tol long (triangle inequality), so
        # the grid minimum is >= closed; the bound lowers it by the grid's 4 h / v only.
        slack = 4 * geo.spacing() / v
        assert closed - slack - 1e-9 <= lower_bound(geo) <= closed + 1e-9 and slack < 0.04 * closed


def test_the_bound_is_below_the_T_of_solved_problems(robot):
    specs = [_spec()] + [replace(s, metamodel="standin") for s in random_problems.random_problems(2, 0)]
    for spec in specs:
        problem = _native(robot, spec)
        p = routed.plan_routed(robot, problem, FAST)
        assert p.success and p.reason is Reason.none, (p.status, p.detail)
        assert 0 < p.lower_bound <= p.T, (p.lower_bound, p.T)


# ---- the reasons --------------------------------------------------------------------------------------
def test_each_infeasibility_reason_on_a_constructed_problem(robot):
    cases = {
        # a meta-model whose rho is at most 0.9 at every speed (below)
        Reason.gamma_unattainable: (_spec(), FAST),
        # the grasp point 3 m up: beyond the arm's reach from any base pose
        Reason.out_of_reach: (_spec(part_position=(4.0, 1.0, 3.0), obstacles=()), FAST),
        # a low dome round the part blocks every base position of the grasping annulus
        Reason.horizon_too_short: (_spec(), replace(FAST, t_max=3.0)),
    }
    dome = _spec(obstacles=(problem_file.SphereObstacle((4.0, 1.0, -0.8), 1.2),))
    for reason, (spec, settings) in list(cases.items()) + [(Reason.out_of_reach, (dome, FAST))]:
        problem = _native(robot, spec)
        if reason is Reason.gamma_unattainable:
            problem.rho = _core.RhoPoly(
                np.array([[0.9, 0.8, 0.9], [0.5, 0.6, 0.7], [0.2, 0.3, 0.3]]), (0.05, 1.2), (0.05, 0.15)
            )
        cert = certify(robot, problem, settings)
        assert cert.reason is reason and cert.detail, (reason, cert)
        p = routed.plan_routed(robot, problem, settings)
        assert not p.success and p.reason is reason and p.stages == [] and p.status is planner.SolveStatus.infeasible
    # Verified independently: the dome's blocked radius
    # sqrt((0.3 + 1.2)^2 - 1.0^2) = 1.118 m exceeds the annulus' 0.8 m; the straight line at 2 m/s
    # takes 7.5 s / 2 > 3 s.
    # (A Bernstein surface lies within the hull of its coefficients: at most 0.9 < 0.96.)
    assert math.sqrt(1.5**2 - 1.0**2) > 0.8 and (8.0 - 0.5) / 2.0 > 3.0
    # The solver fails (one Ipopt iteration per run) on a problem the bound calls feasible.
    problem = _native(robot, _spec())
    p = routed.plan_routed(robot, problem, replace(FAST, max_iter=1))
    assert not p.success and p.reason is Reason.solver_failed and "closest plan" in p.detail
    assert math.isfinite(p.lower_bound) and p.stages_completed >= 0
    # No stage-1 run converges in one iteration: the detail says there is no plan at all.
    assert p.stages == [] and "no base path (stage 1) converged" in p.detail


# ---- the time budget -------------------------------------------------------------------------------
def test_the_time_budget(robot):
    problem = _native(robot, _spec())
    full = routed.plan_routed(robot, problem, FAST)
    assert full.success and full.status is planner.SolveStatus.solved
    tiny = routed.plan_routed(robot, problem, FAST, time_limit=1e-3)
    assert tiny.status is planner.SolveStatus.time_limit and not tiny.success and tiny.reason is Reason.time_limit
    # Whatever the budget cuts, a plan returned as a success is a feasible one (dense checks).
    for share in (0.3, 0.6, 0.9):
        p = routed.plan_routed(robot, problem, FAST, time_limit=share * full.total_seconds)
        assert p.status in (planner.SolveStatus.solved, planner.SolveStatus.time_limit)
        if p.success:
            metrics = planner.evaluate(robot, problem, p)
            assert all(solve_problem.dense_checks(problem, p, metrics).values())
        else:
            assert p.reason is Reason.time_limit
    # The budget bounds the wall time: a native run stops before an iteration that would end past
    # the deadline (the allowance is for the scheduler, not for the planner: the route search and
    # the seeds stop at the deadline too).
    for share in (0.3, 0.6):
        limit = share * full.total_seconds
        p = routed.plan_routed(robot, problem, FAST, time_limit=limit)
        assert p.total_seconds <= limit + 0.05, (p.total_seconds, limit)
    # A budget that is not reached changes nothing.
    same = routed.plan_routed(robot, problem, FAST, time_limit=1e4)
    assert same.status is planner.SolveStatus.solved and np.array_equal(same.native.x, full.native.x)
    with pytest.raises(ValueError, match="time_limit"):
        routed.plan_routed(robot, problem, FAST, time_limit=-1.0)


def test_the_budget_keeps_back_the_python_work_between_native_runs():
    """A native run is given the time left less the longest Python stretch seen between a run's return
    and the next run (the plan's dense checks, the next seed), so the same work after the last run
    still ends by the deadline, and less the most a native run overran its own limit."""
    none = budget.Budget(0.0)
    assert none.settings(FAST) is FAST and not none.spent()
    timer = budget.Budget(10.0)
    first = timer.settings(FAST).time_limit
    # Nothing seen yet to keep back but the scheduler's share.
    kept = 10.0 * (1 - budget.SCHEDULER_SHARE)
    assert 0 < budget.SCHEDULER_SHARE < 0.05 and kept - 0.1 < first <= kept and timer.reserve == 0.0
    timer.note(planner.SolveStatus.solved, 0.01)
    time.sleep(0.02)  # the work after the run
    second = timer.settings(FAST).time_limit
    assert timer.reserve >= 0.02 and second <= first - 0.04
    assert not timer.spent() and timer.late == 0.0
    # A native call that returns past the time it was given: later calls are given that much less.
    timer.note(planner.SolveStatus.solved, second + 0.05)
    third = timer.settings(FAST).time_limit
    assert timer.late == pytest.approx(0.05) and third <= second - 0.05
    # A long native call (one that ran into its iteration limit) does not spend what is left: what a
    # call needs at least is about one of its iterations, not the whole of it.
    long_call = budget.Budget(0.3)
    long_call.note(planner.SolveStatus.max_iterations, 0.45, 450)
    assert long_call.quickest == pytest.approx(1e-3) and not long_call.spent()
    long_call.note(planner.SolveStatus.solved, 0.01, 1)
    assert long_call.quickest == pytest.approx(1e-3)
    # The instant the budget is spent, for the route search's clock: what spent() keeps back.
    assert none.spent_at() is None
    assert timer.spent_at() == pytest.approx(timer.deadline - timer.quickest - timer.reserve - timer.late)
    assert timer.spent_at() < timer.deadline - 0.05  # the reserve and the overrun seen above
    ended = budget.Budget(0.5)
    ended.note(planner.SolveStatus.solved, 0.25, 1)  # an iteration of 0.25 s
    assert not ended.spent() and ended.spent_at() > time.monotonic()
    time.sleep(max(0.0, ended.spent_at() - time.monotonic()) + 1e-3)
    assert ended.spent() and ended.left() > 0  # spent before the deadline itself


def test_the_route_search_and_the_seeds_stop_at_the_deadline(robot):
    spec = _spec(
        base_start=(0.0, 0.0, math.pi / 2),
        part_position=(4.0, 3.5, 0.5),
        obstacles=(problem_file.SphereObstacle((4.0, 3.5, 0.15), 0.15),),
    )
    problem = _native(robot, spec)
    geo = base_geometry(robot, problem, FAST)
    assert route.candidate_routes(geo, 3) and route.candidate_routes(geo, 3, deadline=time.monotonic() - 1.0) == []
    labels = [label for label, _ in routed.seeds(robot, problem, FAST, 3, deadline=time.monotonic() - 1.0)]
    assert labels == ["heuristic"]  # the native seed; no route is searched after the deadline
    assert len(routed.seeds(robot, problem, FAST, 3)) > 1


@pytest.mark.parametrize("part", [(4.0, 1.0, 0.5), (-3.0, 1.0, 0.5)])
def test_stage1_starts_from_the_seed_with_the_shortest_T(robot, part):
    """The seeds come shortest T first. Behind the start the heuristic seed's straight path runs past
    the part's side and back, several times a route's T, and comes last."""
    spec = _part_on_pillar(part)
    problem = _native(robot, spec)
    variant = routed._variants(robot, FAST)[0]
    seeds = routed.seeds(robot, problem, variant, 3)
    T = [x[-3] for _, x in seeds]
    assert len(seeds) > 1 and T == sorted(T)
    heuristic = next(x for label, x in seeds if label == "heuristic")
    native = np.array(_core.pickup_heuristic_seed(robot.native, problem, variant.to_native()))
    np.testing.assert_array_equal(heuristic, native)
    if part[0] < 0:  # behind the start
        assert seeds[-1][0] == "heuristic" and T[-1] > 3 * T[0]


def test_single_shot_from_a_given_seed(robot):
    problem = _native(robot, _spec())
    x1 = routed.seeds(robot, problem, FAST)[0][1]
    r1 = planner.solve_stage(robot, problem, x1, 1, FAST)
    assert r1.success
    p = planner.plan(robot, problem, FAST, planner.Method.single_shot, x0=np.asarray(r1.x))
    assert p.success and planner.passes_dense_checks(robot, problem, p)
    # From the stage-1 solution, not from the random seed: the two runs differ.
    q = planner.plan(robot, problem, FAST, planner.Method.single_shot)
    assert not np.array_equal(np.asarray(p.native.x), np.asarray(q.native.x))
    with pytest.raises(ValueError, match="seed"):
        planner.plan(robot, problem, FAST, planner.Method.single_shot, x0=np.asarray(r1.x)[:-1])


def test_the_five_stages_run_on_the_stage_1_base_path_lifted_to_a_higher_degree(robot):
    """A stage-1 solution lifted to LATER_BASE_DEGREE is the same path (numpy's evaluation of both sets of
    monomial coefficients agrees at every normalised time), sampled LATER_SAMPLES times as densely; the
    routed plan's five stages run at that base degree and it passes the dense checks (at FAST's 6 samples
    per interval, unscaled, the degree-12 base slid sideways between them here, and the all-constraint
    fallback at degree 7 was the plan); the caller's degrees are kept."""
    problem = _native(robot, _spec())
    settings = FAST
    variant = routed._variants(robot, settings)[0]
    ((_, x0),) = routed.seeds(robot, problem, variant, routes=0)
    r = planner.solve_stage(robot, problem, x0, 1, variant)
    assert r.success
    lifted, x = routed._raised(variant, np.asarray(r.x), robot.dof)
    L = routed.LATER_BASE_DEGREE
    assert list(lifted.degrees) == [L, L, L] + list(variant.degrees[3:]) and variant.degrees[0] < L
    assert lifted.samples_per_interval == round(routed.LATER_SAMPLES * variant.samples_per_interval) > 6
    s = np.linspace(0.0, 1.0, 101)
    a = b = 0
    for d_old, d_new in zip(variant.degrees, lifted.degrees):
        old, new = np.asarray(r.x)[a : a + d_old + 1], x[b : b + d_new + 1]
        np.testing.assert_allclose(np.polynomial.polynomial.polyval(s, new), np.polynomial.polynomial.polyval(s, old))
        a, b = a + d_old + 1, b + d_new + 1
    np.testing.assert_array_equal(x[b:], np.asarray(r.x)[a:])  # T1 / T, T2 / T, T, S_g, S_c
    p = routed.plan_routed(robot, problem, settings, routes=0)
    assert p.success and list(p.native.degrees)[:3] == [L, L, L] and planner.passes_dense_checks(robot, problem, p)
    kept = routed.plan_routed(robot, problem, replace(settings, degrees=list(variant.degrees)), routes=0)
    assert list(kept.native.degrees) == list(variant.degrees)


def test_stage1_tries_no_further_seed_once_a_base_path_is_near_the_bound(robot, monkeypatch):
    # The part beside the straight line: the heuristic seed's base path is near the bound, so the
    # route seeds' stage 1 (each 0.1-1.6 s of CPU in clutter) would not find a much faster one.
    problem = _native(robot, _spec())
    real_stage = planner.solve_stage
    stage1 = []  # T of each stage-1 run

    def stage(robot_, problem_, x0, k, settings):
        r = real_stage(robot_, problem_, x0, k, settings)
        stage1.append(r.objective if r.success else math.inf)
        return r

    monkeypatch.setattr(planner, "solve_stage", stage)
    p = routed.plan_routed(robot, problem, FAST, routes=3)
    assert p.success and len(stage1) == 1
    assert p.lower_bound <= stage1[0] <= routed.NEAR_BOUND * p.lower_bound  # a base path is never below the bound
    stage1.clear()
    q = routed.plan_routed(robot, problem, FAST, routes=3, near_bound=0.0)  # never near: every seed's stage 1 runs
    routes = len(routed.seeds(robot, problem, replace(FAST, degrees=[7, 7, 7, 5, 5, 5, 3, 3, 3]), 3)) - 1
    assert q.success and routes >= 1 and len(stage1) == 1 + routes
    assert all(t >= q.lower_bound for t in stage1)
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="near_bound"):
            routed.plan_routed(robot, problem, FAST, near_bound=bad)


def test_all_constraints_from_the_base_paths_when_no_five_stage_plan_passes(robot, monkeypatch):
    problem = _native(robot, _spec())
    real, real_stage = planner.plan, planner.solve_stage
    calls, stage1 = [], []  # (method, base degree) of the plans; base degrees of the stage-1 runs

    def five_stages_fail(robot_, problem_, settings, method=planner.Method.successive, x0=None):
        calls.append((planner.Method.parse(method, "method"), settings.degrees[0]))
        p = real(robot_, problem_, settings, method, x0)
        if calls[-1][0] is planner.Method.successive:  # as if it failed: the fallback must take over
            p.success, p.status = False, planner.SolveStatus.infeasible
        return p

    def stage(robot_, problem_, x0, k, settings):
        stage1.append(settings.degrees[0])
        return real_stage(robot_, problem_, x0, k, settings)

    monkeypatch.setattr(planner, "plan", five_stages_fail)
    monkeypatch.setattr(planner, "solve_stage", stage)
    p = routed.plan_routed(robot, problem, FAST, routes=0)  # the heuristic seed's base paths (degree 7, quintic)
    assert p.success and ", direct" in p.seed and p.reason is Reason.none
    assert planner.passes_dense_checks(robot, problem, p) and p.T >= p.lower_bound
    # The first base path's fallback comes before the next base path's five stages; it passes, so
    # the quintic base path (the later degree) is never solved.
    S, D = planner.Method.successive, planner.Method.single_shot
    L = routed.LATER_BASE_DEGREE  # the five stages lift the stage-1 base path to it; the fallback does not,
    # but its converged plan is then solved again from itself lifted (_lifted_if_better)
    assert calls == [(S, L), (D, 7), (D, L)] and stage1 == [7]
    assert list(p.native.degrees)[0] == (L if p.seed.endswith(f"base degree {L}") else 7)
    calls.clear()
    stage1.clear()
    off = routed.plan_routed(robot, problem, FAST, routes=0, fallback=False)
    assert not off.success and off.reason is Reason.solver_failed
    # No fallback: the quintic's stage 1 and five stages only after the degree-7 base path's failed,
    # then degree 12's.
    assert calls[:2] == [(S, L), (S, L)] and stage1 == list(routed.BASE_DEGREES) == [7, 5, 12]
    assert D not in [m for m, _ in calls]
    # An all-constraint plan far from the bound (here any: SECOND_OPINION 0) gets the next base
    # path's plans as its second opinion: the five stages from it (which pass here), the shorter kept.
    plans = []

    def first_five_stages_fail(robot_, problem_, settings, method=planner.Method.successive, x0=None):
        p = real(robot_, problem_, settings, method, x0)
        if not plans:
            p.success, p.status = False, planner.SolveStatus.infeasible
        plans.append((planner.Method.parse(method, "method"), p))
        return p

    monkeypatch.setattr(planner, "plan", first_five_stages_fail)
    monkeypatch.setattr(routed, "SECOND_OPINION", 0.0)
    p = routed.plan_routed(robot, problem, FAST, routes=0)
    # The all-constraint plan lifted to the five stages' base degree first (all constraints from itself),
    # then the next base path's plans (the quintic's, solved only now; its five-stage plan may fail the
    # dense checks and get its own fallback).
    S, D = planner.Method.successive, planner.Method.single_shot
    assert [m for m, _ in plans][:4] == [S, D, D, S]
    assert list(plans[2][1].native.degrees)[:3] == [routed.LATER_BASE_DEGREE] * 3
    passed = [q.T for _, q in plans[1:] if q.success and planner.passes_dense_checks(robot, problem, q)]
    assert p.success and p.T == min(passed) and planner.passes_dense_checks(robot, problem, p)


def test_an_all_constraint_plan_is_solved_again_from_itself_lifted_and_the_shorter_passing_plan_kept(
    robot, monkeypatch
):
    problem = _native(robot, _spec())
    variant = routed._variants(robot, FAST)[0]
    ((_, x0),) = routed.seeds(robot, problem, variant, routes=0)
    r = planner.solve_stage(robot, problem, x0, 1, variant)
    assert r.success
    x = np.asarray(r.x)
    entry = (r.objective, "heuristic", variant, x, routed._raised(variant, x, robot.dof))
    unlimited = budget.Budget(0.0)
    p, ok = routed._solve_one(robot, problem, entry, unlimited, planner.Method.single_shot)
    assert p.success and list(p.native.degrees)[:3] == [7, 7, 7]
    runs, real = [], routed._run

    def run(robot_, problem_, settings, method, x0_, label, budget_):
        out = real(robot_, problem_, settings, method, x0_, label, budget_)
        runs.append((settings.degrees[0], settings.samples_per_interval, np.asarray(x0_), out))
        # Here the all-constraint NLP is a method of its own: a stage's iterations, not the hedge's cap.
        assert settings.max_iter == FAST.max_iter > FAST.direct_max_iter
        return out

    monkeypatch.setattr(routed, "_run", run)
    routed._solve_one(robot, problem, entry, unlimited, planner.Method.single_shot)
    runs.clear()
    L, m = routed.LATER_BASE_DEGREE, FAST.samples_per_interval
    q, q_ok = routed._lifted_if_better(robot, problem, p, ok, entry, 1.0, unlimited)
    # One all-constraint run at degree L from the same path (its coefficients padded), at the lifted samples.
    ((deg, samples, start, lifted),) = runs
    assert (deg, samples) == (L, round(m * routed.LATER_SAMPLES))
    assert np.array_equal(start, routed._raised(variant, np.asarray(p.native.x), robot.dof)[1])
    assert q_ok and planner.passes_dense_checks(robot, problem, q)
    assert q is (lifted[0] if lifted[1] and (not ok or lifted[0].T < p.T) else p) and q.T <= (p.T if ok else math.inf)
    # A plan that failed the dense checks (as if it had slid sideways between the samples): the lift
    # also refines the samples, and its plan is kept when it passes.
    runs.clear()
    q, q_ok = routed._lifted_if_better(robot, problem, p, False, entry, 1.0, unlimited)
    assert runs[0][1] == round(round(m * routed.REFINE[0]) * routed.LATER_SAMPLES)
    assert q_ok == runs[0][3][1] and (q is runs[0][3][0] if q_ok else q is p)
    # Nothing to lift: the caller's degrees, or a plan that did not converge.
    runs.clear()
    assert routed._lifted_if_better(robot, problem, p, ok, entry[:4] + (None,), 1.0, unlimited) == (p, ok)
    failed = copy.copy(p)
    failed.success, failed.status = False, planner.SolveStatus.max_iterations
    assert routed._lifted_if_better(robot, problem, failed, False, entry, 1.0, unlimited) == (failed, False)
    assert not runs


def test_a_five_stage_plan_far_from_its_bound_gets_the_all_constraint_plans_as_a_second_opinion(robot, monkeypatch):
    problem = _native(robot, _spec())
    real, plans = planner.plan, []

    def record(robot_, problem_, settings, method=planner.Method.successive, x0=None):
        p = real(robot_, problem_, settings, method, x0)
        plans.append((planner.Method.parse(method, "method"), settings.degrees[0], p))
        return p

    monkeypatch.setattr(planner, "plan", record)
    monkeypatch.setattr(routed, "SECOND_OPINION", 0.0)  # every plan is far from its bound
    p = routed.plan_routed(robot, problem, FAST, routes=0)
    # The five stages pass first; then all constraints from the same stage-1 solution, and that plan
    # lifted to the five stages' base degree; the shortest passing plan is kept.
    S, D, L = planner.Method.successive, planner.Method.single_shot, routed.LATER_BASE_DEGREE
    assert [(m, d) for m, d, _ in plans][:3] == [(S, L), (D, 7), (D, L)]
    passed = [q.T for _, _, q in plans if q.success and planner.passes_dense_checks(robot, problem, q)]
    assert plans[0][2].T in passed and p.success and p.T == min(passed)


def test_plans_that_fail_between_the_samples_are_solved_again_at_refined_samples(robot, monkeypatch):
    problem = _native(robot, _spec())
    real = planner.plan
    calls = []

    def coarse_fails(robot_, problem_, settings, method=planner.Method.successive, x0=None):
        p = real(robot_, problem_, settings, method, x0)
        rows = p.stages[-1].rows if p.stages else 0
        calls.append((planner.Method.parse(method, "method"), settings.samples_per_interval, x0.tobytes(), p.T, rows))
        if settings.samples_per_interval == FAST.samples_per_interval:  # as if it held its rows at the samples only
            p.success, p.status = False, planner.SolveStatus.violation_between_samples
        return p

    monkeypatch.setattr(planner, "plan", coarse_fails)
    monkeypatch.setattr(routed, "LATER_SAMPLES", 1.0)  # the five stages at the stage-1 samples, as the fallback
    p = routed.plan_routed(robot, problem, FAST, routes=0)
    fine = round(FAST.samples_per_interval * routed.REFINE[0])
    assert p.success and p.reason is Reason.none and p.seed.endswith(f", {fine} samples per interval")
    assert planner.passes_dense_checks(robot, problem, p) and p.T >= p.lower_bound
    # From each base path the five stages, then all constraints at once; then, at the refined
    # samples, the same method from the same base path as the shortest of those plans, first.
    coarse = [c for c in calls if c[1] == FAST.samples_per_interval]
    assert len(coarse) >= 4 and [c[0] for c in coarse] == [planner.Method.successive, planner.Method.single_shot] * (
        len(coarse) // 2
    )
    shortest = min(coarse, key=lambda c: c[3])
    assert calls[len(coarse)][:3] == (shortest[0], fine, shortest[2])
    # More samples, more rows: from the same base path, the refined NLP holds its rows at more instants.
    assert p.stages[-1].rows > shortest[4]


def test_stage1_solutions_that_repeat_an_earlier_one_are_dropped():
    a = np.array([1.0, -2000.0, 3.5])
    ranked = [(1.0, "a", None, a), (1.0, "b", None, a + 1e-3), (2.0, "c", None, a * 1.01), (3.0, "d", None, a[:2])]
    # b is a within 1e-6 of its scale (2000): a repeat; c differs by 20 in one variable, d in its size.
    assert [e[1] for e in routed._distinct(ranked, 1e-6)] == ["a", "c", "d"]
    assert [e[1] for e in routed._distinct(ranked, 1e-8)] == ["a", "b", "c", "d"]


def test_the_all_constraint_plan_runs_first_from_a_base_path_that_reverses():
    variant = replace(FAST, degrees=[2, 2, 2, 1])
    tail = np.zeros(2 + 5)  # the arm joint's coefficients, then T1 / T, T2 / T, T, S_g, S_c

    def entry(x_coeffs, label):
        x = np.concatenate([x_coeffs, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], tail])
        return (1.0, label, variant, x, None)

    ahead, back = entry([0.0, 4.0, 0.0], "ahead"), entry([0.0, 2.0, -2.0], "back")  # x' = 4; x' = 2 - 4 s
    S, D = planner.Method.successive, planner.Method.single_shot
    jobs = routed._jobs([ahead, back], (S, D))
    assert [(e[1], m) for e, m in jobs] == [("ahead", S), ("ahead", D), ("back", D), ("back", S)]
    # Without the fallback there is nothing to reorder.
    assert [(e[1], m) for e, m in routed._jobs([ahead, back], (S,))] == [("ahead", S), ("back", S)]


# ---- the layouts --------------------------------------------------------------------------------------
@pytest.mark.parametrize("layout", list(random_problems.Layout))
def test_layouts_draw_seeded_problems_of_their_kind(layout):
    ws = random_problems.Workspace(layout=layout, metamodel="standin")
    a = random_problems.random_problems(6, 1, ws)
    assert a == random_problems.random_problems(6, 1, ws)
    for s in a:
        start, goal, part = np.array(s.base_start[:2]), np.array(s.base_goal[:2]), np.array(s.part_position[:2])
        line = (goal - start) / np.linalg.norm(goal - start)
        along, across = line @ (part - start), line[0] * (part - start)[1] - line[1] * (part - start)[0]
        if layout is random_problems.Layout.side:
            assert 2.0 - 1e-9 <= abs(across) <= 5.0 + 1e-9
        if layout is random_problems.Layout.behind:
            assert along < -1.9
        if layout is random_problems.Layout.cluttered:
            assert 3 <= len(s.obstacles) - 2 <= 6
    if layout is random_problems.Layout.paper:  # the first release's problems, unchanged
        assert a == random_problems.random_problems(6, 1, random_problems.Workspace(metamodel="standin"))
