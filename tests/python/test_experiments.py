"""The paper-table runner: a quick sweep gives complete, consistent tables; an interrupted sweep
resumes to the same table; the baselines give valid trajectories; Ray started locally runs units."""

import functools
import io
import json
import math
import os

import numpy as np
import pytest

from pickplan.core.description import robot_info
from pickplan.eval import experiments as E
from pickplan.eval import units
from pickplan.eval.summaries import summarize
from pickplan.cli import bench as C


def _check_summary(summary, methods, scenes, runs):
    assert list(summary) == list(methods)
    for m, row in summary.items():
        assert row["units"] == scenes * runs, m
        assert 0 <= row["planned"] <= row["valid"] <= row["units"]
        assert 0 <= row["execution_successes"] <= row["planning_successes"] <= row["valid"]
        for key in ("planning", "execution"):
            assert 0.0 <= row[key] <= 1.0, (m, key)
        assert row["planning"] == pytest.approx(row["planning_successes"] / row["valid"])
        if row["planned"]:
            for key in ("smoothness", "collision", "time", "goal_set_time"):
                assert math.isfinite(row[key]) and row[key] >= 0, (m, key)


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """Three generated scenes shared by the tests (built-in objects)."""
    out = str(tmp_path_factory.mktemp("scenes"))
    E.scene_files(E.SweepSettings("selection", out=out, scenes=3, workers=0, progress=False))
    return os.path.join(out, "scenes")


def test_quick_planners_sweep_tables_complete(scene_dir, tmp_path):
    methods = ("CHOMP", "CHOMP-C", "RRT-C", "OMG")
    s = E.SweepSettings(
        "planners",
        out=str(tmp_path),
        scene_dir=scene_dir,
        runs=1,
        methods=methods,
        quick=True,
        workers=2,
        progress=True,
    )
    err = io.StringIO()
    records = E.run_sweep(s, stream=err)
    assert len(records) == 3 * len(methods)
    assert "12/12" in err.getvalue()  # the progress bar reached the end
    for r in records:
        if r["execution_success"]:
            assert r["planning_success"]  # failed plans are not executed: they count as failures
        assert r["plan_time"] >= 0 and r["goal_set_time"] >= 0
    text = C.write_report(s, records)
    _check_summary(summarize(records, methods), methods, 3, 1)
    for m in methods:
        assert m in text
    for name in ("table.md", "runs.csv", "runs.json", "summary.json"):
        assert os.path.getsize(tmp_path / name) > 0
    assert "(93%)" in text  # the paper's numbers beside ours
    assert len(open(tmp_path / "runs.csv").read().strip().splitlines()) == 1 + len(records)


def _table_without_times(records, methods):
    summary = summarize(records, methods)
    return {m: {k: v for k, v in row.items() if "time" not in k} for m, row in summary.items()}


def test_interrupted_sweep_resumes_to_same_table(scene_dir, tmp_path):
    methods = ("Fixed", "MD")
    base = dict(scene_dir=scene_dir, runs=1, methods=methods, quick=True, workers=0, execute=False, progress=False)
    full = E.run_sweep(E.SweepSettings("selection", out=str(tmp_path / "full"), **base))

    calls = []

    def interrupted(unit):
        if len(calls) == 4:
            raise KeyboardInterrupt  # the user stops the sweep after 4 finished units
        calls.append(unit)
        return E.run_unit(unit)

    s = E.SweepSettings("selection", out=str(tmp_path / "resumed"), **base)
    with pytest.raises(KeyboardInterrupt):
        E.run_sweep(s, unit_fn=interrupted)
    assert len(os.listdir(tmp_path / "resumed" / "units")) == 4
    rerun = []

    def counting(unit):
        rerun.append(unit)
        return E.run_unit(unit)

    resumed = E.run_sweep(s, unit_fn=counting)
    assert len(rerun) == 2  # only the units that had not finished
    assert len(resumed) == len(full) == 6
    assert _table_without_times(resumed, methods) == _table_without_times(full, methods)
    keyed = lambda rs: {(r["scene"], r["method"], r["run"]): (r["status"], r["smoothness"]) for r in rs}  # noqa: E731
    assert keyed(resumed) == keyed(full)


def test_a_failing_unit_is_recorded_and_the_sweep_goes_on(scene_dir, tmp_path):
    base = dict(scene_dir=scene_dir, runs=1, methods=("Fixed",), quick=True, workers=0, execute=False, progress=False)
    s = E.SweepSettings("selection", out=str(tmp_path / "errors"), **base)
    calls = []

    def flaky(unit):
        calls.append(unit)
        if len(calls) == 2:
            raise RuntimeError("solver blew up")
        return E.run_unit(unit)

    records = E.run_sweep(s, unit_fn=flaky)
    assert len(records) == len(calls) == 3
    errors = [r for r in records if r["status"] == "error"]
    assert len(errors) == 1 and "RuntimeError: solver blew up" in errors[0]["error"]
    row = summarize(records, ("Fixed",))["Fixed"]
    assert row["errors"] == 1 and row["valid"] == 3 and row["planning_successes"] <= 2
    # The error is a finished unit: a rerun does not repeat it.
    assert len(E.run_sweep(s, unit_fn=flaky)) == 3 and len(calls) == 3


def test_baselines_valid_trajectories(scene_dir):
    from pickplan.eval.baselines import BaselineSettings, SupportValidity, plan_baseline
    from pickplan.omg.goals import GoalSetSettings
    from pickplan.omg.planner import OMGSettings, PlanStatus
    from pickplan.sim.scenes import Scene
    from pickplan.omg.world import World

    scene = Scene.load(os.path.join(scene_dir, sorted(os.listdir(scene_dir))[0]))
    world = World(scene)
    settings = BaselineSettings(omg=OMGSettings(goals=GoalSetSettings(max_goals=10), grasp_count=30), time_limit=0.5)
    validity = SupportValidity(world, world.start, settings.omg.metrics.support_tolerance)
    lo, hi = world.robot.lower_limits, world.robot.upper_limits
    for name in ("CHOMP", "CHOMP-C", "FMT", "RRT-C"):
        r = plan_baseline(name, scene, settings, world=world)
        assert r.status != PlanStatus.no_goals, f"{name}: the seeded first scene has goals"
        assert r.trajectory.shape == (31, world.robot.dof), name
        assert np.allclose(r.trajectory[0], world.start)
        assert np.all(r.trajectory >= lo - 1e-6) and np.all(r.trajectory <= hi + 1e-6), name
        assert set(r.metrics.to_dict()) >= {"smoothness", "collision", "success"}
        assert r.timings["total"] >= r.timings["goal_set"] >= 0
        if name in ("FMT", "RRT-C"):
            # a path OMPL found (up to the pre-grasp) is valid at its waypoints, by the rule it was
            # planned with; a success comes only from a found path
            returned = next(a for a in r.history["attempts"] if a["goal"] == r.history["goal"][0])
            assert returned["found"] or not r.success, name
            if returned["found"]:
                assert all(validity(q) for q in r.trajectory[1 : 31 - 5 + 1]), name


def test_ray_local_runs_units(scene_dir, tmp_path):
    pytest.importorskip("ray")
    s = E.SweepSettings(
        "selection",
        out=str(tmp_path),
        scene_dir=scene_dir,
        runs=1,
        methods=("MD",),
        quick=True,
        workers=2,
        ray="local",
        execute=False,
        progress=False,
    )
    records = E.run_sweep(s)
    assert len(records) == 3 and {r["method"] for r in records} == {"MD"}
    # the same units in this process give the same plans
    serial = E.run_sweep(
        E.SweepSettings(
            "selection",
            out=str(tmp_path / "serial"),
            scene_dir=scene_dir,
            runs=1,
            methods=("MD",),
            quick=True,
            workers=0,
            execute=False,
            progress=False,
        )
    )
    assert [(r["status"], r["smoothness"]) for r in records] == [(r["status"], r["smoothness"]) for r in serial]


def test_cli_ablation_quick_writes_plot(scene_dir, tmp_path):
    out = tmp_path / "abl"
    rc = C.main(
        [
            "bench",
            "ablation",
            "--quick",
            "--scene-dir",
            scene_dir,
            "--methods",
            "n=20",
            "lambda=1",
            "--workers",
            "0",
            "--no-execute",
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    assert os.path.getsize(out / "fig8.png") > 0
    assert "n=20" in (out / "table.md").read_text()


def test_bad_arguments_are_clear():
    with pytest.raises(ValueError, match="unknown table"):
        E.SweepSettings("tables")
    with pytest.raises(ValueError, match="unknown methods"):
        E.SweepSettings("selection", methods=("OMG",))
    with pytest.raises(ValueError, match="runs must be >= 1"):
        E.SweepSettings("planners", runs=0)


def test_resuming_with_other_settings_is_refused(scene_dir, tmp_path):
    calls = []

    def counting(unit):
        calls.append(unit)
        return {
            "table": unit["table"],
            "scene": unit["scene_name"],
            "target": "t",
            "method": unit["method"],
            "run": unit["run"],
            "status": "no_goals",
            "valid": True,
            "planned": False,
            "planning_success": False,
            "execution_success": False,
        }

    base = dict(
        out=str(tmp_path / "sweep"),
        scene_dir=scene_dir,
        runs=1,
        methods=("Fixed",),
        grasps=10,
        workers=0,
        execute=False,
        progress=False,
    )
    # the counting units plan nothing: no simulated grasp sets built for them (100 per target, minutes cold)
    sweep = functools.partial(E.run_sweep, unit_fn=counting, warm_grasps=False)
    assert len(sweep(E.SweepSettings("selection", **base))) == 3
    # More runs and another method only add units; the finished ones are reused.
    more = {**base, "runs": 2, "methods": ("Fixed", "MD")}
    assert len(sweep(E.SweepSettings("selection", **more))) == 12 and len(calls) == 12
    # A setting the units depend on may not change under the same folder: nothing is run or written.
    with pytest.raises(ValueError, match=r"other settings \(grasps: 10 there, 5 now"):
        sweep(E.SweepSettings("selection", **{**base, "grasps": 5}))
    with pytest.raises(ValueError, match="seed: 0 there, 3 now"):
        sweep(E.SweepSettings("selection", **{**base, "seed": 3}))
    assert len(calls) == 12 and len(os.listdir(tmp_path / "sweep" / "units")) == 12


def test_no_execute_says_not_run_and_durations_are_reported(scene_dir, tmp_path):
    out = tmp_path / "noexec"
    rc = C.main(
        [
            "bench",
            "selection",
            "--quick",
            "--scene-dir",
            scene_dir,
            "--methods",
            "Fixed",
            "--workers",
            "0",
            "--no-execute",
            "--no-progress",
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    rows = {
        line.split("|")[1].strip(): line
        for line in (out / "table.md").read_text().splitlines()
        if line.startswith("| ")
    }
    assert "not run" in rows["Execution"] and "0%" not in rows["Execution"]  # never a zero for a column not run
    records = json.loads((out / "runs.json").read_text())
    planned = [r for r in records if r.get("planned")]
    assert planned and all(r["trajectory_duration"] > 0 for r in planned)
    summary = summarize(records, ("Fixed",))["Fixed"]
    assert summary["execution"] is None and summary["execution_run"] is False
    assert summary["duration"] == pytest.approx(np.mean([r["trajectory_duration"] for r in planned]))
    duration_cell = rows["Trajectory duration (s, timed within the joint limits)"].split("|")[2].strip()
    assert float(duration_cell) == pytest.approx(summary["duration"], abs=0.005)
    # Executed units still give a rate, failed plans counted as failed executions.
    executed = [{**r, "execution_run": True} for r in records]
    assert summarize(executed, ("Fixed",))["Fixed"]["execution"] == 0.0


def test_timed_execution_follows_the_timed_trajectory(scene_dir, tmp_path):
    from pickplan.sim.execution import ExecutionSettings

    s = E.SweepSettings(
        "selection",
        out=str(tmp_path),
        scene_dir=scene_dir,
        runs=1,
        methods=("Fixed",),
        quick=True,
        workers=0,
        timed_execution=True,
        progress=False,
    )
    units = E.make_units(s, E.scene_files(s))
    executed = []
    for unit in units:
        r = E.run_unit(unit)
        if r["planning_success"]:
            executed.append(r)
            assert r["execution_run"] and r["execution_status"] != "not_executed"
            x = ExecutionSettings()  # sim time = the timed approach + the fixed settle, close, lift and hold phases
            fixed = (
                x.start_settle
                + x.approach_settle
                + x.closing_time(robot_info("panda"))
                + x.lift_duration
                + x.hold_duration
            )
            assert r["execution_sim_time"] == pytest.approx(fixed + r["trajectory_duration"], abs=3 * x.time_step)
    assert executed, "the seeded scenes: at least one plans with Fixed"


def test_a_damaged_unit_file_is_redone_on_resume_and_named(scene_dir, tmp_path):
    """Regression (issue 26): a damaged unit file stopped a resume with a JSON error naming no file."""
    base = dict(
        scene_dir=scene_dir, runs=1, methods=("Fixed", "MD"), quick=True, workers=0, execute=False, progress=False
    )
    s = E.SweepSettings("selection", out=str(tmp_path / "damaged"), **base)
    calls = []

    def fake(unit):  # a finished record without planning: the sweep's bookkeeping is what is tested
        calls.append(unit)
        return {
            "table": unit["table"],
            "scene": unit["scene_name"],
            "method": unit["method"],
            "run": unit["run"],
            "seed": int(unit["seed"]),
            "status": "success",
            "valid": True,
            "planned": True,
            "planning_success": True,
            "execution_success": False,
        }

    first = E.run_sweep(s, unit_fn=fake)
    n = len(first)
    assert n >= 4 and len(calls) == n
    files = sorted((tmp_path / "damaged" / "units").iterdir())
    truncated, foreign = files[0], files[1]
    truncated.write_text(truncated.read_text()[: len(truncated.read_text()) // 2])  # cut mid-record
    foreign.write_text(files[2].read_text())  # another unit's record under this unit's name
    calls.clear()
    with pytest.warns(UserWarning) as seen:
        resumed = E.run_sweep(s, unit_fn=fake)
    messages = " ".join(str(w.message) for w in seen)
    assert truncated.name in messages and "damaged unit record" in messages
    assert foreign.name in messages and "not the record of unit" in messages
    assert len(calls) == 2 and len(resumed) == n  # only the two damaged units ran again
    keyed = lambda rs: sorted((r["scene"], r["method"], r["run"]) for r in rs)  # noqa: E731
    assert keyed(resumed) == keyed(first)


def test_a_workers_shared_models_do_not_change_records(scene_dir, tmp_path, monkeypatch):
    """Units run one after another in a worker share its ModelCache (worlds, generated grasps); each
    record equals the one a fresh cache gives (plans, metrics, statuses: everything but times)."""
    from pickplan.omg.model_cache import ModelCache

    s = E.SweepSettings(
        "planners",
        out=str(tmp_path / "shared"),
        scene_dir=scene_dir,
        runs=1,
        methods=("CHOMP-C", "OMG"),
        quick=True,
        workers=0,
        progress=False,
        execute=False,
        grasp_kind="antipodal",
    )
    shared = E.run_sweep(s)
    calls = []

    def fresh(unit):
        monkeypatch.setattr(units, "_WORKER_MODELS", ModelCache())
        calls.append(unit["method"])
        return units.run_unit(unit)

    alone = E.run_sweep(E.SweepSettings(**{**s.__dict__, "out": str(tmp_path / "fresh")}), unit_fn=fresh)

    def comparable(r):
        return {k: v for k, v in r.items() if "time" not in k and k not in ("unit_seconds", "sweep")}

    assert len(shared) == len(alone) == len(calls) == 6
    assert [comparable(r) for r in shared] == [comparable(r) for r in alone]
    assert sum(r["planning_success"] for r in shared) >= 3  # plans, not a table of failures
