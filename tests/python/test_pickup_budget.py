"""The successive refinement's iteration budget (PickupSettings.iteration_budget) and its cap on
warm active-set re-solves (resolve_max_iter): the runs after the first arm seed's stop at the
budget, the first path is never cut, and the single-shot baseline is untouched by either."""
import numpy as np
import pytest

from pickplan.pickup.nlp import cases
from pickplan.pickup.nlp import planner


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


@pytest.fixture(scope="module")
def case1(robot):
    return cases.make_problem(robot, 1)


def test_spent_budget_leaves_the_first_arm_seed_alone(robot, case1):
    """With the budget spent by stage 1, the solve is exactly the single-seed five stages (no
    second arm seed, no direct track); without a budget both run."""
    spent = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, iteration_budget=1))
    alone = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, iteration_budget=0,
                                                               arm_seeds=1, direct_track=False))
    assert spent.success and alone.success
    assert len(spent.arm_seed_T) == 1 and spent.direct is None
    assert np.array_equal(np.asarray(spent.native.x), np.asarray(alone.native.x))
    free = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, iteration_budget=0))
    assert free.success and len(free.arm_seed_T) == 2 and free.direct is not None
    assert free.T <= spent.T + 1e-9  # the extra runs only ever replace it by a shorter solution


def test_budget_caps_the_later_runs(robot, case1):
    """A budget a little above what the first path uses: the direct track (the last run) gets only
    the remainder, so its iterations never take the total past the budget."""
    st = planner.PlannerSettings(samples_per_interval=6, iteration_budget=0, arm_seeds=1)
    free = planner.plan(robot, case1, st)
    first = sum(s.iterations for s in free.stages)
    assert free.direct is not None and free.direct.iterations > 10
    capped = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, iteration_budget=first + 10,
                                                                arm_seeds=1))
    assert capped.direct is not None and capped.direct.iterations <= 10
    assert capped.direct.status in (planner.SolveStatus.max_iterations, planner.SolveStatus.bounded)
    assert capped.T == pytest.approx(free.stages[-1].objective)


def test_single_shot_ignores_the_successive_limits(robot, case1):
    a = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, seed=3), planner.Method.single_shot)
    b = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, seed=3, iteration_budget=1,
                                                           resolve_max_iter=1), planner.Method.single_shot)
    assert a.status == b.status
    assert np.array_equal(np.asarray(a.native.x), np.asarray(b.native.x))


def test_resolve_cap_bounds_each_warm_round(robot, case1):
    """resolve_max_iter = 1: a stage's warm re-solves take at most one iteration each, so its
    iterations exceed those of the same stage's first round (unchanged: same seed and rows) by at
    most rounds - 1."""
    ref = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, arm_seeds=1, direct_track=False,
                                                             active_max_rounds=1))
    one = planner.plan(robot, case1, planner.PlannerSettings(samples_per_interval=6, arm_seeds=1, direct_track=False,
                                                             resolve_max_iter=1))
    # Stage 3 of case 1 needs a second round (the limit rows that join after its first solve).
    s_ref, s_one = ref.stages[2], one.stages[2]  # same seed, same first round
    assert s_one.stage == 3 and s_one.rounds >= 2
    assert s_ref.iterations < s_one.iterations <= s_ref.iterations + (s_one.rounds - 1)
    assert s_one.status == planner.SolveStatus.max_iterations and not one.success


def test_refine_cap_bounds_stages_4_and_5(robot, case1):
    """refine_max_iter caps stage 4 and stage 5 each (all their rounds together); stages 1-3 are
    untouched, and a cap above what they need changes nothing."""
    st = dict(samples_per_interval=6, arm_seeds=1, direct_track=False)
    free = planner.plan(robot, case1, planner.PlannerSettings(**st))
    assert free.success and free.stages[3].iterations > 1
    one = planner.plan(robot, case1, planner.PlannerSettings(refine_max_iter=1, **st))
    assert [s.iterations for s in one.stages[:3]] == [s.iterations for s in free.stages[:3]]
    assert one.stages[3].stage == 4 and one.stages[3].iterations <= 1 and not one.success
    assert one.stages[3].status == planner.SolveStatus.max_iterations
    need = max(s.iterations for s in free.stages[3:])
    roomy = planner.plan(robot, case1, planner.PlannerSettings(refine_max_iter=need, **st))
    assert np.array_equal(np.asarray(roomy.native.x), np.asarray(free.native.x))

