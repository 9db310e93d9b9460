"""More arm seeds (PickupSettings.arm_seeds > 2) run stages 2-5 from the IK solution's other branches
too: the returned solution is the shortest of the runs and never longer than with fewer seeds, and it
passes the dense checks."""

import math

import pytest

from pickplan.pickup.nlp import cases, planner, solve_problem


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


def test_more_branches_keep_the_shortest(robot):
    problem = cases.make_problem(robot, 1)
    st = dict(samples_per_interval=6, direct_track=False)
    two = planner.plan(robot, problem, planner.PlannerSettings(arm_seeds=2, **st))
    four = planner.plan(robot, problem, planner.PlannerSettings(arm_seeds=4, **st))
    assert two.success and four.success
    assert len(four.arm_seed_T) > len(two.arm_seed_T)  # the branches were run
    finite = [t for t in four.arm_seed_T if not math.isnan(t)]
    assert four.T == pytest.approx(min(finite), rel=1e-12)
    assert four.T == pytest.approx(four.arm_seed_T[four.arm_seed_chosen], rel=1e-12)
    assert four.arm_seed_T[0] == two.arm_seed_T[0]  # the first run is the same (never bounded)
    assert four.T <= two.T * (1 + 1e-9)  # (case 1: both second runs are the same wrist turn)
    checks = solve_problem.dense_checks(problem, four, planner.evaluate(robot, problem, four))
    assert checks and all(checks.values()), checks
