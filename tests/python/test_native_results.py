"""The native bindings return result classes, not dicts (issue 32): each call on a small real input,
its result's type and a few of its fields against an independent computation, and the generic
to_dict / == / repr every result class shares."""

import json
import pathlib
import re

import numpy as np
import pytest
import trimesh

from pickplan import _core
from pickplan.core import sdf
from pickplan.core.collision import CollisionChecker, Table
from pickplan.omg import chomp, goals

ACTIVE = [True] * 7 + [False] * 2
Q_LEFT = np.array([1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])
Q_RIGHT = np.array([-1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])
BINDINGS = pathlib.Path(__file__).resolve().parents[2] / "bindings"


def _rotation_angle(A, B):
    return np.arccos(np.clip((np.trace(A[:3, :3].T @ B[:3, :3]) - 1) / 2, -1, 1))


@pytest.fixture(scope="module")
def ik(panda):
    return _core.IkSolver(panda.native, "panda_hand", goals.IkSettings().to_native(ACTIVE))


@pytest.fixture(scope="module")
def table_chomp(panda):
    pose = np.eye(4)
    pose[:3, 3] = [0.45, 0.0, -0.025]
    scene = sdf.SceneSdf([], table=((1.3, 1.6, 0.05), pose))
    return chomp.Chomp(panda, scene, panda.sample_body_points(per_link=10, seed=0))


def test_no_binding_builds_a_dict():
    """Results cross as classes: the dicts left are Robot.mimic (joint name -> its source, a lookup by
    name) and the generic to_dict (results.hpp)."""
    found = {
        str(p.relative_to(BINDINGS)): len(re.findall(r"py::dict\b", p.read_text())) for p in BINDINGS.rglob("*.[ch]pp")
    }
    assert {k: n for k, n in found.items() if n} == {"core/robot.cpp": 1, "results.hpp": 2}  # and to_dict


def test_ik_solution_reaches_its_target(panda, ik):
    q = Q_LEFT.copy()
    q[:7] += [0.1, -0.2, 0.1, 0.2, -0.1, 0.1, 0.2]
    target = panda.link_pose(q, "panda_hand")
    sol = ik.solve(target, panda.ready_configuration)
    assert type(sol) is _core.IkSolution and sol.converged and sol.iterations >= 1
    reached = panda.link_pose(sol.q, "panda_hand")
    assert sol.position_error == pytest.approx(np.linalg.norm(reached[:3, 3] - target[:3, 3]), abs=1e-12)
    assert sol.position_error < 1e-3 and _rotation_angle(reached, target) < 1e-2
    assert sol.rotation_error == pytest.approx(_rotation_angle(reached, target), abs=1e-6)
    assert not sol.q.flags.writeable  # a read-only view of the result
    assert sol == ik.solve(target, panda.ready_configuration)  # arrays compare by value
    assert sol != ik.solve(target, Q_RIGHT)
    every = ik.solve_all(target, panda.ready_configuration)
    assert every and all(type(s) is _core.IkSolution and s.converged for s in every)


def test_chomp_terms_results_and_metrics(panda, table_chomp):
    c = table_chomp
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    terms, grad = c.objective(xi, Q_LEFT)
    assert type(terms) is _core.ObjectiveTerms and grad.shape == xi.shape
    prior, _ = c.problem.prior(xi, Q_LEFT)
    assert terms.prior == pytest.approx(prior, rel=1e-12)
    assert terms.total == pytest.approx(terms.obstacle + c.settings.lambda_ * terms.prior, rel=1e-12)
    stepped, info = c.step(xi, Q_LEFT, Q_RIGHT)
    assert type(info) is _core.StepInfo and info.before == terms and info.goal_error <= 1e-10
    out = c.problem.optimize(xi, Q_LEFT, Q_RIGHT, 3)
    assert type(out) is _core.ChompResult and out.status == _core.ChompStatus.ok
    assert out.iterations == 3 and len(out.objective) == 3 and out.objective[0] == pytest.approx(terms.total)
    assert out.xi.shape == xi.shape and type(out.final_terms) is _core.ObjectiveTerms
    m = c.metrics(out.xi, Q_LEFT)
    assert type(m) is _core.TrajectoryMetrics
    path = np.vstack([Q_LEFT, out.xi])
    assert m.smoothness == pytest.approx(0.5 * np.sum(np.diff(path, axis=0) ** 2) / c.dt**2, rel=1e-9)


def test_to_dict_equality_and_repr_are_generic(table_chomp):
    c = table_chomp
    xi = c.initial_trajectory(Q_LEFT, Q_RIGHT)
    m, again = c.metrics(xi, Q_LEFT), c.metrics(xi, Q_LEFT)
    d = m.to_dict()
    assert (
        list(d)
        == list(type(m)._fields)
        == ["smoothness", "collision", "min_clearance", "min_table_clearance", "collision_free", "success"]
    )
    assert d["smoothness"] == m.smoothness and json.loads(json.dumps(d)) == d
    assert m == again and m != c.metrics(xi[::-1].copy(), Q_LEFT) and m != d
    assert repr(m).startswith("TrajectoryMetrics(smoothness=")
    out = c.problem.optimize(xi, Q_LEFT, Q_RIGHT, 2)
    nested = out.to_dict()
    assert nested["final_terms"] == out.final_terms.to_dict() and isinstance(nested["xi"], np.ndarray)
    assert "xi=array(30, 9)" in repr(out)
    with pytest.raises(AttributeError):
        m.success = True  # read-only


def test_goal_set_result(panda, ik):
    Q = np.array([Q_LEFT, Q_RIGHT])
    poses = panda.fk_batch(Q)[:, panda.link_index("panda_hand")]
    unreachable = poses[0].copy()
    unreachable[:3, 3] = [3.0, 0.0, 0.5]  # far beyond the arm's reach
    s = _core.GoalSetSettings()
    gs = _core.build_goal_set(ik, None, None, np.concatenate([poses, unreachable[None]]), panda.ready_configuration, s)
    assert type(gs) is _core.GoalSetResult and gs.goals.shape == (2, 9)
    assert gs.tails.shape == (2, s.standoff_steps + 1, 9)
    np.testing.assert_array_equal(gs.tails[:, -1], gs.goals)  # the grasp ends each tail
    assert gs.reasons == [_core.GoalReason.ok, _core.GoalReason.ok, _core.GoalReason.unreachable]
    for g, k in enumerate(gs.grasp_index):
        reached = panda.link_pose(gs.goals[g], "panda_hand")
        assert np.linalg.norm(reached[:3, 3] - poses[k][:3, 3]) < 1e-3


def test_collision_contacts_rrt_and_geometry(panda):
    checker = CollisionChecker(panda, [], Table())
    found = checker.native.contacts(panda.ready_configuration, 2.0)
    assert found and all(type(c) is _core.ContactInfo for c in found)
    table = [c for c in found if c.kind == _core.OtherKind.table]
    assert table and table[0].other == "table"
    assert found[0].distance == pytest.approx(checker.min_distance(panda.ready_configuration), abs=1e-9)
    assert table[0].point_other[2] == pytest.approx(0.0, abs=1e-6)  # the table's top face is z = 0
    planner = _core.MotionPlanner(checker.native, _core.RrtSettings())
    r = planner.rrt_connect(Q_LEFT, np.array([Q_RIGHT]))
    assert type(r) is _core.RrtResult and r.status == _core.RrtStatus.solved and r.goal == 0
    np.testing.assert_array_equal(r.path[0], Q_LEFT)
    np.testing.assert_array_equal(r.path[-1], Q_RIGHT)
    geoms = panda.native.collision_geometries("panda_link0")
    assert geoms and all(type(g) is _core.CollisionGeometry for g in geoms)
    assert geoms[0].kind == _core.GeometryKind.mesh and pathlib.Path(geoms[0].mesh_path).is_file()
    assert geoms[0].origin.shape == (4, 4) and np.allclose(geoms[0].origin[3], [0, 0, 0, 1])


def test_sdf_build_report_counts_degenerate_faces():
    box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    F = np.vstack([box.faces, [[0, 0, 1]]])  # one zero-area triangle more
    _, clean = _core.SdfGrid.build(box.vertices, box.faces, 0.01, 0.02)
    _, report = _core.SdfGrid.build(box.vertices, F, 0.01, 0.02)
    assert type(report) is _core.SdfBuildReport
    assert (clean.degenerate_faces, report.degenerate_faces) == (0, 1)
