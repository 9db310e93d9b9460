"""The robot in use, past its description (issue 21): scenes made for it, stored grasps converted only where
its fingers straddle the object, and a transit that keeps away from the target it will grasp."""

import types

import numpy as np
import pybullet as pb
import pytest
import trimesh

from pickplan.core import objects, robots
from pickplan.core.description import load_description, robot_info
from pickplan.core.graspability import graspability
from pickplan.core.panda import PANDA
from pickplan.omg import chomp
from pickplan.omg import grasps as G
from pickplan.omg.world import World, WorldSettings
from pickplan.sim import scenes


@pytest.mark.parametrize("name", ["ur5", "iiwa"])
def test_a_scene_made_for_a_robot_stands_it_at_its_start_clear_of_every_object(name, monkeypatch):
    info, desc = robot_info(name), load_description(name)
    openings = []

    def recording(model, pose, opening, *args, **kwargs):
        openings.append(opening)
        return graspability(model, pose, opening, *args, **kwargs)

    monkeypatch.setattr(scenes, "graspability", recording)
    lib = objects.library("builtin")
    scene = scenes.generate_scene(3, lib, scenes.SceneSettings(robot=name))
    assert set(openings) == {info.max_opening}  # the target is judged with this gripper's opening
    assert scene.robot == info.name and scene.robot_configuration == list(info.ready)
    back = scenes.Scene.from_json(scene.to_json())
    assert back.robot == info.name and back.robot_configuration == scene.robot_configuration
    assert np.allclose(World(back, WorldSettings(robot=name)).start, info.ready)
    assert np.allclose(World(back, WorldSettings(robot="panda")).start, PANDA.ready)  # another robot: its own start
    client = pb.connect(pb.DIRECT)
    try:
        ids = scenes.load_into_pybullet(back, client, lib)
        robot = robots.load_robot(name, back.robot_base)
        links = {
            pb.getJointInfo(ids["robot"], j, physicsClientId=client)[12].decode(): j
            for j in range(pb.getNumJoints(ids["robot"], physicsClientId=client))
        }
        state = pb.getLinkState(
            ids["robot"], links[info.hand_link], computeForwardKinematics=True, physicsClientId=client
        )
        hand = robot.link_pose(robot.ready_configuration, info.hand_link)
        assert np.allclose(state[4], hand[:3, 3], atol=1e-6)  # PyBullet's robot at its base, at its start
        for o in back.objects:  # nothing was left touching it
            assert not pb.getClosestPoints(ids[o.name], ids["robot"], 0.0, physicsClientId=client), o.name
    finally:
        pb.disconnect(client)
    assert desc.base_pose.shape == (4, 4)


def test_a_panda_scene_file_is_as_before_and_a_bad_robot_entry_is_refused():
    scene = scenes.generate_scene(3, "builtin")
    d = scene.to_dict()
    assert scene.robot == "panda" and "robot" not in d  # the Panda's scene files do not change
    d["robot"] = 7
    with pytest.raises(ValueError, match="robot: expected a non-empty string, got int 7"):
        scenes.Scene.from_dict(d)


def _boxes(*specs):
    """One mesh of axis-aligned boxes, each (min corner, max corner)."""
    parts = []
    for lo, hi in specs:
        lo, hi = np.asarray(lo, float), np.asarray(hi, float)
        parts.append(
            trimesh.creation.box(extents=hi - lo, transform=trimesh.transformations.translation_matrix((lo + hi) / 2))
        )
    return trimesh.util.concatenate(parts)


def _top_down(center, closing_along_x=False):
    """A grasp frame at ``center``, approaching straight down, closing along world y (or x)."""
    F = np.eye(4)
    z = np.array([0.0, 0.0, -1.0])
    y = np.array([1.0, 0.0, 0.0]) if closing_along_x else np.array([0.0, 1.0, 0.0])
    F[:3, 0], F[:3, 1], F[:3, 2], F[:3, 3] = np.cross(y, z), y, z, center
    return F


def test_a_backed_off_grasp_whose_finger_would_rest_on_the_object_is_dropped():
    # A post (5 x 4 cm, 9 cm tall) with two 5 cm high blocks beside it, 4.1-7 cm off its axis along y:
    # outside the Panda's open pads (8 cm), right under the 2F-85's (8.5 cm apart, 1 cm thick).
    mesh = _boxes(
        ((-0.02, -0.025, 0.0), (0.02, 0.025, 0.09)),
        ((-0.02, 0.041, 0.0), (0.02, 0.07, 0.05)),
        ((-0.02, -0.07, 0.0), (0.02, -0.041, 0.05)),
    )
    model = types.SimpleNamespace(mesh=mesh)
    info = robot_info("ur5")
    frames = np.stack([_top_down((0.0, 0.0, 0.065)), _top_down((0.0, 0.0, 0.065), closing_along_x=True)])
    panda_set = G.GraspSet("test", frames @ np.linalg.inv(PANDA.grasp_frame), "post")
    plain = G.convert_grasps(panda_set, model, info)  # frames only: both fit the opening
    assert len(plain) == 2
    checker = G.HandObjectChecker(model, 0.0, info)
    assert checker.in_collision(plain.poses).tolist() == [True, False]  # the tips reach 2.5 cm down: into a block
    out = G.convert_grasps(panda_set, model, info, hand_checker=G.HandObjectChecker)
    # backing the first off would leave its fingers standing on the blocks: dropped; the second is kept as it was
    assert out.info["source_index"].tolist() == [1]
    assert np.allclose(out.poses[0], plain.poses[1])
    reach = info.pad_length / 2
    assert G.fingers_straddle(model, frames, info, reach).tolist() == [False, True]
    lifted = frames[:1].copy()
    lifted[0, 2, 3] += 0.05 + reach  # far above the blocks: nothing under the fingers
    assert G.fingers_straddle(model, lifted, info, reach).tolist() == [True]


Q_LEFT = np.array([1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])
Q_RIGHT = np.array([-1.0, 0.2, 0.0, -2.0, 0.0, 2.2, 0.785, 0.04, 0.04])


def test_the_transit_may_avoid_an_object_the_metrics_leave_out(panda):
    from pickplan.core import sdf

    grid = sdf.mesh_sdf(trimesh.creation.box(extents=(0.1, 0.3, 0.4)), sdf.SdfSettings(cache_dir=""))
    pose = np.eye(4)
    pose[:3, 3] = [0.5, 0.0, 0.2]
    scene = sdf.SceneSdf([("target", grid, pose)])
    body = panda.sample_body_points(per_link=20, seed=0)
    left_out = chomp.Chomp(panda, scene, body, exclude=("target",))
    avoided = chomp.Chomp(panda, scene, body, exclude=("target",), obstacle_exclude=())
    counted = chomp.Chomp(panda, scene, body)
    xi = left_out.initial_trajectory(Q_LEFT, Q_RIGHT)  # sweeps the arm through the box
    f_out, f_avoid, f_all = (c.objective(xi, Q_LEFT)[0].obstacle for c in (left_out, avoided, counted))
    assert f_avoid == pytest.approx(f_all) and f_avoid > f_out  # the optimizer's cost sees the box ...
    m_out, m_avoid = left_out.metrics(xi, Q_LEFT), avoided.metrics(xi, Q_LEFT)
    assert m_avoid.to_dict() == m_out.to_dict() and m_out.collision_free  # ... the success test still leaves it out
    assert not counted.metrics(xi, Q_LEFT).collision_free
