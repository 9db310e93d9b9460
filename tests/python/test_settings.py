"""Settings and results that cannot drift: every Python settings dataclass that mirrors a native
struct has its fields and defaults, and options and statuses are enums that keep their spellings."""

import dataclasses
import json

import numpy as np
import pytest

from pickplan import _core
from pickplan.core.collision import CollisionSettings
from pickplan.omg.chomp import ChompSettings, ChompStatus, Initialization, MetricSettings
from pickplan.omg.goals import GoalSetSettings
from pickplan.core.ik import IkSettings
from pickplan.omg.grasps import GraspKind
from pickplan.omg.isf import IsfSettings
from pickplan.omg.planner import OMGSettings, PlanStatus
from pickplan.omg.selection import CostKind, Selection
from pickplan.omg.world import CheckerKind
from pickplan.pickup.nlp import cases, planner as nlp, problem_file
from pickplan.sim.execution import ExecutionStatus

ARM = [True] * 7 + [False] * 2

# Python dataclass, native struct, conversion, native-only fields (set per call), Python-only fields.
PAIRS = {
    "chomp": (ChompSettings, _core.ChompSettings, lambda s: s.to_native(), {"exclude_mask", "active"}, set()),
    "metrics": (MetricSettings, _core.MetricSettings, lambda s: s.to_native(), {"exclude_mask"}, set()),
    "ik": (IkSettings, _core.IkSettings, lambda s: s.to_native(ARM), {"weights"}, set()),
    "goal_set": (
        GoalSetSettings,
        _core.GoalSetSettings,
        lambda s: s.to_native(),
        set(),
        set(GoalSetSettings.PYTHON_ONLY),
    ),
    "isf": (IsfSettings, _core.IsfSettings, lambda s: s.to_native(ARM), {"active"}, set()),
    "collision": (CollisionSettings, _core.CollisionSettings, lambda s: s.to_native(), set(), set()),
    "pickup": (nlp.PlannerSettings, _core.PickupSettings, lambda s: s.to_native(), set(), set()),
    "stomp": (nlp.StompSettings, _core.StompSettings, lambda s: s.to_native(), set(), set()),
}

# Python option/status enums with a native py::enum_ of the same member names.
NATIVE_ENUMS = [
    (ChompStatus, _core.ChompStatus),
    (nlp.HessianMode, _core.HessianMode),
    (nlp.CoefficientBasis, _core.CoefficientBasis),
    (nlp.MuStrategy, _core.MuStrategy),
    (nlp.RateRows, _core.RateRows),
    (nlp.SolveStatus, _core.SolveStatus),
    (problem_file.GraspKind, _core.GraspKind),
]
OPTIONS = [
    ChompStatus,
    Initialization,
    GraspKind,
    PlanStatus,
    Selection,
    CostKind,
    CheckerKind,
    nlp.HessianMode,
    nlp.CoefficientBasis,
    nlp.MuStrategy,
    nlp.RateRows,
    nlp.Method,
    ExecutionStatus,
]


def native_fields(native_type) -> set:
    """The struct's fields, its bases' included (IkSettings extends DlsSettings)."""
    return {name for klass in native_type.__mro__ for name, v in vars(klass).items() if isinstance(v, property)}


def same(a, b) -> bool:
    if hasattr(a, "name") and hasattr(b, "name"):  # two enums: the native counterpart shares the names
        return a.name == b.name
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):  # an Eigen vector field (GoalSetSettings.approach)
        return np.shape(a) == np.shape(b) and np.array_equal(np.asarray(a, float), np.asarray(b, float))
    if isinstance(a, (list, tuple)) or isinstance(b, (list, tuple)):
        return [tuple(x) if isinstance(x, (list, tuple)) else x for x in a] == [
            tuple(x) if isinstance(x, (list, tuple)) else x for x in b
        ]
    return type(a) is type(b) and a == b


def drift(py_type, native_type, convert, native_only, python_only) -> list:
    """What differs between a Python settings dataclass and its native struct: fields on one side
    only, and defaults that reach the native struct changed (the converted Python default against
    a default-constructed native struct)."""
    ours = {f.name for f in dataclasses.fields(py_type)} - python_only
    theirs = native_fields(native_type) - native_only
    problems = [f"{n}: native only" for n in sorted(theirs - ours)]
    problems += [f"{n}: Python only" for n in sorted(ours - theirs)]
    converted, native = convert(py_type()), native_type()
    for name in sorted(ours & theirs):
        a = converted[name] if isinstance(converted, dict) else getattr(converted, name)
        b = getattr(native, name)
        if not same(a, b):
            problems.append(f"{name}: Python default {a!r}, native {b!r}")
    return problems


@pytest.mark.parametrize("pair", sorted(PAIRS))
def test_python_settings_match_the_native_struct_field_by_field(pair):
    assert drift(*PAIRS[pair]) == []


def test_the_drift_check_sees_a_changed_default_and_a_missing_field():
    py_type, native_type, convert, native_only, python_only = PAIRS["pickup"]
    fields = [(f.name, f.type, dataclasses.field(default=f.default)) for f in dataclasses.fields(py_type)]
    changed = dataclasses.make_dataclass(
        "Changed",
        [(n, t, dataclasses.field(default=9) if n == "max_iter" else d) for n, t, d in fields if n != "seed_speed"],
    )
    problems = drift(changed, native_type, lambda s: dataclasses.asdict(s), native_only, python_only)
    assert problems == ["seed_speed: native only", "max_iter: Python default 9, native 400"]


def test_native_defaults_fill_only_the_fields_left_without_one():
    """The decorator reads a default-constructed native struct: enums become the Option of the
    field, vectors tuples; an explicit Python default stays; a field the struct lacks is an error."""
    from pickplan.core.settings import native_defaults

    @dataclasses.dataclass(frozen=True)
    @native_defaults(_core.GoalSetSettings)
    class Mirror:
        max_goals: int
        approach: tuple
        seed: int = 5

    assert Mirror() == Mirror(max_goals=30, approach=(0.0, 0.0, 0.0), seed=5)
    assert type(Mirror().approach) is tuple and IkSettings().task is type(IkSettings().task).pose
    with pytest.raises(TypeError, match="Missing.standoffs has no default and GoalSetSettings no such field"):
        native_defaults(_core.GoalSetSettings)(type("Missing", (), {"__annotations__": {"standoffs": float}}))


def test_planner_settings_reach_the_native_struct_as_enums():
    s = nlp.PlannerSettings(hessian="limited-memory", rate_rows=nlp.RateRows.sampled, ipopt_options=[("a", "b")])
    assert s.hessian is nlp.HessianMode.limited_memory and s.rate_rows is nlp.RateRows.sampled
    native = s.to_native()
    assert native.hessian == _core.HessianMode.limited_memory and native.rate_rows == _core.RateRows.sampled
    assert native.basis == _core.CoefficientBasis.bernstein and native.ipopt_options == [("a", "b")]


@pytest.mark.parametrize("option", OPTIONS, ids=lambda o: o.__name__)
def test_options_round_trip_through_json_by_value(option):
    for member in option:
        text = json.dumps({"v": member})
        assert text == json.dumps({"v": member.value})  # the file holds the plain spelling
        back = option.parse(json.loads(text)["v"])
        assert back is member and back == member.value and str(back) == member.value == f"{back}"
        assert {member.value: 1}[member] == 1  # one dict key with its spelling


@pytest.mark.parametrize("option", OPTIONS, ids=lambda o: o.__name__)
def test_a_misspelt_option_lists_the_valid_ones(option):
    valid = ", ".join(repr(m.value) for m in option)
    with pytest.raises(ValueError, match=f"unknown thing 'Nope'; valid: {valid}"):
        option.parse("Nope", "thing")


@pytest.mark.parametrize("ours,theirs", NATIVE_ENUMS, ids=lambda e: e.__name__)
def test_native_enums_share_member_names(ours, theirs):
    assert [m.name for m in ours] == list(theirs.__members__)
    for member in ours:
        assert ours.from_native(getattr(theirs, member.name)) is member


def test_api_boundaries_accept_spellings_and_reject_misspellings():
    s = OMGSettings(selection="FTL", grasp_kind="antipodal")
    assert s.selection is Selection.FTL and s.grasp_kind is GraspKind.antipodal
    assert dataclasses.replace(s, selection="MD").selection is Selection.MD
    with pytest.raises(ValueError, match="unknown selection policy 'md'; valid: 'Fixed', 'Proj', 'FTC'"):
        OMGSettings(selection="md")
    with pytest.raises(ValueError, match="unknown grasp set kind 'grasp_it'"):
        OMGSettings(grasp_kind="grasp_it")
    with pytest.raises(ValueError, match="unknown hessian 'lbfgs'; valid: 'exact', 'limited-memory'"):
        nlp.PlannerSettings(hessian="lbfgs")
    with pytest.raises(ValueError, match="unknown checker kind 'hands'; valid: 'goal', 'hand', 'strict', 'obstacles'"):
        CheckerKind.parse("hands", "checker kind")
    # A status read back from an old JSON file compares equal to the enum.
    assert json.loads('{"status": "no_goals"}')["status"] == PlanStatus.no_goals


@pytest.mark.parametrize("hessian", list(nlp.HessianMode), ids=str)
def test_the_hessian_option_reaches_ipopt(tmp_path, hessian):
    """Ipopt's own log: with its L-BFGS approximation the NLP hands it no Hessian entries."""
    robot = nlp.mobile_ur5()
    problem = cases.make_problem(robot, 1)
    log = tmp_path / "ipopt.txt"
    settings = nlp.PlannerSettings(samples_per_interval=4, max_iter=1, hessian=hessian.value, output_file=str(log))
    x0 = _core.pickup_heuristic_seed(robot.native, problem, settings.to_native())
    nlp.solve_stage(robot, problem, x0, 1, settings)
    line = next(x for x in log.read_text().splitlines() if x.startswith("Number of nonzeros in Lagrangian Hessian"))
    nonzeros = int(line.rsplit(":", 1)[1])
    assert (nonzeros == 0) == (hessian is nlp.HessianMode.limited_memory), line
