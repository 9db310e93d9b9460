"""The held object as part of the robot (omg.attach): its body points follow the hand exactly, and a
transfer the robot alone would clear but the held object would not is rejected by the FCL checks
and by the success test."""

import numpy as np
import pytest

from pickplan.core import objects
from pickplan.core.containers import bin_source
from pickplan.omg.attach import HELD_LINK, HeldCheck, HeldWorld, held_from_poses, straight_path
from pickplan.omg.chomp import ChompSettings, MetricSettings
from pickplan.omg.world import World
from pickplan.sim import scenes

from conftest import standing_pose

BOX = "004_sugar_box"


@pytest.fixture(scope="module")
def carry_case():
    """A sugar box held from above by its top, and a bin 10 cm to its side whose 8 cm walls the hand
    clears when it passes over them and the hanging box does not."""
    lib = objects.library("builtin")
    box = lib.get(BOX)
    box_pose = standing_pose(box, (0.5, -0.12))
    wall_pose = np.eye(4)
    wall_pose[:3, 3] = [0.5, 0.16, 0.0]
    scene = scenes.Scene(
        np.eye(4),
        scenes.default_table(),
        [
            scenes.SceneObject(BOX, f"builtin:{BOX}", box_pose),
            scenes.SceneObject("bin", bin_source(0.2, 0.2, 0.08), wall_pose),
        ],
        BOX,
        seed=0,
    )
    world = World(scene)
    robot = world.robot
    top = float((box.mesh.vertices @ box_pose[:3, :3].T + box_pose[:3, 3])[:, 2].max())
    depth = float(robot.grasp_frame[2, 3])  # hand origin to the pads' centre along the approach
    hand = np.eye(4)
    hand[:3, :3] = np.diag([1.0, -1.0, -1.0])  # approach straight down, fingers closing along world y
    # the box's thin side (3.5 cm) between the pads, 2 cm under its top
    R = box_pose[:3, :3]
    thin = R[:, int(np.argmin(box.extents))]
    hand[:3, 1] = thin if thin[1] >= 0 else -thin
    hand[:3, 0] = np.cross(hand[:3, 1], hand[:3, 2])
    hand[:3, 3] = [box_pose[0, 3], box_pose[1, 3], top - 0.02 + depth]
    held = held_from_poses(BOX, hand, box_pose, box.mesh)
    return world, held, top


def _ik(robot, pose, seed):
    from pickplan import _core
    from pickplan.core.ik import IkSettings

    active = [i < robot.info.arm_dof for i in range(robot.dof)]
    sol = _core.IkSolver(robot.native, robot.hand_link, IkSettings().to_native(active)).solve(pose, seed)
    assert sol.converged
    return np.asarray(sol.q)


def test_held_points_follow_the_hand_exactly(carry_case):
    world, held, _ = carry_case
    carrying = HeldWorld(world, held)
    robot = carrying.robot
    link = robot.link_index(HELD_LINK)
    mine = carrying.body.links == link
    assert mine.sum() == len(held.points) and len(carrying.body) == len(world.body) + len(held.points)
    Q = robot.random_configurations(50, seed=1)
    X = robot.transform_points(Q, carrying.body)[:, mine]  # native FK of the held link
    hands = world.robot.fk_batch(Q)[:, world.robot.link_index(world.robot.hand_link)]  # the unattached robot
    expected = (
        np.einsum("tij,nj->tni", (hands @ held.hand_T_object)[:, :3, :3], held.points)
        + (hands @ held.hand_T_object)[:, None, :3, 3]
    )
    np.testing.assert_allclose(X, expected, atol=1e-12)
    # the robot's own points are untouched by the attachment
    np.testing.assert_allclose(
        robot.transform_points(Q, world.body), world.robot.transform_points(Q, world.body), atol=0
    )


def test_a_transfer_only_the_held_object_would_hit_is_rejected(carry_case):
    world, held, top = carry_case
    carrying = HeldWorld(world, held)
    robot = world.robot
    H0 = held.hand_pose(world.target_pose)
    q_grasp = _ik(robot, H0, robot.ready_configuration)
    lift, ok = straight_path(carrying.robot, q_grasp, (0, 0, 1), 0.06, 6)
    assert ok
    # over the bin's near wall (y = 0.05): the pads 12 cm above the wall's top, the box's bottom 2 cm below it
    over = carrying.robot.link_pose(lift[-1], robot.hand_link)
    over[1, 3] = 0.16 - 0.1 - 0.005
    q_over = _ik(robot, over, lift[-1])
    bottom = float(held.object_pose(robot.link_pose(q_over, robot.hand_link))[2, 3])
    assert bottom < 0.08 - 0.02 and robot.link_pose(q_over, robot.hand_link)[2, 3] > 0.08 + 0.1
    # FCL: the robot alone clears everything (the box's old place included); with the held box it does not
    assert not world.checker("obstacles").in_collision(q_over)
    assert carrying.checker(HeldCheck.carry).in_collision(q_over)
    assert not carrying.checker(HeldCheck.carry).in_collision(lift[-1])
    # the success test: the same trajectory passes for the robot alone and fails with the held box
    n = ChompSettings().n
    xi = lift[-1] + (np.arange(1, n + 1) / n)[:, None] * (q_over - lift[-1])
    alone = world.chomp(ChompSettings()).metrics(xi, lift[-1], MetricSettings())
    held_metrics = carrying.chomp(ChompSettings()).metrics(xi, lift[-1], MetricSettings())
    assert alone.collision_free, alone
    assert not held_metrics.collision_free and held_metrics.min_clearance < 0.0


def test_a_target_from_depth_is_carried_as_points_spread_over_what_was_seen(carry_case):
    """The sugar box of ``carry_case`` seen by three rendered cameras: its body points lie on the convex
    hull of its observed points and their feet (within 3 mm of the true box's surface or inside it: no
    volume invented beyond the sensor's noise), and cover the true surface: every sampled point of it
    is within 2 cm of a body point (a random 60 of the observed points left 5 cm here)."""
    from scipy.spatial import cKDTree

    from pickplan.omg.attach import AttachSettings, observed_points, surface_points
    from pickplan.omg.perceived_world import PerceivedWorld
    from pickplan.sim.observe import render_observation

    world = carry_case[0]
    seen = PerceivedWorld(render_observation(world.scene, views=3, seed=0), robot=world.robot)
    settings = AttachSettings()
    body = observed_points(seen, settings)
    assert settings.points <= len(body) <= settings.max_points
    truth = world.target_model.mesh.copy().apply_transform(world.target_pose)
    outside = truth.nearest.signed_distance(body)  # trimesh: positive inside
    assert outside.min() > -0.003
    d, _ = cKDTree(body).query(surface_points(truth, 2000, 1))
    assert d.max() < 0.02, d.max()
