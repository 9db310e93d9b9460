"""Pick and place end to end: the one call and its steps agree, the plan file holds both segments
timed within the robot's limits, the 3D view carries the object with the hand and leaves it at its
place, and the whole task executes in PyBullet (the object at rest in the region, upright, nothing
else moved, no collision)."""

import json
from dataclasses import replace

import numpy as np
import pytest

from pickplan.cli.main import main
from pickplan.core import objects
from pickplan.core.shapes import Obstacle, Shape
from pickplan.core.timing import robot_limits
from pickplan.eval.pickplace import execute_in_sim
from pickplan.eval.place_regions import RegionKind, RegionSettings, place_task
from pickplan.omg.grasps import verify
from pickplan.omg.grasps.physics import SimObject, lift_trial
from pickplan.omg.pickplace import PickPlacePlanner, PickPlaceSettings, PickPlaceStatus, pick_and_place
from pickplan.omg.place import PlaceRequest
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.sim.pickplace_exec import PlaceOutcome
from pickplan.sim.view import view_folder

from conftest import standing_scene

SETTINGS = PickPlaceSettings(pick=OMGSettings(grasp_kind="antipodal"))
REQUEST = PlaceRequest((0.35, -0.5, 0.0), (0.6, -0.25, 0.4))


def _scene():
    return standing_scene((("005_tomato_soup_can", (0.5, 0.0)), ("004_sugar_box", (0.6, 0.2))), "005_tomato_soup_can")[
        0
    ]


@pytest.fixture(scope="module")
def planned():
    scene = _scene()
    planner = PickPlacePlanner(OMGPlanner(None, scene, SETTINGS.pick), REQUEST, SETTINGS)
    return scene, planner, planner.plan()


def test_the_one_call_and_the_steps_plan_the_same(planned):
    scene, planner, plan = planned
    assert plan.status is PickPlaceStatus.success, plan.reason
    assert [n for n, _ in plan.segments()] == ["approach", "lift", "transfer", "retract"]
    whole = pick_and_place(scene, REQUEST, settings=SETTINGS)
    np.testing.assert_array_equal(whole.trajectory, plan.trajectory)
    # the steps on their own: plan a pick, attach, lift, plan a place
    pick = planner.plan_pick()
    carrying = planner.attach(pick.goal)
    lift, ok = planner.plan_lift(carrying, pick.goal)
    goals, place = planner.plan_place(carrying, lift[-1])
    assert ok and place.success
    # the transfer's start keeps the success test's clearance as the test measures it (per-object grids)
    X = carrying.robot.transform_points(lift[-1:], carrying.body)
    d, _ = carrying.sdf.distance(
        X.reshape(-1, 3), cutoff=1.0, exclude=(carrying.target,), exclude_table=True, reference=True
    )
    assert d.min() >= SETTINGS.place.metrics.clearance
    np.testing.assert_array_equal(place.trajectory, plan.place.trajectory)
    # the segments join: each starts where the previous ended
    segs = [Q for _, Q in plan.segments()]
    for a, b in zip(segs, segs[1:]):
        np.testing.assert_allclose(a[-1], b[0], atol=1e-12)
    # the planned place puts the object in the region, lowest point just above the floor
    model = planner.world.target_model
    V = model.mesh.vertices @ plan.place_pose[:3, :3].T + plan.place_pose[:3, 3]
    assert np.all(V >= np.array(REQUEST.region_min)) and np.all(V <= np.array(REQUEST.region_max))
    assert V[:, 2].min() == pytest.approx(SETTINGS.goals.gap, abs=1e-9)
    # the pick's grasp, as planned, held when lifted in PyBullet from its standoff
    grasp = np.linalg.inv(plan.held.hand_T_object)
    lift = replace(SETTINGS.verify_pick.lift, approach=SETTINGS.pick.goals.standoff)
    trial = lift_trial(SimObject(model), [verify._table_rest(planner.world._target_on_table)[0]], grasp, lift)
    assert verify._held(trial, SETTINGS.verify_pick), trial


def test_pickplace_command_writes_both_segments_timed_and_the_view(planned, tmp_path):
    scene, _, plan = planned
    scene.save(str(tmp_path / "scene.json"))
    (tmp_path / "region.json").write_text(json.dumps(REQUEST.to_dict()))
    out = tmp_path / "out"
    code = main(
        [
            "pickplace",
            "--scene",
            str(tmp_path / "scene.json"),
            "--place",
            str(tmp_path / "region.json"),
            "--grasps",
            "antipodal",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    record = json.loads((out / "pickplace.json").read_text())
    assert [s["name"] for s in record["timed"]] == ["approach", "lift", "transfer", "retract"]
    limits = robot_limits(planned[1].world.robot)
    for seg, timed in zip(record["segments"], record["timed"]):
        q, qd, qdd = (np.asarray(timed[k]) for k in ("q", "qd", "qdd"))
        np.testing.assert_allclose(q[[0, -1]], np.asarray(seg["waypoints"])[[0, -1]], atol=1e-9)
        assert np.all(np.abs(qd) <= limits.velocity * (1 + 1e-6)) and np.all(
            np.abs(qdd) <= limits.acceleration * (1 + 1e-6)
        )
        assert np.all(qd[[0, -1]] == 0)  # rest to rest: the hand stops to close, release and between segments
    assert (out / "view.html").stat().st_size > 10000
    # the view: the object rides with the hand between the grasp and the release, then rests at its place
    view = view_folder(str(out))
    (animation,) = [c for c in (c.lower() for c in view.commands) if c["type"] == "set_animation"]
    clip = {a["path"]: a["clip"] for a in animation["animations"]}[f"/meshcat/pickplan/objects/{scene.target}"]
    positions = [k["value"] for t in clip["tracks"] if t["name"] == ".position" for k in t["keys"]]
    held = json.loads((out / "plan.json").read_text())["held"]
    np.testing.assert_allclose(positions[0], np.asarray(scene.object(scene.target).pose)[:3, 3], atol=1e-9)
    np.testing.assert_allclose(positions[-1], np.asarray(held["place_pose"])[:3, 3], atol=1e-9)
    robot = planned[1].world.robot
    mid = (held["from"] + held["to"]) // 2
    hand = robot.link_pose(np.asarray(json.loads((out / "plan.json").read_text())["trajectory"][mid]), robot.hand_link)
    substeps = 4
    np.testing.assert_allclose(positions[mid * substeps], (hand @ np.asarray(held["hand_T_object"]))[:3, 3], atol=1e-9)


def test_pick_and_place_executes_in_pybullet(planned):
    scene, planner, plan = planned
    info = {}
    ex = execute_in_sim(scene, planner, plan, REQUEST, "panda", info=info)
    assert ex.status is PlaceOutcome.placed, ex.message
    assert ex.held_after_close and ex.held_before_release and ex.in_region and ex.at_rest
    assert ex.tilt_deg < REQUEST.tolerance_deg
    assert max(ex.object_displacements.values()) <= 0.02
    assert not ex.robot_contacts or max(ex.robot_contacts.values()) <= 0.002
    assert "grasp_shift" in info  # the grasp as executed was measured (and planned for when it moved)


def test_pick_and_place_from_a_depth_observation(tmp_path):
    """Planned from three rendered views (no mesh): the held object is its observed points standing on
    the plane; the true object, carried by the planned grasp, ends inside the region."""
    from pickplan.sim.observe import render_observation

    scene = _scene()
    path = str(tmp_path / "obs.npz")
    render_observation(scene, views=3, seed=0).save(path)
    scene.save(str(tmp_path / "scene.json"))
    (tmp_path / "region.json").write_text(json.dumps(REQUEST.to_dict()))
    out = tmp_path / "out"
    code = main(
        [
            "pickplace",
            "--observation",
            path,
            "--scene",
            str(tmp_path / "scene.json"),
            "--place",
            str(tmp_path / "region.json"),
            "--out",
            str(out),
        ]
    )
    assert code == 0
    record = json.loads((out / "pickplace.json").read_text())
    assert record["status"] == "success" and len(record["timed"]) == 4
    # the true can, held as the planned grasp holds it (its frame in the observed one: its scene pose)
    truth = np.asarray(scene.object(scene.target).pose)
    place = np.asarray(record["place_pose"]) @ truth
    model = objects.library("builtin").get(scene.target)
    V = model.mesh.vertices @ place[:3, :3].T + place[:3, 3]
    assert np.all(V[:, :2] >= np.array(REQUEST.region_min[:2]) - 0.01)
    assert np.all(V[:, :2] <= np.array(REQUEST.region_max[:2]) + 0.01)
    assert abs(V[:, 2].min()) < 0.01  # on the table (the observed points' feet are on the plane)


def test_pickplace_command_exit_codes(planned, tmp_path, capsys):
    """A wrong region file is bad input (2, naming the file and the field); a region out of reach is
    no plan (1, saying why)."""
    scene = planned[0]
    scene.save(str(tmp_path / "scene.json"))
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"region": {"min": [0.4, 0.2, 0.0], "max": [0.3, 0.4, 0.4]}}))
    args = ["pickplace", "--scene", str(tmp_path / "scene.json"), "--grasps", "antipodal", "--place"]
    assert main(args + [str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "region.max" in err
    far = tmp_path / "far.json"
    far.write_text(json.dumps({"region": {"min": [1.0, 0.65, 0.0], "max": [1.09, 0.78, 0.4]}}))
    assert main(args + [str(far)]) == 1
    assert "no_place_goals: region out of reach" in capsys.readouterr().out


def test_the_carry_check_sees_the_held_object_on_the_true_meshes(planned):
    """``carry_contacts`` (the bench's measure): clear for the plan as planned; another can put where the
    held can's bottom passes mid-transfer (1.5 cm into it) is a collision of the held object."""
    from pickplan.eval.pickplace import CarryContact, carry_contacts
    from pickplan.sim import scenes

    scene, planner, plan = planned
    assert not carry_contacts(plan, planner.attach(plan.pick.goal, plan.held))
    robot, lib = planner.world.robot, objects.library("builtin")
    q = plan.place.trajectory[len(plan.place.trajectory) // 2]
    held_pose = robot.link_pose(q, robot.hand_link) @ plan.held.hand_T_object
    can = lib.get(scene.target).mesh.vertices @ held_pose[:3, :3].T + held_pose[:3, 3]
    box = lib.get("010_potted_meat_can")
    pose = np.eye(4)
    pose[:2, 3] = can[:, :2].mean(axis=0)
    pose[2, 3] = can[:, 2].min() + 0.015 - box.mesh.vertices[:, 2].max()
    blocked = replace(
        scene,
        objects=list(scene.objects) + [scenes.SceneObject("010_potted_meat_can", "builtin:010_potted_meat_can", pose)],
    )
    other = PickPlacePlanner(OMGPlanner(None, blocked, SETTINGS.pick), REQUEST, SETTINGS)
    assert CarryContact.held in carry_contacts(plan, other.attach(plan.pick.goal, plan.held))


def test_a_grasp_that_leaves_no_place_is_replaced_by_one_that_does():
    """A soup can into a bin 10 cm square and 8 cm deep: the pick's first grasp (the one it plans when
    place feasibility is not asked) puts the hand where the bin's wall stands at every place; the pick
    planned again among its other goals that have a place goal completes the task, executed in PyBullet."""
    scene, request = place_task(
        _scene(), RegionKind.bin, seed=0, settings=RegionSettings(bin_inner=(0.10, 0.10), bin_height=0.08)
    )
    never = replace(SETTINGS, regrasp_plans=0)
    first = PickPlacePlanner(OMGPlanner(None, scene, never.pick), request, never).plan()
    assert first.status is PickPlaceStatus.no_place_goals, first.reason
    planner = PickPlacePlanner(OMGPlanner(None, scene, SETTINGS.pick), request, SETTINGS)
    plan = planner.plan()
    assert plan.status is PickPlaceStatus.success and plan.reason.startswith("regrasp: no_place_goals"), plan.reason
    assert plan.pick.grasp_index != first.pick.grasp_index
    ex = execute_in_sim(scene, planner, plan, request, "panda")
    assert ex.status is PlaceOutcome.placed, ex.message
    assert not ex.robot_contacts or max(ex.robot_contacts.values()) <= 0.002


def test_a_transfer_over_a_wall_starts_from_a_sampled_path():
    """A wall 45 cm high between the target and the region: the transfer's loop from the straight line
    ends in collision; from an RRT-Connect start (``OMGSettings.sampled_start``, as a pick among
    furniture) it passes the success test, and the whole task executes in PyBullet."""
    pose = np.eye(4)
    pose[:3, 3] = (0.5, -0.17, 0.225)
    scene = replace(_scene(), obstacles=[Obstacle("wall", Shape.box(0.6, 0.02, 0.45), pose)])
    # the transfer of the first grasp, nothing else (no upright start either: the straight line's loop)
    alone = replace(SETTINGS, regrasp_plans=0, upright_carry=False)
    straight = replace(alone, place=replace(alone.place, sampled_start=None))
    first = PickPlacePlanner(OMGPlanner(None, scene, straight.pick), REQUEST, straight).plan()
    assert first.status is PickPlaceStatus.place_failed, first.reason
    planner = PickPlacePlanner(OMGPlanner(None, scene, alone.pick), REQUEST, alone)
    plan = planner.plan()
    assert plan.status is PickPlaceStatus.success and plan.place.history.get("sampled_start"), plan.reason
    ex = execute_in_sim(scene, planner, plan, REQUEST, "panda")
    assert ex.status is PlaceOutcome.placed, ex.message
    assert not ex.robot_contacts or max(ex.robot_contacts.values()) <= 0.002
