"""Shared pieces of the pick-up-for-any-layout tests (issue 37): fast planner settings and a small
problem (a part beside the straight line, on a pillar) that a test can vary."""

import math

from pickplan.pickup.nlp import planner, problem_file, solve_problem

FAST = planner.PlannerSettings(samples_per_interval=6)


def _spec(**kw):
    base = dict(
        base_start=(0.0, 0.0, 0.0),
        base_goal=(8.0, 0.0, 0.0),
        part_position=(4.0, 1.0, 0.5),
        part_yaw=0.0,
        metamodel="standin",
        uncertainty=problem_file.Uncertainty.medium,
        sigma_r=0.007,
        sigma_phi=math.radians(10),
        gamma=0.96,
        obstacles=(
            problem_file.SphereObstacle((4.0, 1.0, 0.15), 0.15),
            problem_file.SphereObstacle((4.0, 1.0, 0.33), 0.06),
        ),
    )
    base.update(kw)
    return problem_file.PickupProblemSpec(**base)


def _part_on_pillar(part, **kw):
    """_spec with the part at ``part`` (x, y, z) on a pillar of its own, the only obstacle."""
    pillar = problem_file.SphereObstacle((part[0], part[1], 0.15), 0.15)
    return _spec(part_position=part, obstacles=(pillar,), **kw)


def _native(robot, spec):
    return problem_file.native_problem(robot, spec, solve_problem.rho_for_spec(spec))
