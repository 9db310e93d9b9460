"""The ROS 2 node over real DDS: `pickplan ros serve` in its own process, this test the client, on a
private domain over shared memory only (Fast DDS, no socket: checked). The client publishes depth
images rendered from a scene (two cameras: 32FC1 metres and 16UC1 millimetres), their camera info
and the joint states, clicks a point on the target, calls the service, and executes the trajectory
it receives in PyBullet on the true objects: the target is lifted. Every kind of bad message gets
a failed response naming it, and the next good request is answered."""

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from pickplan.core import robots
from pickplan.core.timing import TimedTrajectory, robot_limits
from pickplan.sim.execution import execute_plan
from pickplan.sim.observe import render_observation
from pickplan.sim.pickplace_exec import PlaceCheck, execute_pick_and_place

from conftest import known_scene, socket_inodes

pytest.importorskip("rclpy", reason="the ros extra is not installed (make install installs it)")

from pickplan.ros import convert  # noqa: E402
from pickplan.ros.extra import Transport, configure_transport  # noqa: E402

ENCODINGS = ("32FC1", "16UC1")


def inet_sockets(pid: int) -> list:
    """The process's UDP and TCP sockets (/proc: its socket inodes in the net tables)."""
    inodes = socket_inodes(pid)
    found = []
    for proto in ("udp", "udp6", "tcp", "tcp6"):
        with open(f"/proc/{pid}/net/{proto}") as f:
            found += [(proto, line.split()[1]) for line in f.readlines()[1:] if line.split()[9] in inodes]
    return found


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


@pytest.fixture(scope="module")
def ros(tmp_path_factory):
    """This process's ROS environment: a private domain, shared memory only; rclpy started."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("ROS_DOMAIN_ID", str(10 + os.getpid() % 90))
        env = dict(os.environ)
        configure_transport(Transport.shm, env)
        for key in ("FASTDDS_DEFAULT_PROFILES_FILE",):
            mp.setenv(key, env[key])
        for key in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY"):
            mp.delenv(key, raising=False)
        yield tmp_path_factory.mktemp("ros")


@pytest.fixture(scope="module")
def scene_and_replay(ros):
    from pickplan.ros.client import PickClient
    from pickplan.ros.replay import ObservationReplay

    scene, lib = known_scene()
    obs = render_observation(scene, views=2)
    robot = robots.load_robot("panda")
    client = PickClient()
    replay = ObservationReplay(client.node, obs, robot, robot.ready_configuration, encodings=ENCODINGS)
    client.node.create_timer(0.2, replay.publish)  # a camera streams: 5 Hz while the client spins
    yield scene, lib, obs, robot, client, replay
    client.close()


@pytest.fixture(scope="module")
def server(ros, scene_and_replay):
    *_, replay = scene_and_replay
    log = open(ros / "node.log", "w")
    cmd = [
        sys.executable,
        "-m",
        "pickplan",
        "ros",
        "serve",
        "--robot",
        "panda",
        "--transport",
        "shm",
        "--ros-args",
        *replay.node_arguments(),
    ]
    proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, env=dict(os.environ))
    try:
        yield proc
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            code = proc.wait()
        log.close()
        assert code == 0, (ros / "node.log").read_text()[-3000:]


@pytest.fixture(scope="module")
def ready(server, scene_and_replay):
    scene, lib, obs, robot, client, replay = scene_and_replay
    assert client.wait_for_server(120.0), "the node did not come up"
    client.spin(1.0)  # discovery of the topics; a few frames published
    return scene_and_replay


def _target_point(scene, lib):
    o = next(o for o in scene.objects if o.name == scene.target)
    mesh = lib.get(o.name).mesh.copy()
    mesh.apply_transform(o.pose)
    return np.array([*mesh.centroid[:2], mesh.bounds[1][2]])  # a point on its top, as a click gives


def test_a_clicked_target_is_planned_timed_and_lifted_in_physics(ready, server):
    scene, lib, obs, robot, client, replay = ready
    replay.click(_target_point(scene, lib))
    client.spin(0.3)
    reply = client.plan()
    assert reply.success, reply.message
    assert reply.trajectory is not None and reply.trajectory.header.frame_id == robot.link_names[0]
    timed = convert.timed_trajectory(reply.trajectory, robot.joint_names)
    np.testing.assert_allclose(timed.q[0], robot.ready_configuration, atol=1e-9)  # from the joint states
    np.testing.assert_allclose(timed.qd[[0, -1]], 0.0, atol=1e-6)  # rest to rest
    limits = robot_limits(robot)
    assert np.all(np.abs(timed.qd) <= limits.velocity * (1 + 1e-3))
    assert np.all(np.abs(timed.qdd) <= limits.acceleration * (1 + 1e-2))
    assert np.all(timed.q >= robot.lower_limits - 1e-9) and np.all(timed.q <= robot.upper_limits + 1e-9)
    executed = execute_plan(scene, timed)
    assert executed.success, (executed.status, executed.message)
    assert executed.target_lift > 0.1
    # nothing but shared memory: the node has no UDP or TCP socket at all
    assert inet_sockets(server.pid) == []


def test_markers_and_status_describe_the_plan(ready):
    from diagnostic_msgs.msg import DiagnosticStatus
    from visualization_msgs.msg import MarkerArray

    from pickplan.ros.node import LATCHED

    scene, lib, obs, robot, client, replay = ready
    arrays, statuses = [], []
    client.node.create_subscription(MarkerArray, "/pickplan/markers", arrays.append, LATCHED)
    client.node.create_subscription(DiagnosticStatus, "/pickplan/status", statuses.append, LATCHED)
    client.spin(0.5)
    arrays.clear()
    point = _target_point(scene, lib)
    reply = client.plan(point=point)
    assert reply.success, reply.message
    end = time.monotonic() + 10
    while not arrays and time.monotonic() < end:
        client.spin(0.05)
    markers = {m.ns: m for m in arrays[-1].markers if m.ns}
    assert set(markers) >= {"field", "target", "goal_set", "chosen_grasp"}
    target = np.array([[p.x, p.y, p.z] for p in markers["target"].points])
    assert np.linalg.norm(target.mean(axis=0)[:2] - point[:2]) < 0.05  # the observed target is the clicked one
    hand = np.array([[p.x, p.y, p.z] for p in markers["chosen_grasp"].points])
    assert np.linalg.norm(hand.mean(axis=0)[:2] - point[:2]) < 0.15  # the chosen hand is at the target
    field = np.array([[p.x, p.y, p.z] for p in markers["field"].points])
    can = next(o for o in scene.objects if o.name != scene.target).pose[:3, 3]
    assert np.min(np.linalg.norm(field[:, :2] - can[:2], axis=1)) < 0.03  # the other object is in the field
    assert statuses and statuses[-1].level == DiagnosticStatus.OK and "success" in statuses[-1].message


def _bad_cases(replay, robot):
    """(name, break it, what the reason names): one malformed input of each kind."""

    def image_field(v, **fields):
        def apply():
            for k, val in fields.items():
                setattr(replay.images[v], k, val)

        return apply

    def nan_depth():
        replay.images[0].data = np.full(replay.images[0].height * replay.images[0].width, np.nan, "<f4").tobytes()

    def info_size():
        replay.infos[1].width = replay.infos[1].width // 2

    def missing_joint():
        replay.joints.name, replay.joints.position = list(robot.joint_names[1:]), list(replay.joints.position[1:])

    def nan_joint():
        replay.joints.position = [float("nan")] + list(replay.joints.position[1:])

    def bad_k():
        replay.infos[0].k = [0.0] * 9

    return [
        ("encoding", image_field(0, encoding="rgb8"), "/cam0/depth/image_rect_raw.encoding"),
        ("short data", image_field(1, data=bytes(replay.images[1].data)[:1000]), "/cam1/depth/image_rect_raw.data"),
        ("step", image_field(0, step=7), "/cam0/depth/image_rect_raw.step"),
        ("nan depth", nan_depth, "view 0 has depth in only 0.0 %"),
        ("info size", info_size, "/cam1/depth/camera_info.width"),
        ("intrinsics", bad_k, "/cam0/depth/camera_info.k"),
        ("missing joint", missing_joint, "joint panda_joint1 missing"),
        ("nan joint", nan_joint, "panda_joint1 is not finite"),
    ]


def _restore(replay, robot, obs):
    for v, (image, encoding) in enumerate(zip(replay.images, ENCODINGS)):
        for k, val in convert.image_fields(np.where(obs.depth[v] > 0, obs.depth[v], np.nan), encoding).items():
            setattr(image, k, val)
    for info, K in zip(replay.infos, obs.K):
        info.width, info.k = replay.images[0].width, convert.camera_info_k(K)
    replay.joints.name = list(robot.joint_names)
    replay.joints.position = [float(v) for v in robot.ready_configuration]


def test_every_bad_message_fails_its_request_and_the_next_good_one_is_answered(ready, server):
    scene, lib, obs, robot, client, replay = ready
    point = _target_point(scene, lib)
    for name, breaks, named in _bad_cases(replay, robot):
        breaks()
        replay.publish()
        client.spin(0.5)
        reply = client.plan(point=point)
        assert not reply.success and reply.trajectory is None, name
        assert named in reply.message, (name, reply.message)
        _restore(replay, robot, obs)
        replay.publish()
        client.spin(0.5)
        assert server.poll() is None, name  # alive
    # targets: a clicked point in another frame, a point near nothing, then the good request
    replay.click(point, frame="camera_link")
    client.spin(0.3)
    reply = client.plan()
    assert not reply.success and "header.frame_id" in reply.message, reply.message
    reply = client.plan(point=(0.3, -0.45, 0.02))
    assert not reply.success and reply.message.startswith("no_target"), reply.message
    with pytest.raises(ValueError, match="expected x y z"):
        client.set_target((0.5, 0.0))
    reply = client.plan(point=point)
    assert reply.success and reply.trajectory is not None, reply.message


PLACE_REGION = (0.35, -0.5, 0.0, 0.6, -0.25, 0.4)  # an empty area of the table, right of the target


def _cut(timed, segments) -> dict:
    """The node's one trajectory cut at the parts' times (the status's segment.<name>)."""
    out = {}
    for name, t0, t1 in segments:
        k0, k1 = (int(round(t * timed.rate)) for t in (t0, t1))
        out[name] = TimedTrajectory(
            timed.t[k0 : k1 + 1] - timed.t[k0],
            timed.q[k0 : k1 + 1],
            timed.qd[k0 : k1 + 1],
            timed.qdd[k0 : k1 + 1],
            timed.rate,
        )
    return out


def test_pick_and_place_puts_the_target_in_the_region_in_physics(ready):
    from visualization_msgs.msg import MarkerArray

    from pickplan.ros.node import LATCHED

    scene, lib, obs, robot, client, replay = ready
    arrays = []
    client.node.create_subscription(MarkerArray, "/pickplan/markers", arrays.append, LATCHED)
    client.spin(0.5)
    arrays.clear()
    reply = client.pick_and_place(point=_target_point(scene, lib), region=PLACE_REGION)
    assert reply.success and reply.message.startswith("success: pick and place"), reply.message
    end = time.monotonic() + 10
    while not arrays and time.monotonic() < end:
        client.spin(0.05)
    markers = {m.ns: m for m in arrays[-1].markers if m.ns}
    edges = np.array([[p.x, p.y, p.z] for p in markers["place_region"].points])
    assert len(edges) == 24
    np.testing.assert_allclose([edges.min(axis=0), edges.max(axis=0)], [PLACE_REGION[:3], PLACE_REGION[3:]])
    hand = np.array([[p.x, p.y, p.z] for p in markers["place"].points]).mean(axis=0)
    assert np.all(hand[:2] > np.array(PLACE_REGION[:2]) - 0.05) and np.all(
        hand[:2] < np.array(PLACE_REGION[3:5]) + 0.05
    )
    assert [n for n, *_ in reply.segments] == ["approach", "close", "lift", "transfer", "release", "retract"]
    timed = convert.timed_trajectory(reply.trajectory, robot.joint_names)
    assert reply.segments[0][1] == 0.0 and reply.segments[-1][2] == pytest.approx(timed.duration, abs=1e-3)
    assert all(a[2] == pytest.approx(b[1], abs=1e-9) for a, b in zip(reply.segments, reply.segments[1:]))
    limits = robot_limits(robot)
    assert np.all(np.abs(timed.qd) <= limits.velocity * (1 + 1e-3))
    assert np.all(np.abs(timed.qdd) <= limits.acceleration * (1 + 1e-2))
    parts = _cut(timed, reply.segments)
    arm, info = robot.info.arm_dof, robot.info
    for name, fingers in (
        ("approach", info.finger_open),
        ("lift", info.finger_closed),
        ("transfer", info.finger_closed),
        ("retract", info.finger_open),
    ):
        np.testing.assert_allclose(parts[name].q[:, arm:], fingers, atol=1e-9, err_msg=name)
    for name in ("close", "release"):  # the gripper moves, the arm stands still
        assert np.ptp(parts[name].q[:, :arm], axis=0).max() < 1e-12, name
        np.testing.assert_allclose(parts[name].qd[[0, -1]], 0.0, atol=1e-9)
    target = next(o for o in scene.objects if o.name == scene.target)
    check = PlaceCheck(PLACE_REGION[:3], PLACE_REGION[3:], target.pose)  # upright: the up axis it stood with
    executed = execute_pick_and_place(
        scene, [(n, parts[n]) for n in ("approach", "lift", "transfer", "retract")], check, library=lib
    )
    assert executed.success, (executed.status, executed.message)


def test_place_parameters_are_checked_and_an_unreachable_region_is_a_reason(ready):
    scene, lib, obs, robot, client, replay = ready
    with pytest.raises(ValueError, match="place_region.*must exceed"):
        client.pick_and_place(region=(0.6, -0.5, 0.0, 0.35, -0.25, 0.4))
    with pytest.raises(ValueError, match="place_orientation.*upright or stable"):
        client.pick_and_place(orientation="sideways")
    reply = client.pick_and_place(point=_target_point(scene, lib), region=(1.6, 1.0, 0.0, 1.9, 1.3, 0.4))
    assert not reply.success and reply.trajectory is None
    assert reply.message.startswith("no_place_goals") and "reach" in reply.message, reply.message


def test_memory_stays_flat_over_repeated_requests(ready, server):
    scene, lib, obs, robot, client, replay = ready
    point = _target_point(scene, lib)
    seconds, rss = [], []
    for k in range(24):
        reply = client.plan(point=point)
        assert reply.success, reply.message
        seconds.append(reply.seconds)
        rss.append(rss_mb(server.pid))
    growth = max(rss[12:]) - rss[8]
    print(
        f"\nnode RSS {rss[0]:.0f} -> {rss[-1]:.0f} MB over {len(rss)} requests; request to trajectory "
        f"median {1000 * np.median(seconds):.0f} ms"
    )
    assert growth < 15.0, rss
