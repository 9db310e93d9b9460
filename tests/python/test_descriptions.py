"""Robot descriptions: the shipped ones describe their robots truly (kinematics against PyBullet, the
grasp frame between the pads), and a wrong file gets every problem named, never a crash."""

import numpy as np
import pybullet as pb
import pytest

from pickplan.cli.main import main as cli_main
from pickplan.core import description as D
from pickplan.core.description_check import _pad_gap, start_configuration
from pickplan.core.panda import PANDA
from pickplan.core.robots import check_description, robot_for

SHIPPED = ("iiwa_wsg50", "panda", "ur5_2f85")


def test_the_three_robots_are_shipped_and_valid():
    assert set(SHIPPED) <= set(D.shipped())
    for name in SHIPPED:
        desc, problems = check_description(name)
        assert problems == [], (name, problems)
        assert len(desc.velocity_limits) == len(desc.arm_joints) == len(desc.start)


@pytest.mark.parametrize("name", SHIPPED)
def test_forward_kinematics_match_pybullet(name):
    desc = D.load_description(name)
    robot = robot_for(desc)
    client = pb.connect(pb.DIRECT)
    try:
        T = desc.base_pose
        w, x, y, z = _quat_wxyz(T[:3, :3])
        body = pb.loadURDF(desc.urdf, T[:3, 3].tolist(), [x, y, z, w], useFixedBase=True, physicsClientId=client)
        joints = {
            pb.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
            for j in range(pb.getNumJoints(body, physicsClientId=client))
        }
        links = {pb.getJointInfo(body, j, physicsClientId=client)[12].decode(): j for j in joints.values()}
        rng = np.random.default_rng(3)
        for _ in range(5):
            lo = np.maximum(robot.lower_limits, -np.pi)
            hi = np.minimum(robot.upper_limits, np.pi)
            q = rng.uniform(lo, hi)
            for name_j, value in zip(robot.joint_names, q):
                pb.resetJointState(body, joints[name_j], value, physicsClientId=client)
            poses = robot.fk(q)
            for link, j in links.items():
                state = pb.getLinkState(body, j, computeForwardKinematics=True, physicsClientId=client)
                pos, quat = np.array(state[4]), np.array(state[5])
                ours = poses[robot.link_index(link)]
                np.testing.assert_allclose(ours[:3, 3], pos, atol=1e-6, err_msg=f"{name} {link}")
                R = np.array(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)
                np.testing.assert_allclose(ours[:3, :3], R, atol=1e-6, err_msg=f"{name} {link}")
    finally:
        pb.disconnect(client)


def _quat_wxyz(R):
    w = np.sqrt(max(1.0 + np.trace(R), 1e-12)) / 2
    return w, (R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w)


@pytest.mark.parametrize("name", SHIPPED)
def test_the_grasp_frame_is_centred_between_the_pads_and_y_closes_them(name):
    desc = D.load_description(name)
    robot = robot_for(desc)
    q = start_configuration(desc, robot)
    centre, gap, (z_lo, z_hi) = _pad_gap(desc, robot, q)
    assert abs(centre) < 1e-6 and gap == pytest.approx(desc.gripper.max_opening, abs=0.001)
    assert z_lo < 0 < z_hi
    for f in desc.gripper.finger_joints:  # half-way closed: the gap shrinks, the middle stays
        q[robot.joint_names.index(f.name)] = 0.5 * (f.open + f.closed)
    centre_half, gap_half, _ = _pad_gap(desc, robot, q)
    assert abs(centre_half) < 1e-6 and gap_half == pytest.approx(0.5 * gap, abs=0.002)


def test_the_panda_facts_come_from_its_description():
    desc = D.load_description("panda")
    assert PANDA.ready == tuple(desc.start) + (0.04, 0.04) and PANDA.hand_link == desc.gripper.hand_link
    assert PANDA.pad_depth == desc.gripper.grasp_frame[2, 3]


def _write(tmp_path, text):
    path = tmp_path / "robot.toml"
    path.write_text(text)
    return str(path)


PANDA_TEXT = open(D.description_path("panda")).read()


@pytest.mark.parametrize(
    "change, expected",
    [
        (('hand_link = "panda_hand"', 'hand_link = "panda_palm"'), "'panda_palm' is not a link"),
        (('name = "panda_finger_joint2"', 'name = "panda_joint7"'), "is also an arm joint"),
        (("xyz = [0.0, 0.0, 0.1034]", "xyz = [0.0, 0.012, 0.1034]"), "not between the pads"),
        (("xyz = [0.0, 0.0, 0.1034]", "xyz = [0.0, 0.0, 0.3]"), "not level with the pads"),
        (("max_opening = 0.08", "max_opening = 0.12"), "pads are 0.0797 m apart"),
        (("body_points_per_link = 20", 'body_points_per_link = 20\ncolour = "red"'), "colour: unknown key"),
        (("start = [0.0, -1.285", "start = [nan, -1.285"), "start[0]: expected a finite number, got nan"),
        (
            ("start = [0.0, -1.285, 0.0, -2.356, 0.0, 1.571, 0.785]", "start = [0.0, -1.285]"),
            "start: expected a list of 7 numbers, got 2 values",
        ),
        (("start = [0.0, -1.285", "start = [9.0, -1.285"), "panda_joint1 = 9.0 outside its limits"),
        (('urdf = "pybullet_data:franka_panda/panda.urdf"', 'urdf = "missing.urdf"'), "urdf: file not found"),
        (("max_opening = 0.08", 'max_opening = "wide"'), "max_opening: expected a number, got str 'wide'"),
        (("[gripper]", "[gripper\n"), "not valid TOML"),
    ],
)
def test_a_wrong_file_names_its_problem(tmp_path, change, expected):
    old, new = change
    assert old in PANDA_TEXT
    desc, problems = check_description(_write(tmp_path, PANDA_TEXT.replace(old, new, 1)))
    assert any(expected in str(p) for p in problems), [str(p) for p in problems]


def test_a_fixed_finger_joint_is_named(tmp_path):
    urdf = tmp_path / "panda_fixed.urdf"
    text = open(D.load_description("panda").urdf).read()
    text = text.replace(
        '<joint name="panda_finger_joint2" type="prismatic">', '<joint name="panda_finger_joint2" type="fixed">'
    )
    urdf.write_text(text)
    path = _write(
        tmp_path,
        PANDA_TEXT.replace(
            'urdf = "pybullet_data:franka_panda/panda.urdf"',
            f'urdf = "{urdf}"\npackage_dirs = ["pybullet_data:franka_panda"]',
        ),
    )
    _, problems = check_description(path)
    assert any("'panda_finger_joint2' is fixed, expected prismatic or revolute" in str(p) for p in problems), problems


def test_the_robots_command_lists_and_checks(tmp_path, capsys):
    assert cli_main(["robots", "list"]) == 0
    out = capsys.readouterr().out
    assert all(name in out for name in SHIPPED) and "problem" not in out
    bad = _write(
        tmp_path,
        PANDA_TEXT.replace('hand_link = "panda_hand"', 'hand_link = "nothing"').replace(
            "max_opening = 0.08", "max_opening = -1.0"
        ),
    )
    assert cli_main(["robots", "check", bad]) == 2
    out = capsys.readouterr().out
    assert "'nothing' is not a link" in out and "gripper.max_opening: -1.0 m is outside (0.0, 0.5] m" in out
    assert cli_main(["robots", "check", "ur5_2f85"]) == 0
