"""Robot descriptions at the door (issue 39): every wrong file is an InputError naming the
description file and the field, `pickplan robots check` and every command that loads a robot
(`load_robot`, `demo --robot`) agree on every file, and values outside a real robot's ranges are
refused. Each case here was an internal error (exit 3) or accepted before."""

import os
import re

import numpy as np
import pytest

from pickplan.cli.main import main as cli_main
from pickplan.core import description as D
from pickplan.core.errors import InputError
from pickplan.core.robots import check_description, load_robot

PANDA_TEXT = open(D.description_path("panda")).read()
UR5_TEXT = open(D.description_path("ur5_2f85")).read()
PANDA_URDF = D.load_description("panda").urdf


def _toml(tmp_path, text, name="robot.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _with_urdf(tmp_path, urdf_text, name="arm.urdf"):
    """The Panda's description naming a URDF of ``urdf_text`` (its meshes from pybullet_data)."""
    urdf = tmp_path / name
    urdf.write_text(urdf_text)
    return _toml(
        tmp_path,
        PANDA_TEXT.replace(
            'urdf = "pybullet_data:franka_panda/panda.urdf"',
            f'urdf = "{urdf}"\npackage_dirs = ["pybullet_data:franka_panda"]',
        ),
    )


def _panda_urdf(tmp_path, old, new, count=1):
    text = open(PANDA_URDF).read()
    assert old in text
    return _with_urdf(tmp_path, text.replace(old, new, count))  # package:// meshes from package_dirs


def _refused(path, field, words):
    """Both paths refuse the file, naming it and the field; the same problems."""
    desc, problems = check_description(path)
    assert any(p.field == field and re.search(words, p.message) for p in problems), [str(p) for p in problems]
    with pytest.raises(InputError) as err:
        load_robot(path)
    assert err.value.problems == tuple(problems)
    assert all(p.path == path for p in err.value.problems)
    assert str(err.value).startswith(f"{path}: ")
    return problems


def test_a_urdf_that_is_malformed_xml_or_not_xml_is_named(tmp_path):
    """Was a ParseError (exit 3) in `robots check` and `demo --robot`."""
    _refused(
        _with_urdf(tmp_path, '<?xml version="1.0"?>\n<robot name="x"><link name="a">'),
        "urdf",
        "arm.urdf is not well-formed XML",
    )
    _refused(_with_urdf(tmp_path, "\x00\x01binary \xff garbage"), "urdf", "arm.urdf is not well-formed XML")
    _refused(_with_urdf(tmp_path, '<?xml version="1.0"?>\n<html><body/></html>'), "urdf", "not a URDF: .*<html>")
    gripper = tmp_path / "gripper.urdf"  # a mounted gripper's URDF: was parsed as XML unchecked (ParseError)
    gripper.write_text('<robot name="g"><link name="palm"></robot>')
    _refused(
        _toml(tmp_path, UR5_TEXT.replace('urdf = "assets:robots/robotiq_2f85.urdf"', f'urdf = "{gripper}"')),
        "mount.urdf",
        "gripper.urdf is not well-formed XML",
    )


def test_a_mesh_file_or_a_link_given_twice_is_named(tmp_path):
    path = _panda_urdf(tmp_path, '<mesh filename="', '<mesh filename="a.obj" filename="')
    _refused(path, "urdf", "duplicate attribute")
    path = _panda_urdf(tmp_path, '<link name="panda_link2">', '<link name="panda_link1">')
    _refused(path, "urdf", r"link names given more than once: \['panda_link1'\]")


def test_joint_limits_of_1e308_are_refused_before_an_ik_seed_overflows(tmp_path):
    """Limits of +-1e308 made the IK seed (uniform in the limits) infinite, named nowhere."""
    path = _panda_urdf(tmp_path, 'lower="-2.9671" upper="2.9671"', 'lower="-1e308" upper="1e308"')
    _refused(path, "urdf", r"joint panda_joint1's limits \[-1e\+308, 1e\+308\] are not within")


def test_arm_motor_forces_outside_a_real_joints_are_refused(tmp_path):
    """Execution drives the arm with the URDF's effort limits: 0 N m or 1e308 N m is not a motor."""
    for effort in ("0", "1e308"):
        path = _panda_urdf(tmp_path, '<limit effort="87" lower="-2.9671"', f'<limit effort="{effort}" lower="-2.9671"')
        _refused(path, "urdf", f"joint panda_joint1's effort limit '{effort}' is not within")


@pytest.mark.parametrize(
    "old, new, field, words",
    [
        ("velocity = [2.175,", "velocity = [1e-300,", "limits.velocity[0]", r"1e-300 rad/s is outside \[0.01, 50.0\]"),
        ("acceleration = [15.0,", "acceleration = [1e308,", "limits.acceleration[0]", "is outside"),
        ("jerk = [7500.0,", "jerk = [1e308,", "limits.jerk[0]", "is outside"),
        ("finger_acceleration = 1.0", "finger_acceleration = 1e308", "limits.finger_acceleration", "is outside"),
        ("pad = { length = 0.018,", "pad = { length = -0.018,", "gripper.pad.length", r"-0.018 m is outside"),
        ("width = 0.02,", "width = 0.0,", "gripper.pad.width", r"0.0 m is outside \[0.001, 0.2\]"),
        ("friction = 1.0 }", "friction = -1.0 }", "gripper.pad.friction", "expected a positive number"),
        ("force = 70.0", "force = 0.0", "gripper.force", "expected a positive number"),
        ("force = 70.0", "force = 1e9", "gripper.force", "is outside"),
        ("speed = 0.1 ", "speed = -0.1 ", "gripper.speed", "expected a positive number"),
        ("max_opening = 0.08", "max_opening = 1e9", "gripper.max_opening", "is outside"),
        (
            "body_points_per_link = 20",
            "body_points_per_link = 1000000000",
            "body_points_per_link",
            r"expected an integer in \[1, 1000\]",
        ),
        ("start = [0.0, -1.285", "start = [1e308, -1.285", "start[0]", "is outside"),
        ("xyz = [0.0, 0.0, 0.1034]", "xyz = [0.0, 0.0, 1e300]", "gripper.grasp_frame.xyz[2]", "is outside"),
        ("max_opening = 0.08", 'max_opening = "wide"', "gripper.max_opening", "expected a number, got str 'wide'"),
    ],
)
def test_values_outside_a_real_robots_ranges_are_refused(tmp_path, old, new, field, words):
    """A velocity limit of 1e-300 passed `robots check` and overflowed toppra; 1e308 accelerations,
    a negative pad, a zero pad width and 10^9 body points per link (a field the planner never
    read) were accepted."""
    assert old in PANDA_TEXT
    _refused(_toml(tmp_path, PANDA_TEXT.replace(old, new, 1)), field, words)


def test_a_description_without_pads_is_refused(tmp_path):
    _refused(
        _toml(tmp_path, PANDA_TEXT.replace("pad = { length = 0.018, width = 0.02, friction = 1.0 }", "")),
        "gripper.pad",
        "missing",
    )


@pytest.mark.parametrize(
    "old, new, field",
    [
        ('["panda_hand", "panda_rightfinger"]', '["panda_hand", "no_such_link"]', "skip_collision"),
        ('hand_link = "panda_hand"', 'hand_link = "panda_palm"', "gripper.hand_link"),
        (
            '{ name = "panda_finger_joint2", open = 0.04',
            '{ name = "panda_finger_joint2", open = 0.03',
            "gripper.finger_joints",
        ),
    ],
)
def test_robots_check_and_demo_agree_by_construction(tmp_path, capsys, old, new, field):
    """`robots check` named links that do not exist while `demo --robot` planned with the file (and
    finger joints of two open values the other way round)."""
    path = _toml(tmp_path, PANDA_TEXT.replace(old, new, 1))
    _refused(path, field, ".")
    assert cli_main(["robots", "check", path]) == 2
    for command in (["demo"], ["scenes", "--n", "1"]):  # refused at the door, before a scene is made for it
        assert cli_main(command + ["--robot", path, "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert f"{path}: " in err and f"{field}: " in err and "internal error" not in err
        assert not os.path.exists(tmp_path / "out")


def test_errors_name_the_users_files_not_the_composed_urdf(tmp_path):
    """A mounted gripper's URDF is composed into a temporary file: errors named that file."""
    gripper = tmp_path / "gripper.urdf"
    text = open(os.path.join(D.assets_dir(), "robots", "robotiq_2f85.urdf")).read()
    gripper.write_text(text.replace('<limit lower="0" upper="0.0425"', '<limit lower="1" upper="0.0425"', 1))
    path = _toml(tmp_path, UR5_TEXT.replace('urdf = "assets:robots/robotiq_2f85.urdf"', f'urdf = "{gripper}"'))
    problems = _refused(path, "mount.urdf", "gripper.urdf")
    assert not any("pickplan-" in str(p) or "/robots/robot-" in str(p) for p in problems), problems


def test_the_planner_reads_the_descriptions_body_point_density(tmp_path):
    """body_points_per_link was read from the file and never used (the planner took 20)."""
    from pickplan.omg.world import World, WorldSettings
    from pickplan.sim import scenes

    path = _toml(tmp_path, PANDA_TEXT.replace("body_points_per_link = 20", "body_points_per_link = 3"))
    world = World(scenes.generate_scene(seed=1), WorldSettings(robot=path))
    counts = np.bincount(world.body.links)
    assert counts.max() == 3 and len(world.body) == 3 * np.count_nonzero(counts)
    assert len(World(scenes.generate_scene(seed=1)).body) == 20 * np.count_nonzero(counts)


def test_every_problem_of_a_file_is_named_at_once(tmp_path):
    text = (
        PANDA_TEXT.replace("max_opening = 0.08", "max_opening = -1.0")
        .replace("velocity = [2.175,", "velocity = [0.0,")
        .replace('hand_link = "panda_hand"', 'hand_link = "x"')
    )
    problems = _refused(_toml(tmp_path, text), "gripper.max_opening", "is outside")
    fields = {p.field for p in problems}
    assert {"gripper.max_opening", "limits.velocity[0]", "gripper.hand_link"} <= fields, fields


def test_the_shipped_descriptions_pass_the_door():
    for name in D.shipped():
        assert check_description(name)[1] == []
        assert load_robot(name).description.name == name
