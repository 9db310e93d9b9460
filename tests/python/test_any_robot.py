"""Any robot and parallel gripper (issue 21): robots built from their descriptions, grasps converted to or
generated for their grippers, pads from their own geometry, limits from their files, and a plan executed
in PyBullet for the UR5 + 2F-85 and the iiwa + WSG 50."""

import dataclasses

import numpy as np
import pytest

from conftest import ycb_dir_or_skip
from pickplan.core import objects, robots
from pickplan.core.description import load_description, robot_info, shipped_name
from pickplan.core.robots import check_description
from pickplan.core.panda import PANDA
from pickplan.core.timing import robot_limits
from pickplan.omg import grasps as G
from pickplan.omg.grasps import physics
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanStatus
from pickplan.omg.world import WorldSettings
from pickplan.sim import scenes
from pickplan.sim.execution import ExecutionSettings, ExecutionStatus, execute_plan

OTHERS = ("ur5_2f85", "iiwa_wsg50")


def _local(points, frame):
    return (np.linalg.inv(frame) @ np.c_[points, np.ones(len(points))].T).T[:, :3]


def test_short_names_and_the_robot_a_description_builds():
    assert shipped_name("iiwa") == "iiwa_wsg50" and shipped_name("ur5") == "ur5_2f85"
    with pytest.raises(FileNotFoundError, match="no shipped robot 'kuka'"):
        robots.load_robot("kuka")
    for name, dof in (("panda", 9), ("ur5", 8), ("iiwa", 9)):
        robot = robots.load_robot(name)
        desc = load_description(name)
        assert robot.dof == dof and robot.joint_names[: robot.arm_dof] == list(desc.arm_joints)
        assert np.allclose(robot.base_pose, desc.base_pose)
        assert np.allclose(robot.ready_configuration[: robot.arm_dof], desc.start)


def test_the_timing_limits_are_the_descriptions():
    for name in ("ur5_2f85", "iiwa_wsg50", "panda"):
        robot, desc = robots.load_robot(name), load_description(name)
        limits = robot_limits(robot)
        assert np.allclose(limits.velocity[: robot.arm_dof], desc.velocity_limits)
        assert np.allclose(limits.acceleration[: robot.arm_dof], desc.acceleration_limits)
        assert len(limits.velocity) == robot.dof


@pytest.mark.parametrize("name", OTHERS)
def test_derived_pads_lie_on_the_inner_finger_faces(name):
    """The URDFs' finger boxes put the open pads' inner faces at +-max_opening / 2 of the grasp frame."""
    robot = robots.load_robot(name)
    c = G.hand_contacts(robot=robot)
    local = _local(c.points, robot.grasp_frame)
    half = robot.info.max_opening / 2
    assert np.allclose(np.abs(local[:, 1]), half, atol=1e-6)
    assert np.abs(local[:, 2]).max() <= robot.info.pad_length / 2
    assert set(np.unique(c.finger)) == {0, 1}
    # the normals point across the gap, to the other finger
    assert np.allclose(_local(c.points + 0.01 * c.normals, robot.grasp_frame)[:, 1] * np.sign(local[:, 1]), half - 0.01)
    closed = c.at(robot.info.finger_closed)  # closing moves each pad by the joint travel towards the middle
    inner = half - abs(robot.info.finger_travel)
    assert np.allclose(_local(closed.points, robot.grasp_frame)[:, 1] * np.sign(local[:, 1]), inner, atol=1e-6)


def test_converted_grasps_keep_the_grasp_frame_and_drop_what_does_not_fit():
    model = objects.library().get("005_tomato_soup_can")  # in the built-ins and the YCB folder; fits every gripper
    panda_set = G.grasp_set(model, "antipodal", n=20, seed=0)
    assert len(panda_set) == 20
    for name in OTHERS:
        info = robot_info(name)
        out = G.convert_grasps(panda_set, model, info)  # no hand check: a pure change of frames
        kept = out.info["source_index"]
        assert len(out) == len(panda_set)  # both open wider than the Panda
        assert np.allclose(out.poses @ info.grasp_frame, panda_set.poses[kept] @ PANDA.grasp_frame, atol=1e-9)
    narrow = dataclasses.replace(PANDA, max_opening=0.02)  # a 2 cm gripper keeps only what is narrower
    width = panda_set.info["width"]
    out = G.convert_grasps(panda_set, model, narrow)
    assert len(out) < len(panda_set)
    assert np.all(width[out.info["source_index"]] <= 0.02)


def test_stored_ycb_grasps_convert_and_clear_the_object():
    ycb = ycb_dir_or_skip()
    model = objects.library(ycb).get("005_tomato_soup_can")
    info = robot_info("ur5_2f85")
    gs = G.grasp_set(model, "simulated", gripper=info)
    assert len(gs) == 100  # the 2F-85 opens wider than the Panda: every stored grasp fits
    frames = gs.poses @ info.grasp_frame  # the stored grasp frames, some backed off along the approach
    stored = G.grasp_set(model, "simulated").poses[gs.info["source_index"]] @ PANDA.grasp_frame
    back = np.einsum("nij,ni->nj", frames[:, :3, :3], stored[:, :3, 3] - frames[:, :3, 3])
    assert np.allclose(frames[:, :3, :3], stored[:, :3, :3]) and np.allclose(back[:, :2], 0.0, atol=1e-9)
    assert np.all((back[:, 2] > -1e-9) & (back[:, 2] <= info.pad_length / 2 + 1e-9))


@pytest.mark.parametrize("name", OTHERS)
def test_generated_grasps_are_this_grippers_and_lift_in_pybullet(name):
    """Antipodal grasps generated for the gripper centre its grasp frame on the contact pair, closing
    along y; its open hand clears the object; PyBullet closes this gripper on them and lifts the object."""
    info = robot_info(name)
    model = objects.library().get("005_tomato_soup_can")  # built-in or YCB: a can both grippers span
    gs = G.grasp_set(model, "antipodal", n=6, seed=0, gripper=info)
    assert len(gs) == 6
    frames = gs.poses @ info.grasp_frame
    mid = gs.info["contacts"].mean(axis=1)
    assert np.allclose(frames[:, :3, 3], mid, atol=1e-9)
    axis = gs.info["contacts"][:, 1] - gs.info["contacts"][:, 0]
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    assert np.allclose(np.abs(np.einsum("nji,nj->ni", frames[:, :3, :3], axis)[:, 1]), 1.0, atol=1e-9)
    assert not G.HandObjectChecker(model, 0.0, info).in_collision(gs.poses).any()
    lifted = physics.lift_test(model, gs.poses[:4], gripper=info)
    assert (lifted == 1).sum() >= 2, lifted


def test_the_planner_takes_a_robot_and_refuses_a_bare_urdf_model():
    scene = scenes.generate_scene(seed=1)
    planner = OMGPlanner("iiwa", scene, OMGSettings())
    assert planner.world().robot.info.name == "iiwa_wsg50"
    assert planner.world().start.tolist() == list(robots.load_robot("iiwa").ready_configuration)
    bare = robots.Robot.from_urdf(load_description("panda").urdf)
    with pytest.raises(ValueError, match="no gripper"):
        OMGPlanner(bare, scene)
    with pytest.raises(ValueError, match=r"\(T, 8\).*ur5_2f85"):
        execute_plan(scene, np.zeros((3, 9)), ExecutionSettings(robot="ur5"))


@pytest.mark.parametrize("name, seed", [("ur5_2f85", 2), ("iiwa_wsg50", 1)])
def test_a_demo_sized_plan_executes_and_lifts(name, seed):
    scene = scenes.generate_scene(seed=seed)
    settings = OMGSettings(grasp_kind="antipodal", world=WorldSettings(robot=name))
    result = OMGPlanner(None, scene, settings).plan()
    assert result.status == PlanStatus.success
    assert result.trajectory.shape[1] == robots.load_robot(name).dof
    timed = result.timed(rate=240.0)  # within this robot's limits
    limits = robot_limits(robots.load_robot(name))
    assert np.all(np.abs(timed.qd) <= limits.velocity * (1 + 1e-6))
    run = execute_plan(scene, result.trajectory, ExecutionSettings(robot=name))
    assert run.status == ExecutionStatus.lifted, run.message
    assert run.target_lift > 0.1


def test_the_validator_names_an_approach_axis_that_is_not_the_hands_z(tmp_path):
    text = open(load_description("iiwa_wsg50").source).read()
    path = tmp_path / "tilted.toml"
    path.write_text(
        text.replace(
            "grasp_frame = { xyz = [0.0, 0.0, 0.11], rpy = [0.0, 0.0, 0.0] }",
            "grasp_frame = { xyz = [0.0, 0.0, 0.11], rpy = [0.0, 0.3, 0.0] }",
        ).replace('mount]\nurdf = "assets:', 'mount]\nurdf = "assets:')
    )
    _, problems = check_description(str(path))
    assert any("z axis (the approach) must be the hand link's +z" in str(p) for p in problems), problems


def test_a_sweep_plans_for_its_robot_and_will_not_resume_with_another(tmp_path):
    from pickplan.eval.experiments import SweepSettings, check_resumable, make_units

    scenes.generate_scene(seed=1).save(str(tmp_path / "scene_0000.json"))
    s = SweepSettings(
        "planners", out=str(tmp_path / "out"), scene_dir=str(tmp_path), runs=1, methods=("OMG",), robot="iiwa"
    )
    units = make_units(s, [str(tmp_path / "scene_0000.json")])
    assert [u["robot"] for u in units] == ["iiwa"]
    check_resumable(s)
    with pytest.raises(ValueError, match="robot: 'iiwa' there, 'ur5' now"):
        check_resumable(dataclasses.replace(s, robot="ur5"))


def test_the_robots_grasps_command_counts_what_converts(capsys):
    from pickplan.cli.main import main as cli_main

    assert cli_main(["robots", "grasps", "ur5", "--objects", ycb_dir_or_skip()]) == 0
    out = capsys.readouterr().out
    assert "| 005_tomato_soup_can | 100 | 100 (100 %) |" in out and "kept for ur5_2f85" in out
