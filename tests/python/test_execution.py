"""Executing plans in PyBullet: hand-made grasp trajectories (no planner), independent of pickplan's IK.

The grasps are built here from the object meshes (top-down, fingers across the narrowest width of
the footprint) and solved with a small damped-least-squares IK on ``Robot.jacobian``; the trajectory
is start -> pre-grasp 10 cm above -> grasp by linear joint interpolation.
"""

import struct

import numpy as np
import pytest

from pickplan.sim import execution
from pickplan.sim import lift as lift_mod
from pickplan.core import objects
from pickplan.core import robots
from pickplan.sim import scenes

GRASP_DEPTH = 0.105  # panda_hand origin -> the point between the finger pads (panda_grasptarget)
SEED_CAN, CAN = 5, "005_tomato_soup_can"  # an upside-down can with free space around it
OBSTACLE = "010_potted_meat_can"  # in the same scene, between the robot and the can


# --- helpers: grasps and IK built for the test -----------------------------------------------------
def top_down_grasp(scene, name, offset=(0.0, 0.0), depth=0.025):
    """Hand pose (4x4) above the footprint centre, z down, fingers (hand y) across the narrowest width.

    Returns the pose, the width across the fingers and the horizontal direction across them.
    """
    o = scene.object(name)
    model = objects.model_from_source(o.name, o.source)
    V = np.asarray(model.mesh.convex_hull.vertices) @ o.pose[:3, :3].T + o.pose[:3, 3]
    dirs = [np.array([np.cos(t), np.sin(t)]) for t in np.radians(np.arange(0.0, 180.0, 3.0))]
    width, d = min(((np.ptp(V[:, :2] @ u), i) for i, u in enumerate(dirs)))
    d = dirs[d]
    perp = np.array([-d[1], d[0]])
    a, b = V[:, :2] @ d, V[:, :2] @ perp
    c = d * (a.min() + a.max()) / 2 + perp * (b.min() + b.max()) / 2
    y = np.array([d[0], d[1], 0.0]) * (-1.0 if d[1] > 0 else 1.0)  # hand y near -y, like the ready pose
    z = np.array([0.0, 0.0, -1.0])
    T = np.eye(4)
    T[:3, :3] = np.column_stack([np.cross(y, z), y, z])
    grasp_point = [c[0] + offset[0], c[1] + offset[1], max(V[:, 2].max() - depth, 0.02)]
    T[:3, 3] = np.array(grasp_point) - GRASP_DEPTH * z
    return T, float(width), np.array([y[0], y[1]])


def ik(robot, T_goal, q0, iters=400, lam=0.05):
    hand = robot.link_index("panda_hand")
    q = np.array(q0, dtype=float)
    for _ in range(iters):
        T = robot.fk(q)[hand]
        err = np.concatenate([T_goal[:3, 3] - T[:3, 3], 0.5 * sum(np.cross(T[:3, i], T_goal[:3, i]) for i in range(3))])
        if np.linalg.norm(err) < 1e-6:
            break
        J = robot.jacobian(q, hand, None)[:, :7]
        dq = J.T @ np.linalg.solve(J @ J.T + lam**2 * np.eye(6), err)
        dq *= min(1.0, 0.2 / max(np.linalg.norm(dq), 1e-12))
        q[:7] = np.clip(q[:7] + dq, robot.lower_limits[:7], robot.upper_limits[:7])
    T = robot.fk(q)[hand]
    assert np.linalg.norm(T[:3, 3] - T_goal[:3, 3]) < 1e-4 and np.allclose(T[:3, :3], T_goal[:3, :3], atol=1e-3)
    return q


def lerp(a, b, n):
    return [a + (b - a) * t for t in np.linspace(0.0, 1.0, n)[1:]]


def grasp_trajectory(robot, scene, name, offset=(0.0, 0.0), via_pose=None):
    q0 = np.array(scene.robot_configuration, dtype=float)
    T, _, _ = top_down_grasp(scene, name, offset)
    pre = T.copy()
    pre[2, 3] += 0.10
    Q, q = [q0], q0
    if via_pose is not None:
        q_via = ik(robot, via_pose, q0)
        Q += lerp(q0, q_via, 15)
        q = q_via
    q_pre = ik(robot, pre, q)
    q_grasp = ik(robot, T, q_pre)
    return np.array(Q + lerp(q, q_pre, 20) + lerp(q_pre, q_grasp, 10))


# --- fixtures ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def robot():
    return robots.panda()


@pytest.fixture(scope="module")
def can_scene():
    # the built-ins whatever $PICKPLAN_YCB_DIR says: the scene and its free space are chosen for them
    scene = scenes.generate_scene(SEED_CAN, objects.library("builtin"))
    scene.target = CAN
    return scene


@pytest.fixture(scope="module")
def can_plan(robot, can_scene):
    return grasp_trajectory(robot, can_scene, CAN)


@pytest.fixture(scope="module")
def can_result(can_scene, can_plan):
    return execution.execute_plan(can_scene, can_plan)


def _com_height(scene, name):
    o = scene.object(name)
    m = objects.model_from_source(o.name, o.source)
    return float((o.pose[:3, :3] @ m.com + o.pose[:3, 3])[2])


# --- success -------------------------------------------------------------------------------------
def test_top_down_grasp_lifts_the_can(can_scene, can_result):
    r, s = can_result, execution.ExecutionSettings()
    assert r.success and r.status == "lifted", r.message
    assert r.held and r.target_lift >= 0.9 * s.lift_height
    assert r.target_lift <= s.lift_height + 0.02
    # the fingers rest on the can: the gap is its diameter (68 mm), not closed, not open
    assert 0.060 < r.finger_gap < 0.075
    assert r.contacts_during_approach == {} and not r.collided and r.max_penetration == 0.0
    assert set(r.object_displacements) == {o.name for o in can_scene.objects} - {CAN}
    assert max(r.object_displacements.values()) < 0.005
    assert r.target_pushed < 0.005 and r.tracking_error < 0.05
    o = can_scene.object(CAN)
    assert r.target_final_pose.shape == (4, 4)
    assert r.target_final_pose[2, 3] - o.pose[2, 3] == pytest.approx(r.target_lift, abs=0.01)
    assert r.steps > 0 and r.sim_time == pytest.approx(r.steps / 240.0) and r.seconds > 0
    assert r.frames == [] and r.to_dict()["status"] == "lifted"


def test_box_grasp_lifts_the_box(robot):
    scene = scenes.generate_scene(2)
    scene.target = "004_sugar_box"
    r = execution.execute_plan(scene, grasp_trajectory(robot, scene, scene.target))
    assert r.success and r.status == "lifted", r.message
    assert r.target_lift >= 0.9 * execution.ExecutionSettings().lift_height
    _, width, _ = top_down_grasp(scene, scene.target)
    assert r.finger_gap == pytest.approx(width, abs=0.008)


def test_deterministic(can_scene, can_plan, can_result):
    again = execution.execute_plan(can_scene, can_plan).to_dict()
    first = can_result.to_dict()
    first.pop("seconds"), again.pop("seconds")
    assert again == first


# --- failures ------------------------------------------------------------------------------------
def test_grasp_10cm_to_the_side_misses(robot, can_scene):
    _, _, across = top_down_grasp(can_scene, CAN)
    beside = 0.10 * np.array([-across[1], across[0]])  # along the pads: both fingers land beside the can
    r = execution.execute_plan(can_scene, grasp_trajectory(robot, can_scene, CAN, offset=beside))
    assert not r.success and r.status in ("missed", "dropped"), (r.status, r.message)
    assert abs(r.target_lift) < 0.01 and not r.held
    assert not r.collided


def test_arm_driven_through_another_object_reports_contact(robot, can_scene):
    through, _, _ = top_down_grasp(can_scene, OBSTACLE)
    through[2, 3] -= 0.06  # fingers 6 cm into the obstacle
    Q = grasp_trajectory(robot, can_scene, CAN, via_pose=through)
    r = execution.execute_plan(can_scene, Q)
    assert OBSTACLE in r.contacts_during_approach
    assert r.contacts_during_approach[OBSTACLE] > 0.002 and r.collided
    assert r.max_penetration == max(r.contacts_during_approach.values())
    assert r.object_displacements[OBSTACLE] > 0.01
    assert CAN not in r.contacts_during_approach


def test_start_in_collision_runs_and_reports(robot, can_scene):
    inside, _, _ = top_down_grasp(can_scene, OBSTACLE)
    inside[2, 3] -= 0.06
    q_in = ik(robot, inside, can_scene.robot_configuration)
    r = execution.execute_plan(can_scene, np.array([q_in] + [q_in] * 3))
    assert r.status in execution.STATUSES and r.steps > 0
    assert OBSTACLE in r.contacts_during_approach and r.collided
    assert r.status == "collision" and not r.success


def test_out_of_limits_is_an_invalid_trajectory(can_scene, can_plan):
    Q = can_plan.copy()
    Q[3, 3] = 0.5  # joint 4 must stay <= 0
    r = execution.execute_plan(can_scene, Q)
    assert r.status == "invalid_trajectory" and not r.success and r.steps == 0
    assert "waypoint 3" in r.message and "panda_joint4" in r.message


# --- bad input -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "bad, words",
    [
        (np.zeros((5, 7)), "(T, 9)"),
        (np.zeros(9), "(T, 9)"),
        (np.zeros((0, 9)), "at least one"),
        ([[0.0] * 9, [0.0] * 8], "trajectory"),
        ("abc", "trajectory"),
    ],
)
def test_bad_shapes_raise(can_scene, bad, words):
    with pytest.raises(ValueError, match="trajectory") as info:
        execution.execute_plan(can_scene, bad)
    assert words in str(info.value)


def test_nan_raises_with_its_position(can_scene, can_plan):
    Q = can_plan.copy()
    Q[4, 2] = np.nan
    with pytest.raises(ValueError, match=r"NaN or infinity \(first at waypoint 4, joint 2\)"):
        execution.execute_plan(can_scene, Q)


def test_bad_settings_raise():
    with pytest.raises(ValueError, match="arm_forces"):
        execution.ExecutionSettings(arm_forces=(87.0,) * 6)
    with pytest.raises(ValueError, match="lift_duration"):
        execution.ExecutionSettings(lift_duration=0.0)
    with pytest.raises(ValueError, match="RecordSettings"):
        execution.RecordSettings(every=0)


# --- recording -----------------------------------------------------------------------------------
def test_recorded_frames_and_files(tmp_path, can_scene, can_plan, can_result):
    rec = execution.RecordSettings(every=120, width=96, height=72)
    r = execution.execute_plan(can_scene, can_plan, record=rec)
    # recording paints the objects and renders; the physics is the same
    assert r.status == can_result.status and r.target_lift == can_result.target_lift
    assert len(r.frames) == 1 + r.steps // 120 + (r.steps % 120 != 0)
    assert all(f.shape == (72, 96, 3) and f.dtype == np.uint8 for f in r.frames)
    assert not np.array_equal(r.frames[0], r.frames[-1])  # the arm moved
    png = tmp_path / "sheet.png"
    execution.save_frames(r.frames, str(png), columns=4)
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    rows = -(-len(r.frames) // 4)
    assert struct.unpack(">II", data[16:24]) == (4 * 96, rows * 72)
    gif = tmp_path / "run.gif"
    execution.save_gif(r.frames, str(gif), fps=10)
    from PIL import Image  # installed with matplotlib; used only to check the GIF decodes

    with Image.open(gif) as im:
        assert im.size == (96, 72) and im.n_frames == len(r.frames)
        im.seek(len(r.frames) - 1)
        decoded = np.asarray(im.convert("RGB"), dtype=int)
    assert np.abs(decoded - r.frames[-1]).max() <= 26  # half a palette step
    with pytest.raises(ValueError, match="no frames"):
        execution.save_frames([], str(png))


def test_lift_path_raises_the_hand_straight_up_with_the_native_ik(robot):
    """The lift's joint targets (native damped least squares): FK of each waypoint puts the hand
    lift_height * k / lift_waypoints above its start, orientation held, fingers untouched."""
    s = execution.ExecutionSettings()
    q0 = np.array(robot.ready_configuration, dtype=float)
    path = lift_mod.lift_path(robot, q0, s)
    assert path.shape == (s.lift_waypoints + 1, robot.dof)
    hand = robot.link_index("panda_hand")
    T0, poses = robot.fk(q0)[hand], robot.fk_batch(path)[:, hand]
    rise = s.lift_height * np.arange(s.lift_waypoints + 1) / s.lift_waypoints
    np.testing.assert_allclose(poses[:, :3, 3], T0[:3, 3] + np.outer(rise, [0.0, 0.0, 1.0]), atol=1e-4)
    np.testing.assert_allclose(poses[:, :3, :3], np.broadcast_to(T0[:3, :3], poses[:, :3, :3].shape), atol=1e-3)
    np.testing.assert_array_equal(path[:, 7:], np.broadcast_to(q0[7:], path[:, 7:].shape))
    assert np.all(path >= robot.lower_limits) and np.all(path <= robot.upper_limits)
