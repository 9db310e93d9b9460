"""Pick-up on the move NLP through the Python layer: a case solves and its trajectory is checked by
independent dense re-sampling (numpy polynomials + the robot's FK / Jacobian); bad input."""

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from pickplan.pickup.nlp import cases, problem_file, random_problems, routed, solve_problem
from pickplan.pickup.nlp import planner

FAST = planner.PlannerSettings(samples_per_interval=6)


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


@pytest.fixture(scope="module")
def solved(robot):
    problem = cases.make_problem(robot, 4)
    return problem, planner.plan(robot, problem, FAST)


def resample(plan_dict, n):
    """q, q' from the stored normalised-time coefficients with numpy (independent of the native eval)."""
    T, x, deg = plan_dict["T"], np.asarray(plan_dict["x"]), plan_dict["degrees"]
    t = np.linspace(0.0, T, n)
    q, qd, off = np.zeros((n, len(deg))), np.zeros((n, len(deg))), 0
    P = np.polynomial.polynomial
    for i, d in enumerate(deg):
        a = x[off : off + d + 1]
        q[:, i], qd[:, i] = P.polyval(t / T, a), P.polyval(t / T, P.polyder(a)) / T
        off += d + 1
    return t, q, qd


def test_case_solves_and_dense_resampling_checks(robot, solved):
    problem, p = solved
    assert p.success, p.status
    assert p.stages_completed == 5 and [s.stage for s in p.stages] == [1, 2, 3, 4, 5]
    assert 0 <= p.T1 <= p.T2 <= p.T
    d = p.to_dict()
    # Pose at T2 by FK of the independently evaluated polynomials.
    t2 = np.array([p.T2])
    q2 = resample({**d, "T": p.T}, 2)[1]  # endpoints only: check consistency of the evaluator
    assert np.allclose(q2[0], p.sample([0.0])[0][0], atol=1e-12)
    q_at_t2 = p.sample(t2)[0][0]
    T_tool = robot.link_pose(q_at_t2, "tool")
    G = np.asarray(problem.grasp_pose)
    assert np.linalg.norm(T_tool[:3, 3] - G[:3, 3]) < 1e-4
    cosang = (np.trace(G[:3, :3].T @ T_tool[:3, :3]) - 1) / 2
    assert math.acos(min(1.0, cosang)) < 1e-3
    t, q, qd = resample(d, 3001)
    # Non-holonomic error: lateral speed stays at the tolerance's scale (heading error ~ tol).
    lateral = np.abs(qd[:, 0] * np.sin(q[:, 2]) - qd[:, 1] * np.cos(q[:, 2]))
    drift = float(np.sum(0.5 * (lateral[1:] + lateral[:-1]) * np.diff(t)))
    assert drift < 0.2, drift
    assert np.mean(lateral) < 0.02
    # Limits: base speed, arm joint rates (sampled constraints, checked densely with slack).
    assert np.max(np.hypot(qd[:, 0], qd[:, 1])) <= problem.base_speed_limit * 1.05
    assert np.max(np.abs(qd[:, 3:])) <= np.max(problem.arm_rate_limits) * 1.1
    # Position limits are enforced at the samples, tightened by joint_limit_margin (0.05 rad); between
    # samples (about 1 s apart at m = 6) a polynomial may overshoot the sampled bound by a little.
    lo, hi = robot.lower_limits[3:], robot.upper_limits[3:]
    overshoot = max(np.max(lo - q[:, 3:]), np.max(q[:, 3:] - hi))
    assert overshoot < 0.03, overshoot
    # Gripper moves at S_g along n_g during grasping (Jacobian constraint), rho >= gamma.
    tool = robot.link_index("tool")
    mask = (t >= p.T1) & (t <= p.T2)
    v = np.array([robot.jacobian(q[k], tool)[:3] @ qd[k] for k in np.flatnonzero(mask)])
    assert np.max(np.linalg.norm(v - p.S_g * np.asarray(problem.approach_dir), axis=1)) < 0.05
    assert problem.rho.value(p.S_g, p.S_c) >= problem.gamma - 1e-6
    assert abs((p.T2 - p.T1) * p.S_c - problem.stroke) < 1e-6
    m = planner.evaluate(robot, problem, p)
    assert m.pose_error_position < 1e-4 and abs(m.nonholonomic_drift - drift) < 0.01


def test_plan_dict_round_trip(tmp_path, solved):
    _, p = solved
    planner.save_plan(p.to_dict(), tmp_path / "plan")
    d = json.loads((tmp_path / "plan.json").read_text())
    z = np.load(tmp_path / "plan.npz")
    assert d["status"] == "solved" and z["q"].shape == (201, 9)
    # The direct track's record: an all-constraint solve (stage 0); when chosen, its T is returned.
    assert d["direct"]["stage"] == 0 and isinstance(d["direct_chosen"], bool)
    assert d["T"] == pytest.approx(d["direct"]["objective"] if d["direct_chosen"] else d["stages"][-1]["objective"])
    # The arm seeds of stages 2-5: the final T of each run (None: failed or stopped by the bound).
    assert 1 <= len(d["arm_seed_T"]) <= 2 and 0 <= d["arm_seed_chosen"] < len(d["arm_seed_T"])
    assert d["arm_seed_T"][d["arm_seed_chosen"]] == pytest.approx(d["stages"][-1]["objective"])


def test_direct_track_can_be_switched_off(robot):
    problem = cases.make_problem(robot, 1)
    p = planner.plan(robot, problem, planner.PlannerSettings(samples_per_interval=6, direct_track=False))
    assert p.success and p.direct is None and not p.direct_chosen
    assert p.T == pytest.approx(p.stages[-1].objective)


def test_goal_heading_is_an_angle(robot):
    """The goal's heading and the same heading a turn later are one pose: the same plan. A base path
    that loops round once (a route behind the start) ends a turn past the goal's number; held to the
    number itself, the base would have to spin back a full turn at the goal."""
    plans = []
    for turns in (0, 1, -1):
        problem = cases.make_problem(robot, 1)
        problem.goal = np.asarray(problem.goal) + [0.0, 0.0, 2 * math.pi * turns]
        plans.append(planner.plan(robot, problem, planner.PlannerSettings(samples_per_interval=6, direct_track=False)))
    assert all(p.success for p in plans), [p.status for p in plans]
    assert [p.T for p in plans[1:]] == pytest.approx([plans[0].T] * 2, rel=1e-6)


def test_stage2_keeps_the_heading_of_a_base_path_driven_backwards(robot):
    """Behind the start the base path drives backwards before it turns. Where the stage-2 seed bends
    it so that the arm reaches the part, the bent path keeps the backward legs' heading: the tangent
    alone turned them round by pi, and stage 2 then ran to its 400-iteration cap on each of these
    problems (it converges in 20-50 iterations now)."""
    workspace = random_problems.Workspace(layout=random_problems.Layout.behind)
    specs = [replace(s, metamodel="standin") for s in random_problems.random_problems(43, 0, workspace)]
    for i in (4, 15, 42):
        problem = problem_file.native_problem(robot, specs[i], solve_problem.rho_for_spec(specs[i], progress=False))
        settings = routed._variants(robot, planner.PlannerSettings(seed=0))[0]
        x0 = routed.seeds(robot, problem, settings)[0][1]
        stage1 = planner.solve_stage(robot, problem, x0, 1, settings)
        assert stage1.success, (i, stage1.status)
        later, x1 = routed._raised(settings, np.asarray(stage1.x), robot.dof)
        p = planner.plan(robot, problem, replace(later, direct_track=False), planner.Method.successive, x0=x1)
        stage2 = next(s for s in p.stages if s.stage == 2)
        assert stage2.status is planner.SolveStatus.solved and stage2.iterations < 100, (i, stage2)


def test_single_arm_seed(robot):
    problem = cases.make_problem(robot, 1)
    p = planner.plan(robot, problem, planner.PlannerSettings(samples_per_interval=6, direct_track=False, arm_seeds=1))
    assert p.success and len(p.arm_seed_T) == 1 and p.arm_seed_chosen == 0
    assert p.T == pytest.approx(p.arm_seed_T[0])


def test_stomp_keeps_interval_ends(robot, solved):
    problem, p = solved
    tails = planner.refine_tails(robot, problem, p, n=20, iterations=10)
    for name, (t, Q, info) in tails.items():
        q0, _, _ = p.sample(t)
        assert np.allclose(Q[:2], q0[:2]) and np.allclose(Q[-2:], q0[-2:])  # ends and end velocities held
        assert np.allclose(Q[:, :3], q0[:, :3])  # base untouched
        assert info.final_cost <= info.initial_cost + 1e-9


def test_unreachable_part_is_infeasible_status(robot):
    problem = cases.make_problem(robot, 1, part_z=3.5, obstacles=False)
    p = planner.plan(robot, problem, FAST)
    assert not p.success
    assert p.status == "infeasible"
    assert p.stages_completed == 1  # the last good stage is returned


def test_inconsistent_time_ordering_raises(robot):
    problem = cases.make_problem(robot, 1)
    with pytest.raises(ValueError, match="time ordering"):
        planner.seed_from_times(robot, problem, T=10.0, T1=6.0, T2=5.0)
    x = planner.seed_from_times(robot, problem, T=10.0, T1=4.0, T2=4.6)
    x[-4] = 0.3  # T2 / T below T1 / T
    with pytest.raises(ValueError, match="time ordering"):
        planner.solve_stage(robot, problem, x, 1, FAST)


def test_missing_metamodel_file_raises(robot, tmp_path):
    with pytest.raises(FileNotFoundError, match="meta-model file not found"):
        cases.make_problem(robot, 1, metamodel=str(tmp_path / "nope.json"))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match="not a pickplan meta-model"):
        planner.load_rho(bad, 0.007, math.radians(10))


def test_metamodel_file_surface_is_used(robot, tmp_path):
    # A RhoSurface-format level written by hand: the planner must read exactly these coefficients.
    coeffs = [[0.99, 0.995], [0.9, 0.95], [0.5, 0.6]]
    f = tmp_path / "mm.json"
    f.write_text(
        json.dumps(
            {
                "format": planner.METAMODEL_FORMAT,
                "levels": [
                    {
                        "name": "medium",
                        "sigma_r": 0.007,
                        "sigma_phi": math.radians(10),
                        "surface": {"coeffs": coeffs, "sg_range": [0.1, 1.0], "sc_range": [0.05, 0.15]},
                    }
                ],
            }
        )
    )
    rho = planner.load_rho(f, 0.007, math.radians(10))
    assert np.allclose(rho.coeffs, coeffs) and rho.sg_range == (0.1, 1.0)
    assert rho.value(0.1, 0.05) == pytest.approx(0.99)
    assert rho.value(1.0, 0.15) == pytest.approx(0.6)


def test_bad_method_and_shapes(robot):
    problem = cases.make_problem(robot, 1)
    with pytest.raises(ValueError, match="method"):
        planner.plan(robot, problem, FAST, method="magic")
    problem.arm_start = np.zeros(5)
    with pytest.raises(ValueError, match="arm_start: expected 6"):
        planner.plan(robot, problem, FAST)
    with pytest.raises(ValueError, match="case_id"):
        cases.make_problem(robot, 7)
