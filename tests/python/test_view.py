"""The 3D view of a plan (``pickplan view``): what plan.json holds for it, the drawing against forward
kinematics and exact geometry, the self-contained page, and the page rendered in headless Chromium."""

import ipaddress
import json
import os
import urllib.request
import warnings
from html.parser import HTMLParser

import numpy as np
import pytest

from pickplan.cli.main import main
from pickplan.core.io import write_json
from pickplan.core.robots import panda
from pickplan.omg import planner as omg
from pickplan.omg.plan_file import collision_points, plan_record
from pickplan.omg.world import World
from pickplan.sim import scenes
from pickplan.sim.view import PlanView, ViewSettings, build_view, read_plan, view_folder
from pickplan.sim.view_page import find_chromium, screenshot, serve, write_html

from conftest import socket_inodes

SETTINGS = omg.OMGSettings(grasp_kind="antipodal")


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """A real plan (scene seed 1, built-in objects) written as `pickplan plan --out` writes it."""
    folder = tmp_path_factory.mktemp("plan")
    scene = scenes.generate_scene(1)
    planner = omg.OMGPlanner(None, scene, SETTINGS)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = planner.plan()
    scene.save(str(folder / "scene.json"))
    write_json(str(folder / "plan.json"), plan_record(result, planner.world()))
    return str(folder), scene, result


def lowered(view: PlanView):
    return [c.lower() for c in view.commands]


def test_plan_record_holds_the_goal_set_and_both_grasps(planned):
    folder, scene, result = planned
    _, plan = read_plan(folder)
    robot = panda(scene.robot_base)
    goals = np.asarray(plan["goal_set"])
    assert goals.shape[0] >= 1 and goals.shape[1] == robot.dof
    assert np.all(goals >= robot.lower_limits - 1e-9) and np.all(goals <= robot.upper_limits + 1e-9)
    chosen = np.asarray(plan["chosen_goal"])
    assert any(np.array_equal(chosen, g) for g in goals)  # a member of the goal set, bit for bit
    final = np.asarray(plan["trajectory"])[-1]
    if result.refined:
        np.testing.assert_array_equal(np.asarray(plan["refined_goal"]), final)
        # ISF is local: the hand moves at most isf_max_shift from the chosen grasp (forward kinematics).
        shift = np.linalg.norm(
            robot.link_pose(final, robot.hand_link)[:3, 3] - robot.link_pose(chosen, robot.hand_link)[:3, 3]
        )
        assert shift <= SETTINGS.isf_max_shift + 1e-9
    else:
        assert plan["refined_goal"] is None
        np.testing.assert_array_equal(chosen, final)
    # A collision-free plan (its clearances are measured on the same body points) has no point inside.
    assert result.metrics.collision_free and plan["collision_points"] == []


def test_collision_points_are_the_body_points_inside_the_table():
    table = scenes.default_table()
    far = np.eye(4)
    far[:3, 3] = [0.9, 0.6, 0.05]  # out of the arm's way
    scene = scenes.Scene(
        robot_base=np.eye(4),
        table=table,
        objects=[scenes.SceneObject("box", "builtin:003_cracker_box", far)],
        target="box",
    )
    world = World(scene)
    q_down = world.robot.ready_configuration.copy()
    q_down[1], q_down[3] = 1.4, -1.0  # shoulder forward, elbow open: the hand goes into the table top
    trajectory = np.stack([world.robot.ready_configuration, q_down])
    got = collision_points(world, trajectory)
    # Exact geometry: the table top is z = 0; a point is inside when below it and within the footprint.
    X = world.robot.transform_points(trajectory, world.body)
    centre, half = np.asarray(table.pose)[:3, 3], np.asarray(table.size) / 2
    inside = np.all(np.abs(X - centre) < half, axis=2)
    steps, points = np.nonzero(inside)
    assert len(steps) > 5
    want = np.column_stack([X[steps, points], steps])
    np.testing.assert_allclose(got[np.lexsort(got.T[::-1])], want[np.lexsort(want.T[::-1])], atol=1e-12)
    assert np.all(got[:, 3] == 1)  # the start configuration is clear of the table


def test_view_moves_every_link_along_the_trajectory_by_forward_kinematics(planned):
    folder, scene, result = planned
    settings = ViewSettings(seconds_per_waypoint=0.2, substeps=3)
    view = view_folder(folder, settings)
    robot = panda(scene.robot_base)
    Q = result.trajectory
    assert view.duration == pytest.approx((len(Q) - 1) * 0.2)
    (animation,) = [c for c in lowered(view) if c["type"] == "set_animation"]
    clips = {a["path"]: a["clip"] for a in animation["animations"]}
    moved = 0
    for name in robot.link_names:
        clip = clips.get(f"/meshcat/pickplan/robot/{name}")
        if clip is None:
            continue
        tracks = {t["name"]: t["keys"] for t in clip["tracks"]}
        assert clip["fps"] == pytest.approx(3 / 0.2)
        for key, q in ((0, Q[0]), (-1, Q[-1]), (3 * 5, Q[5])):  # sample 15 is waypoint 5
            pose = robot.link_pose(q, name)
            np.testing.assert_allclose(tracks[".position"][key]["value"], pose[:3, 3], atol=1e-9)
            x, y, z, w = tracks[".quaternion"][key]["value"]
            R = np.array(
                [
                    [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
                ]
            )
            np.testing.assert_allclose(R, pose[:3, :3], atol=1e-9)
        assert tracks[".position"][-1]["time"] == 3 * (len(Q) - 1)
        moved += 1
    assert moved >= 10  # every link with a mesh: 8 arm links, the hand, 2 fingers


def test_view_draws_the_scene_the_goal_set_and_both_grasps(planned):
    folder, scene, result = planned
    _, plan = read_plan(folder)
    view = view_folder(folder, ViewSettings(max_goal_hands=2))
    drawn = [c["path"] for c in lowered(view) if c["type"] == "set_object"]
    for o in scene.objects:
        assert f"/meshcat/pickplan/objects/{o.name}" in drawn
    assert "/meshcat/pickplan/table" in drawn
    hands = [p for p in drawn if p.startswith("/meshcat/pickplan/goal_set/")]
    others = [g for g in plan["goal_set"] if g != plan["chosen_goal"]]  # the chosen one has its own colour
    assert len(others) == len(plan["goal_set"]) - 1
    assert len(hands) == min(2, len(others))
    assert "/meshcat/pickplan/chosen_grasp" in drawn
    assert ("/meshcat/pickplan/refined_grasp" in drawn) == result.refined
    # The object sits where the scene puts it.
    target = scene.object(scene.target)
    (placed,) = [
        c
        for c in lowered(view)
        if c["type"] == "set_transform" and c["path"] == f"/meshcat/pickplan/objects/{target.name}"
    ]
    np.testing.assert_allclose(np.reshape(placed["matrix"], (4, 4)).T, target.pose)


def test_collision_points_are_drawn_where_the_plan_puts_them(planned):
    folder, scene, _ = planned
    _, plan = read_plan(folder)
    plan["collision_points"] = [[0.5, 0.1, -0.01, 3], [0.6, 0.0, -0.02, 4]]
    (cloud,) = [c for c in lowered(build_view(scene, plan)) if c["path"] == "/meshcat/pickplan/collision_points"]
    geometry = cloud["object"]["geometries"][0]["data"]["attributes"]["position"]
    xyz = np.frombuffer(geometry["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(xyz, [[0.5, 0.1, -0.01], [0.6, 0.0, -0.02]], atol=1e-7)


class _Resources(HTMLParser):
    """Every element attribute that would load something from outside the page."""

    def __init__(self):
        super().__init__()
        self.external, self.scripts = [], 0

    def handle_starttag(self, tag, attrs):
        self.scripts += tag == "script"
        self.external += [(tag, k, v) for k, v in attrs if k in ("src", "href", "data") and v]


def test_the_page_is_self_contained(planned, tmp_path):
    folder, _, _ = planned
    path = write_html(view_folder(folder), str(tmp_path / "view.html"))
    text = open(path, encoding="utf-8").read()
    parser = _Resources()
    parser.feed(text)
    assert parser.external == [] and parser.scripts == 2  # three.js viewer and the drawing, both inline
    assert "MeshCat.Viewer" in text and len(text) > 500_000


def test_cli_view_writes_the_page_and_rejects_bad_folders(planned, tmp_path, capsys):
    folder, _, _ = planned
    page = tmp_path / "out" / "page.html"
    assert main(["view", folder, "--html", str(page)]) == 0
    assert page.is_file() and "wrote" in capsys.readouterr().out
    assert main(["view", str(tmp_path / "missing"), "--html", str(page)]) == 2
    assert "plan folder not found" in capsys.readouterr().err
    broken = tmp_path / "broken"
    broken.mkdir()
    (broken / "scene.json").write_text(open(os.path.join(folder, "scene.json")).read())
    (broken / "plan.json").write_text(json.dumps({"trajectory": [[0.0] * 7]}))
    assert main(["view", str(broken), "--html", str(page)]) == 2
    assert "trajectory: expected finite configurations of 9 joint values" in capsys.readouterr().err
    (broken / "plan.json").write_text("{not json")
    assert main(["view", str(broken), "--html", str(page)]) == 2
    assert "malformed JSON" in capsys.readouterr().err


def test_serve_starts_a_local_viewer_and_stops(planned):
    folder, _, _ = planned
    announced, pages = [], []

    def fetch_once():
        url = announced[0].split()[2]
        assert url.startswith("http://127.0.0.1:")
        with urllib.request.urlopen(url, timeout=10) as response:
            pages.append(response.read().decode("utf-8"))
        return False

    serve(view_folder(folder), keep_running=fetch_once, announce=announced.append)
    assert "MeshCat" in pages[0]


def _server_pids() -> list:
    """This process's children running the viewer's server."""
    pids = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = open(f"/proc/{entry}/stat").read()
                cmdline = open(f"/proc/{entry}/cmdline").read()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == os.getpid() and "view_server" in cmdline:
                pids.append(int(entry))
    return pids


def _address(hex_address: str) -> str:
    """/proc/net/tcp{,6}'s local address (little-endian 32-bit words) as text."""
    raw = bytes.fromhex(hex_address)
    return str(ipaddress.ip_address(b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))))


def _listening(pid: int) -> list:
    """(address, port) of every TCP socket process ``pid`` listens on, from /proc (IPv4 and IPv6)."""
    inodes = socket_inodes(pid)
    out = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in open(table).read().splitlines()[1:]:
            cols = line.split()
            if cols[3] == "0A" and cols[9] in inodes:  # 0A: LISTEN
                address, port = cols[1].split(":")
                out.append((_address(address), int(port, 16)))
    return out


def test_the_live_viewer_listens_on_loopback_only(planned):
    """meshcat's own server listened on 0.0.0.0 and [::] whatever URL it printed (issue 39)."""
    folder, _, _ = planned
    announced, sockets = [], []

    def inspect():
        pids = _server_pids()
        assert len(pids) == 1, pids
        sockets.extend(_listening(pids[0]))
        return False

    serve(view_folder(folder), keep_running=inspect, announce=announced.append)
    port = int(announced[0].split()[2].split(":")[2].split("/")[0])
    assert port in [p for _, p in sockets] and len(sockets) >= 2, sockets  # the web page and the command port
    assert all(ipaddress.ip_address(a).is_loopback for a, _ in sockets), sockets
    assert not _server_pids()  # stopped


def test_another_address_is_asked_for_and_said_loudly(planned, capsys, monkeypatch):
    import pickplan.cli.view as view_cli

    folder, _, _ = planned
    hosts = []
    monkeypatch.setattr(view_cli, "serve", lambda view, open_browser, host: hosts.append(host))
    assert main(["view", folder]) == 0 and hosts == ["127.0.0.1"]
    assert "WARNING" not in capsys.readouterr().err
    assert main(["view", folder, "--host", "0.0.0.0"]) == 0 and hosts[-1] == "0.0.0.0"
    assert "WARNING: the viewer listens on 0.0.0.0, not only on this machine" in capsys.readouterr().err
    assert main(["view", folder, "--host", "example.org"]) == 2
    assert "--host: expected an IP address" in capsys.readouterr().err
    assert main(["view", folder, "--host", "192.0.2.1"]) == 2  # TEST-NET-1: no interface of this machine
    assert "--host: cannot listen on 192.0.2.1" in capsys.readouterr().err


def _pixels(png):
    from PIL import Image

    return np.asarray(Image.open(png).convert("RGB")).astype(int)


@pytest.mark.skipif(find_chromium() is None, reason="chromium (Debian package) not installed: no browser to render in")
def test_chromium_renders_the_robot_and_the_scene(planned, tmp_path):
    folder, _, _ = planned
    view = view_folder(folder)
    robot_paths = ("/meshcat/pickplan/robot/",)
    without_robot = PlanView(
        [
            c
            for c in view.commands
            if getattr(c, "path", None) is not None and not c.path.lower().startswith(robot_paths)
        ],
        view.duration,
        view.title,
    )
    size = dict(width=900, height=640)  # software WebGL: fewer pixels, less time
    full = _pixels(screenshot(write_html(view, str(tmp_path / "full.html")), str(tmp_path / "full.png"), **size))
    bare = _pixels(
        screenshot(write_html(without_robot, str(tmp_path / "bare.html")), str(tmp_path / "bare.png"), **size)
    )
    h, w, _ = full.shape
    canvas = full[: h - 140, : w - 260]  # leave out the legend and the controls panel
    assert len(np.unique(canvas.reshape(-1, 3), axis=0)) > 2000  # shaded meshes, not an empty canvas
    # The table (brown: red over blue) fills part of the view.
    assert np.mean((canvas[..., 0] - canvas[..., 2]) > 40) > 0.05
    # The robot is where the two renders differ, and it is drawn in its light grey.
    changed = np.abs(full - bare).sum(axis=2)[: h - 140, : w - 260] > 30
    assert changed.mean() > 0.01
    robot_pixels = canvas[changed]
    greyish = (robot_pixels.max(axis=1) - robot_pixels.min(axis=1) < 40) & (robot_pixels.min(axis=1) > 120)
    assert greyish.mean() > 0.5
    # At the end of the motion (page#t=...) the robot stands elsewhere: the animation drives it.
    end = _pixels(screenshot(str(tmp_path / "full.html"), str(tmp_path / "end.png"), moment=view.duration, **size))
    moved = np.abs(end - full).sum(axis=2)[: h - 140, : w - 260] > 30
    assert moved.mean() > 0.01
    robot_at_end = end[: h - 140, : w - 260][np.abs(end - bare).sum(axis=2)[: h - 140, : w - 260] > 30]
    light = (robot_at_end.max(axis=1) - robot_at_end.min(axis=1) < 40) & (robot_at_end.min(axis=1) > 120)
    assert len(robot_at_end) > 0.01 * changed.size and light.mean() > 0.4


def test_plan_command_writes_a_folder_the_view_reads(tmp_path, capsys):
    scene_file = tmp_path / "scene.json"
    scenes.generate_scene(1).save(str(scene_file))
    out = tmp_path / "plan"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert main(["plan", "--scene", str(scene_file), "--grasps", "antipodal", "--out", str(out)]) == 0
    assert (out / "scene.json").read_text() == scene_file.read_text()
    assert main(["view", str(out), "--html", str(out / "view.html")]) == 0
    assert "wrote" in capsys.readouterr().out and (out / "view.html").stat().st_size > 500_000
