"""Pick-up problem files (issue 23): the format's round trip and every error at the door, the six
shipped cases equal to the native reference definitions, a random problem solved and checked by
independent dense re-sampling, and `pickplan pickup plan / problems` end to end."""

import copy
import json
import math
import os
from dataclasses import replace

import numpy as np
import pytest

from pickplan import _core
from pickplan.cli.main import main as cli_main
from pickplan.core.errors import InputError
from pickplan.pickup.nlp import cases, planner, problem_file, random_problems, solve_problem

FAST = planner.PlannerSettings(samples_per_interval=6)
CASE = json.load(open(cases.case_path(1)))


@pytest.fixture(scope="module")
def robot():
    return planner.mobile_ur5()


def write(tmp_path, d, name="p.json"):
    path = tmp_path / name
    path.write_text(json.dumps(d) if not isinstance(d, str) else d)
    return str(path)


# ---- the format --------------------------------------------------------------------------------
def test_round_trip_of_the_cases_and_of_random_problems(tmp_path):
    specs = [problem_file.load_problem(cases.case_path(c)) for c in range(1, 7)]
    specs += random_problems.random_problems(5, 3)
    specs.append(
        replace(
            specs[0],
            uncertainty=problem_file.Uncertainty.custom,
            sigma_r=0.004,
            sigma_phi=0.1,
            obstacles=(problem_file.BoxObstacle((4.0, 1.0, 0.3), (0.4, 1.2, 0.6), 0.3),),
        )
    )
    for i, spec in enumerate(specs):
        path = tmp_path / f"p{i}.json"
        problem_file.dump_problem(spec, path)
        back = problem_file.load_problem(path)
        assert back == spec
        problem_file.dump_problem(back, tmp_path / "again.json")
        assert json.loads((tmp_path / "again.json").read_text()) == json.loads(path.read_text())


def _set(d, dotted, value):
    keys = dotted.split(".")
    for k in keys[:-1]:
        d = d[int(k)] if isinstance(d, list) else d[k]
    if value is KeyError:
        del d[keys[-1]]
    elif isinstance(d, list):
        d[int(keys[-1])] = value
    else:
        d[keys[-1]] = value


BAD = [  # (key to change, new value or KeyError = remove, the field the error must name, words in it)
    ("base_start", KeyError, "base_start", "missing"),
    ("base_goal", KeyError, "base_goal", "missing"),
    ("part", KeyError, "part", "missing"),
    ("gamma", KeyError, "gamma", "missing"),
    ("obstacles", KeyError, "obstacles", "missing"),
    ("part.position", KeyError, "part.position", "missing"),
    ("part.yaw", KeyError, "part.yaw", "missing"),
    ("part.metamodel", KeyError, "part.metamodel", "missing"),
    ("part.uncertainty", KeyError, "part.uncertainty", "missing"),
    ("colour", "red", "colour", "unknown key"),
    ("part.colour", 1, "part.colour", "unknown key"),
    ("base_start", [0, 0], "base_start", "list of 3 numbers"),
    ("base_goal", "8,0,0", "base_goal", "list of 3 numbers"),
    ("base_start.1", float("nan"), "base_start[1]", "finite"),
    ("base_goal.0", True, "base_goal[0]", "expected a number"),
    ("part.position.2", None, "part.position[2]", "expected a number"),
    ("part.yaw", float("inf"), "part.yaw", "finite"),
    ("part.grasp", "diagonal", "part.grasp", "'top' or 'side'"),
    ("part.metamodel", "", "part.metamodel", "non-empty string"),
    ("part.uncertainty", "extreme", "part.uncertainty", "'low', 'medium', 'high'"),
    ("part.uncertainty", {"sigma_r": 0.01}, "part.uncertainty.sigma_phi", "missing"),
    ("part.uncertainty", {"sigma_r": -0.01, "sigma_phi": 0.1}, "part.uncertainty.sigma_r", "positive"),
    ("gamma", 1.5, "gamma", "[-inf, 1.0]"),
    ("gamma", 0, "gamma", "positive"),
    ("obstacles", {"sphere": [1, 2, 3, 4]}, "obstacles", "expected a list"),
    ("obstacles.0", {"cone": [1, 2]}, "obstacles[0].cone", "unknown key"),
    ("obstacles.0", {"sphere": [1, 2, 3, 0.1], "box": {}}, "obstacles[0]", "exactly one"),
    ("obstacles.0", {"sphere": [1, 2, 3, -0.1]}, "obstacles[0].sphere[3]", "positive"),
    ("obstacles.1", {"sphere": [1, 2, 3]}, "obstacles[1].sphere", "list of 4"),
    ("obstacles.2", {"box": {"center": [1, 2, 0], "size": [1, 0, 1]}}, "obstacles[2].box.size[1]", "positive"),
    ("obstacles.2", {"box": {"size": [1, 1, 1]}}, "obstacles[2].box.center", "missing"),
    ("arm_start", [0, 0, 0], "arm_start", "list of 6"),
    ("goal_tolerance.position", -1, "goal_tolerance.position", "positive"),
    ("goal_tolerance.turn", 1, "goal_tolerance.turn", "unknown key"),
    ("limits.base_speed", 0, "limits.base_speed", "positive"),
    ("limits.arm_rates", [1, 1, 1, 1, 1, float("inf")], "limits.arm_rates[5]", "finite"),
    ("grasp_area", {"r_min": 0.9, "r_max": 0.5}, "grasp_area", "r_min < r_max"),
    ("format", "pickplan.scene", "format", "expected 'pickplan.pickup_problem'"),
    ("version", 2, "version", "expected 1"),
]


@pytest.mark.parametrize("key,value,field,words", BAD, ids=[f"{b[0]}-{i}" for i, b in enumerate(BAD)])
def test_every_wrong_or_missing_key_is_named(tmp_path, key, value, field, words):
    d = copy.deepcopy(CASE)
    _set(d, key, value)
    path = write(tmp_path, d)
    with pytest.raises(InputError) as err:
        problem_file.load_problem(path)
    assert err.value.path == path and err.value.field == field, str(err.value)
    assert words in str(err.value)


def test_files_that_are_not_problems(tmp_path, robot):
    with pytest.raises(InputError, match="malformed JSON"):
        problem_file.load_problem(write(tmp_path, '{"base_start": [0, 0,'))
    with pytest.raises(InputError, match=r"\(top level\): expected an object"):
        problem_file.load_problem(write(tmp_path, [1, 2]))
    with pytest.raises(FileNotFoundError):
        problem_file.load_problem(tmp_path / "missing.json")
    # An arm start outside the robot's limits: named, with the file.
    d = copy.deepcopy(CASE)
    d["arm_start"][2] = 3.5
    spec = problem_file.load_problem(write(tmp_path, d))
    with pytest.raises(InputError, match=r"p.json: arm_start\[2\]: 3.5 outside the joint's limits"):
        problem_file.native_problem(robot, spec, planner.synthetic_rho(0.007, 0.17))
    # A meta-model path is resolved from the problem's folder and must exist.
    d = copy.deepcopy(CASE)
    d["part"]["metamodel"] = "models/none.json"
    spec = problem_file.load_problem(write(tmp_path, d))
    assert spec.metamodel_path() == os.path.join(str(tmp_path), "models", "none.json")
    with pytest.raises(FileNotFoundError, match="none.json"):
        solve_problem.rho_for_spec(spec)


def test_box_obstacles_are_covered_by_their_spheres():
    box = problem_file.BoxObstacle((1.0, -2.0, 0.4), (0.3, 1.1, 0.8), 0.7)
    spheres = box.spheres()
    rng = np.random.default_rng(0)
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    local = (rng.random((4000, 3)) - 0.5) * np.asarray(box.size)
    local[:8] = 0.5 * np.asarray(box.size) * np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1).T  # corners
    points = np.asarray(box.center) + local @ R.T
    centers = np.array([p for p, _ in spheres])
    radii = np.array([r for _, r in spheres])
    d = np.linalg.norm(points[:, None, :] - centers[None], axis=2) - radii[None]
    assert (d.min(axis=1) <= 1e-12).all()
    assert max(radii) < 0.5 * np.linalg.norm(box.size)  # a grid, not one huge sphere
    wall = problem_file.BoxObstacle((0.0, 0.0, 0.5), (20.0, 0.1, 1.0)).spheres()
    assert len(wall) <= problem_file.MAX_BOX_SPHERES and max(r for _, r in wall) < 0.5


# ---- the cases: files equal to the native reference ----------------------------------------------
FIELDS = [
    "start",
    "arm_start",
    "goal",
    "goal_tol_pos",
    "goal_tol_yaw",
    "grasp_pose",
    "approach_dir",
    "part_xy",
    "grasp_area_rmin",
    "grasp_area_rmax",
    "gamma",
    "stroke",
    "vary_sc",
    "sc_fixed",
    "base_speed_limit",
    "base_yaw_rate_limit",
    "arm_rate_limits",
    "tool_link",
]


@pytest.mark.parametrize("case_id", range(1, 7))
def test_case_files_equal_the_native_cases(robot, case_id):
    for kw in ({}, {"sigma": "low", "gamma": 0.98, "arm_rate": 3 * math.pi}, {"obstacles": False, "part_z": 0.6}):
        mine = cases.make_problem(robot, case_id, **kw)
        sigma = kw.pop("sigma", "medium")
        ref = _core.pickup_paper_case(robot.native, case_id, cases.rho_for(sigma), **kw)
        for f in FIELDS:
            assert np.array_equal(np.asarray(getattr(mine, f)), np.asarray(getattr(ref, f))), f
        assert len(mine.obstacles) == len(ref.obstacles) and len(mine.body_spheres) == len(ref.body_spheres)
        for (a, r), (b, s) in zip(mine.obstacles, ref.obstacles):
            assert np.array_equal(a, b) and r == s
        for (la, a, r), (lb, b, s) in zip(mine.body_spheres, ref.body_spheres):
            assert la == lb and np.array_equal(a, b) and r == s
        assert np.array_equal(mine.rho.coeffs, ref.rho.coeffs)


def test_a_case_from_its_file_solves_exactly_as_the_native_case(robot):
    mine = planner.plan(robot, cases.make_problem(robot, 4), FAST)
    ref = planner.plan(robot, _core.pickup_paper_case(robot.native, 4, cases.rho_for("medium")), FAST)
    assert mine.success and mine.status is planner.SolveStatus.solved
    assert np.array_equal(mine.native.x, ref.native.x) and mine.T == ref.T


def test_the_case_files_ship_inside_the_package():
    import pickplan

    assert cases.CASES_DIR == os.path.join(os.path.dirname(pickplan.__file__), "pickup", "problems")
    assert sorted(os.listdir(cases.CASES_DIR)) == [f"case{c}.json" for c in range(1, 7)]


# ---- a random problem, solved and checked densely -------------------------------------------------
def _spheres_world(robot, q, problem):
    out = []
    for link, c, r in problem.body_spheres:
        T = robot.link_pose(q, link)
        out.append((T[:3, :3] @ np.asarray(c) + T[:3, 3], r))
    return out


def test_a_random_problem_is_solved_and_passes_independent_dense_checks(robot):
    spec = replace(random_problems.random_problems(3, 0)[2], metamodel="standin")
    sol = solve_problem.solve(robot, spec, solve_problem.rho_for_spec(spec), FAST)
    p, problem = sol.plan, sol.problem
    assert p.success and sol.passed, (p.status, sol.checks)
    # Independent of the native metrics: numpy polynomials, the robot's FK, exact sphere distances.
    d = p.to_dict()
    T, x, deg = p.T, np.asarray(d["x"]), d["degrees"]
    t = np.linspace(0.0, T, 1501)
    q, qd, off = np.zeros((len(t), 9)), np.zeros((len(t), 9)), 0
    P = np.polynomial.polynomial
    for i, k in enumerate(deg):
        a = x[off : off + k + 1]
        q[:, i], qd[:, i] = P.polyval(t / T, a), P.polyval(t / T, P.polyder(a)) / T
        off += k + 1
    q2 = np.array([P.polyval(p.T2 / T, x[o : o + k + 1]) for o, k in zip(np.cumsum([0] + [k + 1 for k in deg]), deg)])
    tool = robot.link_pose(q2, "tool")
    G = np.asarray(problem.grasp_pose)
    assert np.linalg.norm(tool[:3, 3] - G[:3, 3]) < 1e-3
    assert math.acos(min(1.0, (np.trace(G[:3, :3].T @ tool[:3, :3]) - 1) / 2)) < 1e-2
    lateral = np.abs(qd[:, 0] * np.sin(q[:, 2]) - qd[:, 1] * np.cos(q[:, 2]))
    assert np.mean(lateral) < 0.02 and np.trapezoid(lateral, t) < 0.2
    clearance = min(
        np.linalg.norm(c - o) - r - ro
        for k in range(0, len(t), 3)
        for c, r in _spheres_world(robot, q[k], problem)
        for o, ro in problem.obstacles
    )
    assert clearance >= 0.0, clearance
    assert np.hypot(q[-1, 0] - spec.base_goal[0], q[-1, 1] - spec.base_goal[1]) <= spec.goal_tol_pos + 1e-6
    assert problem.rho.value(p.S_g, p.S_c) >= spec.gamma - 1e-6


def test_random_problems_are_seeded_and_pass_their_cheap_checks():
    a, b = random_problems.random_problems(8, 5), random_problems.random_problems(8, 5)
    assert a == b and a != random_problems.random_problems(8, 6)
    ws = random_problems.Workspace()
    for s in a:
        assert ws.part_x[0] <= s.part_position[0] <= ws.part_x[1] and ws.part_z[0] <= s.part_position[2] <= ws.part_z[1]
        for o in s.obstacles[2:]:  # pillars keep clear of the start, the goal and the grasping area
            for xy in (s.base_start[:2], s.base_goal[:2]):
                assert math.hypot(o.center[0] - xy[0], o.center[1] - xy[1]) > o.radius + random_problems.BASE_RADIUS
            assert math.hypot(o.center[0] - s.part_position[0], o.center[1] - s.part_position[1]) > 0.8 + o.radius


# ---- the command line ---------------------------------------------------------------------------------
def test_pickup_plan_and_problems_commands(tmp_path, capsys):
    out = tmp_path / "problems"
    assert cli_main(["pickup", "problems", "--n", "3", "--seed", "0", "--out", str(out), "--metamodel", "standin"]) == 0
    first = (out / "problem_0002.json").read_text()
    assert cli_main(["pickup", "problems", "--n", "3", "--seed", "0", "--out", str(out), "--metamodel", "standin"]) == 0
    assert (out / "problem_0002.json").read_text() == first
    plan = tmp_path / "plan"
    assert cli_main(["pickup", "plan", "--problem", str(out / "problem_0002.json"), "--out", str(plan)]) == 0
    printed = capsys.readouterr().out
    assert f"pickplan pickup replay {plan / 'trajectory.json'}" in printed
    traj = json.loads((plan / "trajectory.json").read_text())
    metrics = json.loads((plan / "metrics.json").read_text())
    assert metrics["status"] == "solved" and metrics["best_stage"] == 5 and metrics["passed_dense_checks"]
    assert len(traj["t"]) == len(traj["base"]) == len(traj["arm"]) and len(traj["arm"][0]) == 6
    assert traj["t"][-1] == pytest.approx(metrics["T"]) and (plan / "speeds.png").stat().st_size > 1000
    # The replay reads the problem back from the trajectory and agrees with the plan at T2.
    assert cli_main(["pickup", "replay", str(plan / "trajectory.json")]) == 0
    assert "tool error at T2" in capsys.readouterr().out


def test_pickup_plan_without_a_solution_reports_status_and_stage(tmp_path, capsys):
    d = copy.deepcopy(CASE)
    d["part"]["metamodel"] = "standin"
    d["part"]["position"][2] = 2.5  # out of the arm's reach
    path = write(tmp_path, d)
    assert cli_main(["pickup", "plan", "--problem", path, "--out", str(tmp_path / "o"), "--method", "successive"]) == 1
    assert "no solution: status infeasible; best stage reached 1 of 5" in capsys.readouterr().out
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["status"] == "infeasible" and m["best_stage"] == 1 and not m["success"]
    # The default (routed) says why before any solve (issue 37).
    assert cli_main(["pickup", "plan", "--problem", path, "--out", str(tmp_path / "r")]) == 1
    assert "no solution: status infeasible, reason out_of_reach: the grasp point" in capsys.readouterr().out
    m = json.loads((tmp_path / "r" / "metrics.json").read_text())
    assert m["reason"] == "out_of_reach" and m["best_stage"] == 0 and m["T"] is None and m["lower_bound"] is None
    assert cli_main(["pickup", "plan", "--problem", path, "--out", str(tmp_path / "r"), "--time-limit", "-1"]) == 2
    assert "--time-limit: expected a finite number >= 0" in capsys.readouterr().err
    d["gamma"] = "high"
    assert cli_main(["pickup", "plan", "--problem", write(tmp_path, d), "--out", str(tmp_path / "o")]) == 2
    assert "p.json: gamma: expected a number" in capsys.readouterr().err
