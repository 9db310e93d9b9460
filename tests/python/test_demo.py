"""What ``pickplan demo`` writes, read back: the plan it reports, its timed trajectory (from the plan's
start to its goal, within the Panda's limits, the same in JSON and NPZ), the execution's outcome in
the table and in the exit code, the picture of the execution and the 3D view."""

import json

import numpy as np
import pytest
from PIL import Image

from pickplan.cli.main import main
from pickplan.core import robots
from pickplan.core.timing import TimedTrajectory, robot_limits
from pickplan.sim.scenes import Scene


def test_demo_writes_the_plan_its_timing_execution_picture_and_view(tmp_path, capsys):
    out = tmp_path / "demo"
    code = main(["demo", "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    plan = json.loads((out / "plan.json").read_text())
    executed = plan["execution"]
    assert plan["status"] == "success" and executed is not None  # the demo's seeded scene plans
    assert code == (0 if executed["success"] else 1)
    table = (out / "metrics.md").read_text()
    assert table in printed  # the table shown is the one written
    assert f"Status: {plan['status']}; execution: {executed['status']}" in table
    assert f"| Execution (target lifted) | {'yes' if executed['success'] else 'no'} |" in table

    timed = TimedTrajectory.load(str(out / "timed.npz"))
    np.testing.assert_array_equal(TimedTrajectory.load(str(out / "timed.json")).q, timed.q)
    path = np.asarray(plan["trajectory"])
    np.testing.assert_allclose(timed.q[0], path[0], atol=1e-6)
    np.testing.assert_allclose(timed.q[-1], path[-1], atol=1e-6)
    assert timed.rate == 1000.0 and np.allclose(np.diff(timed.t), 1e-3)
    assert plan["trajectory_duration"] == pytest.approx(timed.t[-1])
    limits = robot_limits(robots.panda())
    assert np.all(np.abs(timed.qd) <= 1.001 * limits.velocity)
    np.testing.assert_allclose(timed.qd[[0, -1]], 0, atol=1e-6)  # from rest to rest

    scene = Scene.load(str(out / "scene.json"))
    assert scene.target == executed["target"]
    with Image.open(out / "demo.png") as picture:  # a sheet of frames of the execution
        assert picture.format == "PNG" and picture.width >= 4 * 160
    page = (out / "view.html").read_text()
    assert len(page) > 500_000 and "<html" in page.lower()


def test_demo_place_carries_the_target_to_its_region(tmp_path, capsys):
    """``pickplan demo --place``: the table printed is the one written, the plan file holds the four
    segments timed, the view's plan carries the object, and the exit code is the execution's."""
    out = tmp_path / "place"
    code = main(["demo", "--place", "--out", str(out), "--quiet"])
    record = json.loads((out / "pickplace.json").read_text())
    assert record["status"] == "success"  # the demo's seeded scene plans
    placed = record["execution"]["status"] == "placed"
    assert code == (0 if placed else 1)
    assert [s["name"] for s in record["timed"]] == ["approach", "lift", "transfer", "retract"]
    table = (out / "metrics.md").read_text()
    assert table in capsys.readouterr().out
    assert f"| Executed in PyBullet | {record['execution']['status']}" in table
    held = json.loads((out / "plan.json").read_text())["held"]
    assert 0 < held["from"] < held["to"] and np.asarray(held["place_pose"]).shape == (4, 4)
    region = json.loads((out / "region.json").read_text())["region"]
    assert np.all(np.asarray(held["place_pose"])[:2, 3] >= np.asarray(region["min"][:2]))
    assert np.all(np.asarray(held["place_pose"])[:2, 3] <= np.asarray(region["max"][:2]))
    assert (out / "view.html").stat().st_size > 500_000
