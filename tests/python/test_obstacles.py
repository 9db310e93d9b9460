"""Obstacles of any shape at any pose in the world model: the scene file, the SDF (closed forms), the
FCL checkers, the success test, PyBullet execution and the 3D view all take them."""

import numpy as np
import pytest

from pickplan.core.errors import InputError
from pickplan.core.shapes import Obstacle, Shape, ShapeKind
from pickplan.omg.world import CheckerKind, World
from pickplan.sim import scenes
from pickplan.sim.execution import ExecutionSettings, execute_plan
from pickplan.sim.view import build_view


def pose(x, y, z, yaw=0.0):
    T = np.eye(4)
    c, s = np.cos(yaw), np.sin(yaw)
    T[:3, :3] = [[c, -s, 0], [s, c, 0], [0, 0, 1]]
    T[:3, 3] = [x, y, z]
    return T


def scene_with(obstacles):
    far = pose(0.9, 0.6, 0.05)
    obj = scenes.SceneObject("box", "builtin:003_cracker_box", far)
    return scenes.Scene(
        robot_base=np.eye(4), table=scenes.default_table(), objects=[obj], target="box", obstacles=obstacles
    )


WALL = Obstacle("wall", Shape.box(0.5, 0.02, 0.5), pose(0.5, 0.0, 0.25, yaw=0.3))
POST = Obstacle("post", Shape.cylinder(0.04, 0.6), pose(0.3, -0.4, 0.3))
BALL = Obstacle("ball", Shape.sphere(0.05), pose(0.4, 0.35, 0.6))


def test_scene_file_round_trip_and_malformed_obstacles():
    scene = scene_with([WALL, POST, BALL])
    again = scenes.Scene.from_json(scene.to_json())
    assert [(o.name, o.shape, o.support) for o in again.obstacles] == [
        (o.name, o.shape, o.support) for o in scene.obstacles
    ]
    for o, p in zip(again.obstacles, scene.obstacles):
        np.testing.assert_array_equal(o.pose, p.pose)
    d = scene.to_dict()
    d["obstacles"][1]["size"] = [0.04]
    with pytest.raises(InputError, match=r"obstacles\[1\]\.size"):
        scenes.Scene.from_dict(d)
    d = scene.to_dict()
    d["obstacles"][0]["shape"] = "torus"
    with pytest.raises(InputError, match=r"obstacles\[0\]\.shape"):
        scenes.Scene.from_dict(d)
    d = scene.to_dict()
    d["obstacles"][2]["name"] = "box"  # an object's name
    with pytest.raises(InputError, match=r"obstacles\[2\]\.name"):
        scenes.Scene.from_dict(d)
    d = scene.to_dict()
    d["obstacles"][0]["pose"][0][0] = 3.0
    with pytest.raises(InputError, match=r"obstacles\[0\]\.pose"):
        scenes.Scene.from_dict(d)


def test_world_sdf_is_the_closed_form_of_the_posed_shapes():
    world = World(scene_with([WALL, POST, BALL]))
    rng = np.random.default_rng(0)
    X = rng.uniform([0.1, -0.6, 0.05], [0.8, 0.6, 0.8], size=(400, 3))
    want = np.full(len(X), np.inf)
    for o in (WALL, POST, BALL):
        local = (X - o.pose[:3, 3]) @ o.pose[:3, :3]  # world into the shape frame
        want = np.minimum(want, o.shape.signed_distance(local))
    table_top = X[:, 2]  # the table's top face is z = 0 (points over it)
    want = np.minimum(want, table_top)
    d, _ = world.sdf.distance(X, cutoff=np.inf, exclude=("box",))
    np.testing.assert_allclose(d, want, atol=1e-12)
    # hand-computed: 10 cm above the ball's top, straight up; on the post's axis, 1 cm below its cap
    d, _ = world.sdf.distance(np.array([[0.4, 0.35, 0.75], [0.3, -0.4, 0.59]]), exclude=("box",))
    np.testing.assert_allclose(d, [0.1, -0.01], atol=1e-12)


def test_checkers_and_the_success_test_see_obstacles():
    world = World(scene_with([WALL]))
    robot = world.robot
    q = robot.ready_configuration.copy()
    q[:7] = [0.0, 0.6, 0.0, -1.6, 0.0, 2.2, 0.785]  # the hand about 0.5 m out, low: in the wall
    hand = robot.link_pose(q, robot.hand_link)[:3, 3]
    local = (hand - WALL.pose[:3, 3]) @ WALL.pose[:3, :3]
    assert np.all(np.abs(local) < 0.5 * np.array(WALL.shape.size) + [0, 0.08, 0])  # the hand at the wall
    for kind in (CheckerKind.strict, CheckerKind.obstacles, CheckerKind.goal):
        assert world.checker(kind).in_collision(q)
    contacts = world.checker(CheckerKind.strict).contacts(q)
    assert any(c.other == "wall" for c in contacts)
    clear = World(scene_with([]))
    assert not clear.checker(CheckerKind.strict).in_collision(q)
    # the success test of a trajectory through the wall fails on collision
    chomp = world.chomp(world_chomp_settings())
    xi = np.repeat(q[None], chomp.settings.n, axis=0)
    assert not chomp.metrics(xi, q).collision_free


def world_chomp_settings():
    from pickplan.omg.chomp import ChompSettings

    return ChompSettings()


def test_execution_hits_an_obstacle_and_the_view_draws_it():
    scene = scene_with([WALL, POST])
    robot_q = World(scene).robot.ready_configuration
    q_in = robot_q.copy()
    q_in[:7] = [0.0, 0.6, 0.0, -1.6, 0.0, 2.2, 0.785]
    traj = np.linspace(robot_q, q_in, 20)
    run = execute_plan(scene, traj, ExecutionSettings())
    assert "wall" in run.contacts_during_approach and run.collided
    view = build_view(scene, {"trajectory": traj.tolist()})
    drawn = [c["path"] for c in (c.lower() for c in view.commands) if c["type"] == "set_object"]
    assert "/meshcat/pickplan/obstacles/wall" in drawn and "/meshcat/pickplan/obstacles/post" in drawn
    cyl = Shape.cylinder(0.04, 0.6).trimesh()
    np.testing.assert_allclose(cyl.extents, [0.08, 0.08, 0.6], atol=1e-3)
    assert Shape(ShapeKind.sphere, (0.05,)).trimesh().is_watertight
