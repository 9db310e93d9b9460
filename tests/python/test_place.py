"""Place requests and place goal sets (omg.place): requests checked at the door, candidates inside the
region by exact geometry, every goal of a set puts the object at rest in the region (dropped in
PyBullet), and an empty set says why."""

import json
from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest

from pickplan.core import objects
from pickplan.core.errors import InputError
from pickplan.omg.attach import HeldWorld, held_from_poses, straight_path
from pickplan.omg.goals import GoalSetSettings
from pickplan.omg.place import (
    Orientation,
    PlaceRequest,
    PlaceSettings,
    PlaceVerdict,
    build_place_goal_set,
    candidate_poses,
    resting_rotations,
)
from pickplan.omg.world import World
from pickplan.sim import bodies, scenes
from test_attach import BOX, _ik

from conftest import standing_pose

CAN = "005_tomato_soup_can"


@pytest.fixture(scope="module")
def held_case():
    """The sugar box held from above by its top, lifted 10 cm; a soup can beside it."""
    lib = objects.library("builtin")
    box, can = lib.get(BOX), lib.get(CAN)
    box_pose, can_pose = standing_pose(box, (0.5, 0.0)), standing_pose(can, (0.5, 0.25))
    scene = scenes.Scene(
        np.eye(4),
        scenes.default_table(),
        [scenes.SceneObject(BOX, f"builtin:{BOX}", box_pose), scenes.SceneObject(CAN, f"builtin:{CAN}", can_pose)],
        BOX,
        seed=0,
    )
    world = World(scene)
    robot = world.robot
    top = float((box.mesh.vertices @ box_pose[:3, :3].T + box_pose[:3, 3])[:, 2].max())
    hand = np.eye(4)
    thin = box_pose[:3, int(np.argmin(box.extents))]
    hand[:3, 2] = [0.0, 0.0, -1.0]
    hand[:3, 1] = thin if thin[1] >= 0 else -thin
    hand[:3, 0] = np.cross(hand[:3, 1], hand[:3, 2])
    hand[:3, 3] = [0.5, 0.0, top - 0.03 + robot.grasp_frame[2, 3]]
    carrying = HeldWorld(world, held_from_poses(BOX, hand, box_pose, box.mesh))
    q_grasp = _ik(robot, hand, robot.ready_configuration)
    lift, ok = straight_path(carrying.robot, q_grasp, (0, 0, 1), 0.1, 5)
    assert ok
    return world, carrying, lift[-1], box


def test_request_files_are_checked_at_the_door(tmp_path):
    good = {"region": {"min": [0.4, -0.4, 0.0], "max": [0.6, -0.2, 0.4]}, "orientation": "stable"}
    path = tmp_path / "region.json"
    path.write_text(json.dumps(good))
    request = PlaceRequest.load(str(path))
    assert request.orientation is Orientation.stable and request.floor == 0.0
    assert PlaceRequest.from_dict(request.to_dict()) == request
    for bad, field in (
        ({"region": {"min": [0, 0, 0], "max": [0.1, -0.1, 0.2]}}, "region.max"),
        ({"region": {"min": [0, 0]}}, "region.min"),
        ({**good, "tolerance_deg": 0}, "tolerance_deg"),
        ({**good, "rotation": [[1, 0, 0], [0, 1, 0], [0, 0, 2]]}, "rotation"),
        ({**good, "orientation": "sideways"}, "orientation"),
        ({**good, "orientation": "pose"}, "rotation"),
        ({**good, "colour": "red"}, "colour"),
    ):
        path.write_text(json.dumps(bad))
        with pytest.raises(InputError) as err:
            PlaceRequest.load(str(path))
        assert str(path) in str(err.value) and field in str(err.value)
    path.write_text(json.dumps({"region": {"min": [0, 0, 0], "max": [1, 1, -1]}, "yaw_deg": "north"}))
    with pytest.raises(InputError) as err:  # every problem at once
        PlaceRequest.load(str(path))
    assert {p.field for p in err.value.problems} == {"region.max", "yaw_deg"}
    path.write_text("{not json")
    with pytest.raises(InputError):
        PlaceRequest.load(str(path))


def test_candidates_keep_the_whole_object_inside_the_region(held_case):
    _, carrying, _, box = held_case
    request = PlaceRequest((0.35, -0.45, 0.0), (0.65, -0.2, 0.4), "stable")
    settings = PlaceSettings()
    rotations = resting_rotations(request, carrying.base.target_pose, box, settings.max_rests)
    assert len(rotations) == min(settings.max_rests, len(box.resting_poses))
    poses = candidate_poses(request, box.mesh.vertices, rotations, settings)
    assert len(poses) > 50
    V = np.einsum("nij,vj->nvi", poses[:, :3, :3], box.mesh.vertices) + poses[:, None, :3, 3]
    assert V[..., :2].min() >= -0.45 - 1e-12 and V[..., 0].min() >= 0.35 - 1e-12
    assert V[..., 0].max() <= 0.65 + 1e-12 and V[..., 1].max() <= -0.2 + 1e-12
    np.testing.assert_allclose(V[..., 2].min(axis=1), settings.gap, atol=1e-12)  # lowest point: gap above the floor


def test_fingers_below_the_object_are_kept_above_the_floor_too(held_case):
    """A pinch low on the object reaches below it: with the fingers' vertices (object frame) given, each
    candidate's lowest point of object and fingers together is ``gap`` above the floor (the object then
    higher by as much as the fingers reach below it); fingers within the object change nothing."""
    _, carrying, _, box = held_case
    request = PlaceRequest((0.35, -0.45, 0.0), (0.65, -0.2, 0.4), "stable")
    settings = PlaceSettings()
    rotations = resting_rotations(request, carrying.base.target_pose, box, settings.max_rests)
    plain = candidate_poses(request, box.mesh.vertices, rotations, settings)
    down = rotations[0].T @ [0.0, 0.0, -1.0]  # the world's down in the object as it rests first
    below = box.mesh.vertices[(box.mesh.vertices @ down).argmax()] + 0.01 * down  # 1 cm under its lowest point
    fingers = np.array([below, below - 0.05 * down])
    poses = candidate_poses(request, box.mesh.vertices, rotations, settings, fingers)
    assert len(poses) == len(plain)
    V = np.einsum("nij,vj->nvi", poses[:, :3, :3], np.vstack([box.mesh.vertices, fingers])) + poses[:, None, :3, 3]
    np.testing.assert_allclose(V[..., 2].min(axis=1), settings.gap, atol=1e-12)
    assert np.all(poses[:, 2, 3] >= plain[:, 2, 3] - 1e-12) and np.any(poses[:, 2, 3] > plain[:, 2, 3] + 1e-3)
    inside = box.mesh.vertices.mean(axis=0)[None]  # within the object's hull: never below its lowest point
    np.testing.assert_allclose(candidate_poses(request, box.mesh.vertices, rotations, settings, inside), plain)


def _rest(client, body, model, seconds=1.5):
    for _ in range(int(seconds * 240)):
        pb.stepSimulation(physicsClientId=client)
    v, w = pb.getBaseVelocity(body, physicsClientId=client)
    return scenes.object_pose(client, body, model), float(np.linalg.norm(v)), float(np.linalg.norm(w))


@pytest.mark.parametrize("orientation", ["upright", "stable"])
def test_every_place_goal_puts_the_object_at_rest_in_the_region(held_case, orientation):
    world, carrying, start, box = held_case
    request = PlaceRequest((0.35, -0.45, 0.0), (0.65, -0.2, 0.4), orientation)
    goals = build_place_goal_set(
        carrying, request, start, PlaceSettings(goals=GoalSetSettings(max_goals=12, standoff=0.1)), model=box
    )
    assert goals.verdict is PlaceVerdict.ok and len(goals) >= 5, goals.reason_counts()
    robot = carrying.robot
    for g, q in enumerate(goals.goal_set.goals):
        hand = robot.link_pose(q, robot.hand_link)
        planned = carrying.held.object_pose(hand)
        np.testing.assert_allclose(planned, goals.object_poses[goals.goal_set.grasp_index[g]], atol=2e-3)
        client = pb.connect(pb.DIRECT)
        try:
            pb.setGravity(0, 0, -9.81, physicsClientId=client)
            bodies.add_table(client, world.scene.table)
            body = bodies.add_object_body(client, box, planned)
            final, v, w = _rest(client, body, box)
        finally:
            pb.disconnect(client)
        hull = box.mesh.convex_hull.vertices @ final[:3, :3].T + final[:3, 3]
        assert v < 0.01 and w < 0.1
        assert np.all(hull >= np.array(request.region_min) - 0.005) and np.all(
            hull <= np.array(request.region_max) + 0.005
        )
        up = np.clip((final[:3, :3].T @ [0, 0, 1]) @ (planned[:3, :3].T @ [0, 0, 1]), -1, 1)
        assert np.degrees(np.arccos(up)) < 5.0  # it lands as planned, not toppled


def test_an_empty_place_goal_set_says_why(held_case):
    _, carrying, start, box = held_case
    small = PlaceRequest((0.5, -0.3, 0.0), (0.53, -0.27, 0.4))  # 3 x 3 cm: the box does not fit
    far = PlaceRequest((1.0, 0.65, 0.0), (1.09, 0.78, 0.4))  # beyond the arm's reach
    can = carrying.base.scene.object(CAN).pose  # only the can's own footprint
    blocked = PlaceRequest((can[0, 3] - 0.07, can[1, 3] - 0.07, 0.0), (can[0, 3] + 0.07, can[1, 3] + 0.07, 0.4))
    shelf = PlaceRequest((0.4, -0.4, 0.2), (0.6, -0.2, 0.5))  # a floor in mid-air
    for request, verdict in (
        (small, PlaceVerdict.too_small),
        (far, PlaceVerdict.out_of_reach),
        (blocked, PlaceVerdict.blocked),
        (shelf, PlaceVerdict.no_support),
    ):
        goals = build_place_goal_set(carrying, request, start, model=box)
        assert len(goals) == 0 and goals.verdict is verdict, goals.reason_counts()
        assert goals.reason == f"no_place_goals: {verdict.value}"


def test_hull_vertices_give_the_candidates_all_vertices_give(held_case):
    """The place candidates read only the object's extents under each rotation, which its hull's
    vertices attain exactly: the same poses, bit for bit, from a few hundred vertices as from thousands."""
    import trimesh

    from pickplan.omg.place import hull_vertices

    mesh = trimesh.creation.capsule(height=0.1, radius=0.03, count=[48, 48])
    V = np.asarray(mesh.vertices) + np.random.default_rng(0).normal(scale=1e-4, size=mesh.vertices.shape)
    H = hull_vertices(V)
    assert 8 <= len(H) < len(V)
    request = PlaceRequest((0.35, -0.45, 0.0), (0.65, -0.2, 0.4), "upright")
    rotations = [np.eye(3), trimesh.transformations.rotation_matrix(0.7, (1, 1, 0))[:3, :3]]
    settings = PlaceSettings()
    np.testing.assert_array_equal(
        candidate_poses(request, H, rotations, settings), candidate_poses(request, V, rotations, settings)
    )
    flat = np.c_[np.random.default_rng(1).uniform(size=(20, 2)), np.zeros(20)]  # no volume: every point kept
    assert len(hull_vertices(flat)) == 20


def test_pre_places_keep_the_transit_clearance_and_the_cap_counts_only_such_goals(held_case):
    """Places around the can: a pre-place (15 cm above its place) nearer the can than the clearance asked
    (8 cm here: the can is short) is rejected inside the goal-set loop ("pregrasp_clearance"), so it never takes one of the
    ``max_goals`` places (a full set when enough places pass). Clearance measured here on the body points
    in the scene SDF, the held object's old place and the table left out."""
    _, carrying, start, box = held_case
    can = carrying.base.scene.object(CAN).pose
    request = PlaceRequest((can[0, 3] - 0.15, can[1, 3] - 0.15, 0.0), (can[0, 3] + 0.15, can[1, 3] + 0.15, 0.4))
    goals = GoalSetSettings(standoff=0.15, standoff_steps=5, approach_clearance=0.01, max_goals=100)
    settings = PlaceSettings(goals=goals, preplace_clearance=0.08)
    every = build_place_goal_set(carrying, request, start, settings, model=box)
    reasons = every.reason_counts()
    assert reasons.get("pregrasp_clearance", 0) > 0 and len(every) >= 6, reasons
    X = carrying.robot.transform_points(every.goal_set.tails[:, 0], carrying.body)
    d, _ = carrying.sdf.distance(X.reshape(-1, 3), cutoff=1.0, exclude=(carrying.target,), exclude_table=True)
    assert d.reshape(len(X), -1).min(axis=1).min() >= settings.preplace_clearance - 1e-6
    capped = build_place_goal_set(
        carrying, request, start, replace(settings, goals=replace(goals, max_goals=5)), model=box
    )
    assert len(capped) == 5, capped.reason_counts()


def test_a_place_goal_set_does_not_read_another_grasps_robot(held_case):
    """The model cache keys the IK solver by robot model: a held object grasped differently is another
    robot (its held link elsewhere), and its place goal set must be the one a fresh cache builds (the
    bench planned every unit after the first with the first unit's held link: all ``in_collision``)."""
    world, carrying, start, box = held_case
    free = PlaceRequest((0.4, -0.45, 0.0), (0.64, -0.25, 0.4))
    assert len(build_place_goal_set(carrying, free, start, model=box)) > 0  # grasp A's solver in the cache
    higher = carrying.held.hand_T_object.copy()
    higher[2, 3] -= 0.03  # grasp B: the box 3 cm further up in the hand (its approach axis, z, points down)
    held_b = replace(carrying.held, hand_T_object=higher)
    shared = build_place_goal_set(HeldWorld(world, held_b), free, start, model=box)
    fresh = build_place_goal_set(HeldWorld(World(world.scene), held_b), free, start, model=box)
    assert len(fresh) > 0
    assert shared.goal_set.reasons == fresh.goal_set.reasons
    np.testing.assert_array_equal(shared.goal_set.goals, fresh.goal_set.goals)


def _held_cube(world, tilt_deg: float, extents=(0.03, 0.03, 0.03)) -> HeldWorld:
    """A 3 cm cube (a box of ``extents``) held by its middle from above, the closing axis (y) tilted
    ``tilt_deg`` (a grasp the object turned in)."""
    import trimesh

    cube = trimesh.creation.box(extents=extents)
    pose = np.eye(4)
    pose[:3, 3] = (0.5, 0.0, extents[2] / 2)
    hand = np.eye(4)
    hand[:3, :3] = np.array([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]).T  # x, y, z columns: down
    hand[:3, 3] = pose[:3, 3] + [0.0, 0.0, world.robot.grasp_frame[2, 3]]
    tilt = trimesh.transformations.rotation_matrix(np.radians(tilt_deg), (1.0, 0.0, 0.0), pose[:3, 3])
    return HeldWorld(world, held_from_poses(BOX, tilt @ hand, pose, cube))


def test_the_fingers_opened_for_the_release_stay_above_the_floor(held_case):
    """A 3 cm cube held by its middle with the closing axis tilted 20 deg (a grasp the object turned in):
    opening the fingers at the place sends one finger 7 mm further down. Every place goal keeps both
    fingers, closed and opened (forward kinematics of the goal with the fingers open, the finger links'
    collision meshes), off the floor."""
    world, _, start, _ = held_case
    robot = world.robot
    carrying = _held_cube(world, 20.0)
    request = PlaceRequest((0.35, -0.45, 0.0), (0.65, -0.2, 0.4), "upright")
    settings = PlaceSettings(goals=GoalSetSettings(max_goals=12, standoff=0.1))
    goals = build_place_goal_set(carrying, request, robot.with_fingers(start, 0.015), settings)
    assert len(goals) >= 5, goals.reason_counts()

    def lowest_finger_point(q):
        poses = robot.fk(q)
        return min(
            float((np.asarray(m.vertices) @ T[:3, :3].T + T[:3, 3])[:, 2].min())
            for T, m in ((poses[robot.link_index(n)], robot.collision_meshes(n)) for n in robot.finger_links)
        )

    for q in goals.goal_set.goals:
        closed, opened = lowest_finger_point(q), lowest_finger_point(robot.with_fingers(q, robot.info.finger_open))
        assert opened < closed - 0.005  # the tilt sends the opening finger down
        assert opened >= settings.gap - 1e-3


def test_no_place_goal_opens_a_finger_into_a_bin_wall(held_case):
    """The 3 cm cube set down in a 14 x 8 cm tray with 3 cm walls: its fingers, closed on it, clear the walls
    at every heading, but opened (4 cm each) they reach the long walls unless they open along the tray.
    Those goals are dropped (``release_in_collision``), and every goal kept opens its fingers clear of
    everything (FCL, nothing allowed to touch)."""
    from pickplan.core.containers import bin_source
    from pickplan.omg.world import CheckerKind

    world0, _, start, _ = held_case
    tray = np.eye(4)
    tray[:3, 3] = (0.5, -0.3, 0.0)
    scene = replace(
        world0.scene,
        objects=list(world0.scene.objects) + [scenes.SceneObject("tray", bin_source(0.14, 0.08, 0.03), tray)],
    )
    world = World(scene)
    carrying = _held_cube(world, 0.0)
    request = PlaceRequest((0.43, -0.34, 0.0), (0.57, -0.26, 0.4))
    goals = GoalSetSettings(standoff=0.1, standoff_steps=5, max_goals=600, diversity=0.0)
    settings = PlaceSettings(goals=goals, margin=0.0)
    place = build_place_goal_set(carrying, request, world.robot.with_fingers(start, 0.015), settings)
    reasons = place.reason_counts()
    assert reasons.get("release_in_collision", 0) > 0 and len(place) >= 2, reasons
    robot, strict = world.robot, world.checker(CheckerKind.strict)
    opened = robot.with_fingers(place.goal_set.goals, robot.info.finger_open)
    assert not strict.in_collision_batch(opened).any()


def test_a_region_only_a_finer_grid_fits_gets_goals_from_it(held_case):
    """A 30 x 2.5 cm bar in a 29 x 15 cm region fits only turned 22.5 deg (or 157.5) from the region's
    long side: exact extents at 0 deg (30 cm) and 45 deg (23 cm across) are too big, and the coarse grid's
    8 yaws hold no other. The goal set samples the region again twice as finely, and every goal found
    holds the bar inside the region at one of those headings."""
    world, _, start, _ = held_case
    carrying = _held_cube(world, 0.0, extents=(0.30, 0.025, 0.025))
    request = PlaceRequest((0.355, -0.45, 0.0), (0.645, -0.30, 0.4), "upright")
    coarse = build_place_goal_set(carrying, request, start, PlaceSettings(refine=1))
    assert len(coarse) == 0 and coarse.verdict is PlaceVerdict.too_small
    place = build_place_goal_set(carrying, request, start, PlaceSettings())
    assert len(place) >= 1, place.reason_counts()
    for index in place.goal_set.grasp_index:
        pose = place.object_poses[index]
        along = np.degrees(np.arctan2(pose[1, 0], pose[0, 0])) % 180.0
        assert min(abs(along - 22.5), abs(along - 157.5)) < 1e-6
        corners = np.array([[sx * 0.15, sy * 0.0125, 0.0] for sx in (-1, 1) for sy in (-1, 1)]) @ pose[:3, :3].T
        xy = corners[:, :2] + pose[:2, 3]
        assert (xy >= np.array(request.region_min[:2]) - 1e-9).all() and (
            xy <= np.array(request.region_max[:2]) + 1e-9
        ).all()


def test_rests_the_object_could_roll_out_of_come_last():
    """Four rests: the two whose barrier (centre-of-mass rise to tip) exceeds the release's fall come
    first, most likely first, though the others are likelier; then the one that tips most hardly. With no
    fall given, the likeliest first, as before; a model without barriers keeps that order."""
    from types import SimpleNamespace

    turns = [np.eye(4) for _ in range(4)]
    for k, T in enumerate(turns):
        T[:3, :3] = _quarter_turns(k)
    model = SimpleNamespace(
        resting_poses=turns, resting_probabilities=[0.1, 0.5, 0.3, 0.2], resting_barriers=[0.02, 0.001, 0.003, 0.01]
    )
    request = PlaceRequest((0.3, -0.2, 0.0), (0.6, 0.2, 0.4), "stable")

    def order(rotations):
        return [next(k for k, T in enumerate(turns) if np.allclose(T[:3, :3], R)) for R in rotations]

    assert order(resting_rotations(request, np.eye(4), model, 3, drop=lambda R: 0.004)) == [3, 0, 2]
    assert order(resting_rotations(request, np.eye(4), model, 3)) == [1, 2, 3]
    model.resting_barriers = []
    assert order(resting_rotations(request, np.eye(4), model, 4, drop=lambda R: 0.004)) == [1, 2, 3, 0]


def _quarter_turns(k: int) -> np.ndarray:
    """A quarter turn ``k`` times about x: distinct rotations to tell rests apart."""
    c, s = np.cos(k * np.pi / 2), np.sin(k * np.pi / 2)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def test_the_fall_at_the_release_counts_fingers_below_the_object():
    """``release_drop``: the gap alone when the fingers hold it above its lowest point; the fingers'
    reach below it added (the object is lifted that much to keep them off the floor)."""
    from pickplan.omg.place import release_drop

    cube = np.array([[x, y, z] for x in (-0.02, 0.02) for y in (-0.02, 0.02) for z in (-0.02, 0.02)])
    high = np.array([[0.0, 0.03, 0.0], [0.0, -0.03, 0.0]])
    low = np.array([[0.0, 0.03, -0.03], [0.0, -0.03, -0.03]])
    assert release_drop(cube, high, 0.004)(np.eye(3)) == pytest.approx(0.004)
    assert release_drop(cube, low, 0.004)(np.eye(3)) == pytest.approx(0.014)
    assert release_drop(cube, None, 0.004)(np.eye(3)) == pytest.approx(0.004)
