"""Grasping from a surface (issue 20): fingertips may rest on the table, the palm may not.

PyBullet execution is the judge of the thin-object grasp; the palm test checks the hand's own
collision mesh against the table plane before asking the goal set.
"""

import numpy as np
import pytest

from pickplan.core import collision, objects
from pickplan.omg import goals
from pickplan.omg import grasps as grasps_mod
from pickplan.omg.grasps.quality import GraspFit
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanStatus
from pickplan.omg.world import World
from pickplan.sim import scenes
from pickplan.sim.execution import execute_plan

NO_SUPPORT_MODEL = goals.SupportSettings(
    contact=collision.SupportContact(0.0), max_shift=0.0, max_level_deg=0.0, tilts_deg=()
)
NO_SUPPORT_MODEL_BUT_TOLERANCE = goals.SupportSettings(max_shift=0.0, max_level_deg=0.0, tilts_deg=())
# The hand poses below that test the support alone close on empty table 25 cm from the pen: the grasp
# quality (issue 33) rightly says they miss (``test_a_hand_beside_the_object_misses``), so they are
# asked of the goal set with the quality off, as every grasp was before it.
NO_QUALITY = goals.GoalSetSettings(quality=None)


def _lone_object_scene(name: str, xy=(0.5, 0.05)) -> scenes.Scene:
    model = objects.library("procedural").get(name)
    pose = np.array(model.resting_poses[0])
    pose[:2, 3] += xy
    table = scenes.default_table(scenes.SceneSettings())
    return scenes.Scene(
        robot_base=np.eye(4), table=table, objects=[scenes.SceneObject(name, model.source, pose)], target=name
    )


@pytest.fixture(scope="module")
def pen_world():
    scene = _lone_object_scene("pen_00")
    world = World(scene)
    height = np.ptp(world.target_model.mesh.vertices @ world.target_pose[:3, :3].T[:, 2])
    assert height < 0.025  # a thin object, as the issue asks
    return world


def _tables_plane(world):
    t = world.scene.table
    return collision.support_plane(collision.Table(tuple(np.asarray(t.size, float)), np.asarray(t.pose, float)))


def test_default_tolerance_comes_from_the_gripper_pads(pen_world):
    pad = collision.gripper_spec(pen_world.robot).pad_length
    assert collision.SupportContact().resolved(pen_world.robot) == pytest.approx(
        collision.SUPPORT_TOLERANCE_FRACTION * pad
    )
    assert collision.SupportContact(0.001).resolved(pen_world.robot) == 0.001
    with pytest.raises(ValueError, match="support tolerance"):
        collision.SupportContact(-0.001).resolved(pen_world.robot)


def test_finger_penetration_is_exact_against_the_plane(pen_world):
    """A hand pointing straight down: the fingertips' depth moves one for one with the hand's height."""
    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    normal, offset = _tables_plane(pen_world)
    H = np.eye(4)
    H[:3, :3] = np.diag([1.0, -1.0, -1.0])  # z (approach) down
    tip = fingers.vertices[:, 2].max()  # deepest finger point along the approach axis
    heights = np.array([-0.004, 0.0, 0.01])
    poses = np.repeat(H[None], 3, axis=0)
    poses[:, 2, 3] = tip + heights  # fingertips at these heights above the table top (z = 0)
    assert np.allclose(fingers.penetration(poses, normal, offset), -heights, atol=1e-9)


def test_thin_object_grasp_is_accepted_and_lifted_in_pybullet(pen_world):
    grasps = grasps_mod.grasp_set(pen_world.target_model, "antipodal", 100, seed=0).poses
    strict = goals.build_goal_set(pen_world, grasps, support=NO_SUPPORT_MODEL)
    modelled = goals.build_goal_set(pen_world, grasps)
    assert len(modelled) > len(strict)
    assert modelled.reason_counts()["support_penetration"] < strict.reason_counts()["support_penetration"]
    assert modelled.adjusted.any()
    # the goals' fingers rest on the table within the tolerance, none deeper
    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    hands = np.array([robot.link_pose(q, robot.hand_link) for q in modelled.goals])
    depth = fingers.penetration(hands, *_tables_plane(pen_world))
    assert depth.max() <= collision.SupportContact().resolved(robot) + 1e-3
    assert depth.max() > -0.01  # a grasp from the surface: the fingertips reach down to it

    result = OMGPlanner(None, pen_world.scene, OMGSettings(grasp_kind="antipodal"), world=pen_world).plan(grasps=grasps)
    assert result.status == PlanStatus.success
    run = execute_plan(pen_world.scene, result.trajectory)
    assert run.success, (run.status, run.target_lift)


def _at_depth(fingers, H, normal, offset, depth):
    """H moved along the table normal so that the fingers reach ``depth`` into the table."""
    H = H.copy()
    H[:3, 3] += (fingers.penetration(H[None], normal, offset)[0] - depth) * normal
    return H


def _down_at(fingers, normal, offset, depth):
    """A hand approaching straight down at (0.45, -0.2), its fingertips ``depth`` into the table."""
    down = np.eye(4)
    down[:3, :3] = np.diag([1.0, -1.0, -1.0])
    down[:3, 3] = [0.45, -0.2, 0.0]
    return _at_depth(fingers, down, normal, offset, depth)


def test_a_hand_beside_the_object_misses(pen_world):
    """The support tests' hand pose: its pads' closing region is nowhere near the pen (exact distance
    from the grasp point to the pen's vertices), and the goal set's quality rejects it as a miss."""
    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    down = _down_at(fingers, *_tables_plane(pen_world), 0.001)
    centre = (down @ robot.info.grasp_frame)[:3, 3]
    pen = pen_world.target_model.mesh.vertices @ pen_world.target_pose[:3, :3].T + pen_world.target_pose[:3, 3]
    assert np.linalg.norm(pen - centre, axis=1).min() > 0.1 > robot.info.max_opening
    gs = goals.build_goal_set(pen_world, (np.linalg.inv(pen_world.target_pose) @ down)[None])
    assert gs.reasons == [GraspFit.misses.value] and len(gs) == 0


def test_palm_on_the_table_is_still_rejected(pen_world):
    """Fingertips pressing 1 mm into the table pass (lifted to touch it, or as they are without the
    variants); a sideways hand whose fingertips clear the table while its palm reaches into it does not."""
    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    palm = np.asarray(robot.collision_meshes(robot.hand_link).convex_hull.vertices)
    normal, offset = _tables_plane(pen_world)
    to_object = np.linalg.inv(pen_world.target_pose)

    down = _down_at(fingers, normal, offset, 0.001)  # approach straight down
    gs = goals.build_goal_set(pen_world, (to_object @ down)[None], settings=NO_QUALITY)
    assert gs.reasons == ["ok"] and gs.adjusted[0]  # lifted until the fingertips just touch
    hand = robot.link_pose(gs.goals[0], robot.hand_link)
    assert fingers.penetration(hand[None], normal, offset)[0] == pytest.approx(0.0, abs=2e-4)
    kept = goals.build_goal_set(
        pen_world, (to_object @ down)[None], settings=NO_QUALITY, support=NO_SUPPORT_MODEL_BUT_TOLERANCE
    )
    assert kept.reasons == ["ok"] and not kept.adjusted[0]  # 1 mm deep, within the tolerance, as it is

    side = np.eye(4)
    side[:3, :3] = np.column_stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])  # approach +x, x down
    side[:3, 3] = [0.45, -0.2, 0.0]
    side = _at_depth(fingers, side, normal, offset, -0.0005)  # fingertips 0.5 mm above the table
    palm_low = (palm @ side[:3, :3].T + side[:3, 3])[:, 2].min()
    assert palm_low < offset - 0.005  # ... and the palm inside it
    gs = goals.build_goal_set(pen_world, (to_object @ side)[None], settings=NO_QUALITY)
    assert gs.reasons == ["in_collision"]


def test_antipodal_grasps_aware_of_the_support_keep_the_hand_above_it(pen_world):
    from pickplan.omg.grasps.generators import SupportFilter, antipodal_grasps

    support = SupportFilter.under(pen_world.target_pose)
    aware = antipodal_grasps(pen_world.target_model, 20, seed=1, support=support)
    assert len(aware) == 20 and np.all(aware.info["seconds"] > 0)
    hands = pen_world.target_pose @ aware.poses
    normal, offset = _tables_plane(pen_world)
    assert np.all(support.fingers.penetration(hands, normal, offset) <= support.tolerance + 1e-9)
    assert np.all(support.palm.penetration(hands, normal, offset) <= 1e-9)
    assert np.allclose(support.fan(5), np.radians([0, 15, -15, 30, -30]))


def test_success_metric_lets_only_the_fingers_touch_the_table(pen_world):
    """A plan ending with the fingertips 2 mm into the table (within the tolerance) is collision-free;
    the same plan is not when the finger links get no allowance."""
    from dataclasses import replace

    from pickplan.omg.chomp import Chomp, MetricSettings, cubic_initialization

    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    normal, offset = _tables_plane(pen_world)
    down = _down_at(fingers, normal, offset, 0.002)
    gs = goals.build_goal_set(
        pen_world,
        (np.linalg.inv(pen_world.target_pose) @ down)[None],
        settings=NO_QUALITY,
        support=NO_SUPPORT_MODEL_BUT_TOLERANCE,
    )
    assert gs.reasons == ["ok"]
    chomp = Chomp(robot, pen_world.sdf, pen_world.body, exclude=(pen_world.target,))
    xi = cubic_initialization(pen_world.start, gs.goals[0], 30)
    xi[-gs.tails.shape[1] :] = gs.tails[0]
    settings = MetricSettings(tail_waypoints=gs.tails.shape[1])
    allowed = chomp.metrics(xi, pen_world.start, settings)
    strict = chomp.metrics(xi, pen_world.start, replace(settings, support_link_mask=0))
    assert -collision.SupportContact().resolved(robot) <= allowed.min_table_clearance < 0
    assert allowed.collision_free and not strict.collision_free


def test_sampling_planners_validity_follows_the_success_test(pen_world):
    """OMPL's state validity (``SupportValidity``): fingertips 1 mm into the table pass, as the goal set
    and the success test let them; 6 mm (beyond the tolerance) and a palm in the table do not; the
    plain obstacle checker rejects all three (the premise)."""
    from pickplan.eval.baselines import SupportValidity

    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    normal, offset = _tables_plane(pen_world)
    to_object = np.linalg.inv(pen_world.target_pose)
    side = np.eye(4)
    side[:3, :3] = np.column_stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
    side[:3, 3] = [0.45, -0.2, 0.0]
    hands = [
        _down_at(fingers, normal, offset, 0.001),
        _down_at(fingers, normal, offset, 0.006),
        _at_depth(fingers, side, normal, offset, -0.0005),
    ]
    sets = [goals.build_goal_set(pen_world, (to_object @ H)[None], collision_check=False) for H in hands]
    assert all(gs.reasons == ["ok"] for gs in sets)
    qs = [gs.goals[0] for gs in sets]
    depths = fingers.penetration(np.array([robot.link_pose(q, robot.hand_link) for q in qs]), normal, offset)
    assert depths[0] == pytest.approx(0.001, abs=3e-4) and depths[1] == pytest.approx(0.006, abs=3e-4)

    valid = SupportValidity(pen_world, pen_world.start)
    strict = pen_world.checker("obstacles")
    assert all(strict.in_collision(q) for q in qs)
    assert [valid(q) for q in qs] == [True, False, False]
    assert valid(pen_world.start)  # a free state


def test_isf_steps_never_press_the_fingers_deeper_into_the_support(pen_world):
    """f_pml pulls the pads towards a lying pen, i.e. down into the table: with the support, ISF stops
    where the fingertips touch it (or stay as deep as they were); without it the same steps press in.
    The refiner's depth is the exact hull-vertex depth (``HandGeometry``)."""
    robot = pen_world.robot
    fingers = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    normal, offset = _tables_plane(pen_world)
    grasps = grasps_mod.grasp_set(pen_world.target_model, "antipodal", 100, seed=0).poses
    gs = goals.build_goal_set(pen_world, grasps)
    refiner = pen_world.grasp_refiner()
    hands = np.array([robot.link_pose(q, robot.hand_link) for q in gs.goals])
    exact = fingers.penetration(hands, normal, offset)
    assert np.allclose([refiner.support_depth(q) for q in gs.goals], exact, atol=1e-9)

    from pickplan.omg.isf import GraspRefiner

    free = GraspRefiner(pen_world)
    free._native.set_support(np.zeros((0, 3)), np.array([0.0, 0.0, 1.0]), 0.0)  # no support
    pressed, kept = 0, 0
    for q, d0 in zip(gs.goals, exact):
        limit = max(0.0, d0) + 1e-6
        q_ref, _ = refiner.refine(q, 10)
        assert refiner.support_depth(q_ref) <= limit
        kept += bool(np.abs(q_ref - q).max() > 0)
        pressed += refiner.support_depth(free.refine(q, 10)[0]) > limit
    assert pressed > 0  # the premise: unconstrained ISF presses some of these grasps into the table
    assert kept > 0  # and the constrained one still refines grasps
    with pytest.raises(ValueError, match="unit vector"):
        free._native.set_support(fingers.vertices, np.array([0.0, 0.0, 2.0]), 0.0)


def test_cached_finger_geometry_is_the_fresh_one_built_once_per_opening(pen_world):
    """``ModelCache.finger_geometry`` (what plans use): the same hull vertices as building them from the
    meshes, shared by worlds of the same robot, and rebuilt for another finger opening."""
    robot, cache = pen_world.robot, pen_world.cache
    fresh = collision.HandGeometry(robot, pen_world.start, robot.hand_link, robot.finger_links)
    cached = cache.finger_geometry(robot, pen_world.start)
    assert np.array_equal(cached.vertices, fresh.vertices)
    other_world = World(pen_world.scene, cache=cache)
    assert cache.finger_geometry(other_world.robot, other_world.start).vertices is cached.vertices
    assert not cached.vertices.flags.writeable
    closed = np.array(pen_world.start, dtype=float)
    closed[robot.info.arm_dof :] = robot.lower_limits[robot.info.arm_dof :]
    narrow = cache.finger_geometry(robot, closed)
    assert np.array_equal(
        narrow.vertices, collision.HandGeometry(robot, closed, robot.hand_link, robot.finger_links).vertices
    )
    assert not np.allclose(narrow.vertices, fresh.vertices)  # the fingers moved
    with pytest.raises(ValueError, match="vertices"):
        collision.HandGeometry.from_vertices(np.zeros((0, 3)))
