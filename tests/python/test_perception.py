"""Planning's world from depth cameras: observations (format, errors), the fused field against exact
distances of a known scene, unseen space behind a surface, the support plane, the target's points."""

import numpy as np
import pytest
import trimesh

from conftest import known_scene as _known_scene
from pickplan import _core
from pickplan.core.observation import Observation, ObservationError, grow_target
from pickplan.perception.field import FieldSettings, perceive, support_plane
from pickplan.sim.observe import CameraRig, render_observation

RES = 0.01


def _world_mesh(scene, lib, name):
    o = next(o for o in scene.objects if o.name == name)
    mesh = lib.get(name).mesh.copy()
    mesh.apply_transform(o.pose)
    return mesh


@pytest.fixture(scope="module")
def known():
    scene, lib = _known_scene()
    return scene, lib, render_observation(scene, views=3)


def test_the_distance_transform_is_exact():
    rng = np.random.default_rng(0)
    mask = (rng.random((7, 9, 11)) < 0.05).astype(np.uint8)
    d2 = _core.squared_distance_transform(mask)
    ones = np.argwhere(mask)
    for idx in np.ndindex(mask.shape):
        assert d2[idx] == pytest.approx(((ones - idx) ** 2).sum(axis=1).min(), abs=1e-3)


def test_the_field_matches_exact_distances_where_observed(known):
    scene, lib, obs = known
    perceived = perceive(obs, FieldSettings(resolution=RES))
    can = _world_mesh(scene, lib, "005_tomato_soup_can")
    top = can.bounds[1][2]
    rng = np.random.default_rng(1)
    # above the can, and on its side facing the first camera (+x): seen by every view or by the first
    pts = np.vstack(
        [
            np.column_stack(
                [
                    rng.uniform(*can.bounds[:, 0], 40),
                    rng.uniform(*can.bounds[:, 1], 40),
                    top + rng.uniform(0.02, 0.08, 40),
                ]
            ),
            np.column_stack(
                [
                    can.bounds[1][0] + rng.uniform(0.02, 0.06, 40),
                    np.full(40, can.centroid[1]),
                    rng.uniform(0.02, top - 0.02, 40),
                ]
            ),
        ]
    )
    exact = np.abs(trimesh.proximity.signed_distance(can, pts))
    d, _ = perceived.sdf.distance(pts, exclude_table=True)
    np.testing.assert_allclose(d, exact, atol=RES)


def test_space_no_camera_has_seen_behind_a_surface_is_occupied():
    scene, lib = _known_scene()
    obs = render_observation(scene, views=1)  # one camera across the table, looking at the robot (-x)
    perceived = perceive(obs, FieldSettings(resolution=RES))
    can = _world_mesh(scene, lib, "005_tomato_soup_can")  # an obstacle (the box is the target)
    behind = np.array([[can.bounds[0][0] - 0.03, can.centroid[1], 0.03]])  # 3 cm behind the can, low
    assert trimesh.proximity.signed_distance(can, behind)[0] < -0.02  # truly outside the can...
    d, _ = perceived.sdf.distance(behind, exclude_table=True)
    assert d[0] <= 0.0  # ...but hidden by it: occupied
    d3, _ = perceive(render_observation(scene, views=3), FieldSettings(resolution=RES)).sdf.distance(
        behind, exclude_table=True
    )
    assert d3[0] > 0.0  # the side cameras see behind it


def test_the_support_plane_is_the_table_top(known):
    _, _, obs = known
    perceived = perceive(obs)
    n, d = perceived.plane
    assert n @ [0, 0, 1] > 0.999 and abs(d) < 0.003


def test_target_points_lie_on_the_target_with_outward_normals(known):
    scene, lib, obs = known
    perceived = perceive(obs)
    box = _world_mesh(scene, lib, "004_sugar_box")
    P, N = perceived.target_points, perceived.target_normals
    assert len(P) > 500
    closest, dist, tri = trimesh.proximity.closest_point(box, P)
    assert np.percentile(dist, 95) < 0.004
    assert np.mean(np.einsum("ij,ij->i", N, box.face_normals[tri]) > 0.9) > 0.9
    # the target is not an obstacle: its surface is far from the obstacle field's zero level
    d, _ = perceived.sdf.distance(P[::10], exclude_table=True)
    assert np.median(d) > 0.02


def test_noise_moves_the_field_by_about_the_noise(known):
    """2 mm of depth noise moves the fused field by about that (a voxel at most where a surface
    estimate crosses a voxel boundary), not more, and the support plane by less than 4 mm."""
    scene, lib, obs = known
    noise = 0.002
    noisy = render_observation(scene, views=3, noise=noise, seed=3)
    assert not np.array_equal(noisy.depth, obs.depth)
    clean_field, noisy_field = (
        perceive(obs, FieldSettings(resolution=RES)),
        perceive(noisy, FieldSettings(resolution=RES)),
    )
    can = _world_mesh(scene, lib, "005_tomato_soup_can")
    rng = np.random.default_rng(2)
    lo, hi = can.bounds[0] - [0.08, 0.08, 0.0], can.bounds[1] + [0.08, 0.08, 0.08]
    pts = rng.uniform(lo, hi, (2000, 3))
    pts = pts[trimesh.proximity.signed_distance(can, pts) < -0.01]  # outside the can, by 1 cm at least
    d_clean, _ = clean_field.sdf.distance(pts, exclude_table=True)
    d_noisy, _ = noisy_field.sdf.distance(pts, exclude_table=True)
    moved = np.abs(d_noisy - d_clean)
    assert moved.max() > 0  # the noise does reach the field
    assert np.median(moved) <= 2 * noise and np.percentile(moved, 99) <= RES + 3 * noise
    n, d = noisy_field.plane
    assert n @ [0, 0, 1] > 0.999 and abs(d) < 0.004


def test_observations_round_trip_and_refuse_bad_input(tmp_path, known):
    _, _, obs = known
    path = tmp_path / "obs.npz"
    obs.save(path)
    back = Observation.load(path)
    assert np.array_equal(back.depth, obs.depth) and np.array_equal(back.target_mask, obs.target_mask)
    cases = {
        "target_mask: expected shape": dict(target_mask=obs.target_mask[:, :-1]),
        "camera_pose: view 0 is not a rigid transform": dict(
            camera_pose=obs.camera_pose * np.array([1, 1, 1, 1.0])[:, None] * 1.01
        ),
        "has depth in only 0.0 %": dict(depth=np.zeros_like(obs.depth)),
        "negative or infinite": dict(depth=-obs.depth),
        "K: expected shape": dict(K=obs.K[:, :2]),
        "the target has no pixel": dict(target_mask=np.zeros_like(obs.target_mask)),
    }
    for message, change in cases.items():
        fields = dict(depth=obs.depth, K=obs.K, camera_pose=obs.camera_pose, target_mask=obs.target_mask)
        fields.update(change)
        with pytest.raises(ObservationError, match=message):
            Observation(**fields)
    nan_view = obs.depth.copy()
    nan_view[0] = np.nan
    with pytest.raises(ObservationError, match="view 0 has depth in only"):
        Observation(nan_view, obs.K, obs.camera_pose, obs.target_mask)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ObservationError, match="not a readable"):
        Observation.load(tmp_path / "junk.npz")
    with pytest.raises(FileNotFoundError):
        Observation.load(tmp_path / "none.npz")


def test_a_target_pixel_grows_to_its_surface(known):
    _, _, obs = known
    r, c = np.argwhere(obs.target_mask[0])[len(np.argwhere(obs.target_mask[0])) // 2]
    grown = grow_target(obs.depth[:1], [[r, c]])
    inter = (grown[0] & obs.target_mask[0]).sum()
    assert inter > 0.5 * obs.target_mask[0].sum()  # recall: most of the target's pixels


@pytest.mark.xfail(
    strict=True,
    reason="found by issue 32: grow_target leaks from the box's foot onto the table "
    "(depth is continuous where an object stands on it): 2,438 of 226,900 grown "
    "pixels are the target's; fix grow_target, then drop this mark",
)
def test_a_grown_target_stays_on_the_target(known):
    _, _, obs = known
    r, c = np.argwhere(obs.target_mask[0])[len(np.argwhere(obs.target_mask[0])) // 2]
    grown = grow_target(obs.depth[:1], [[r, c]])
    inter = (grown[0] & obs.target_mask[0]).sum()
    assert inter > 0.95 * grown[0].sum()  # precision: it does not leak onto the table or the can


def test_cameras_look_at_the_table_from_a_mountable_distance():
    rig = CameraRig()
    for T in rig.camera_poses(3):
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3)) and T[2, 3] > 0.5
        to_target = np.asarray(rig.look_at) - T[:3, 3]
        assert np.dot(T[:3, 2], to_target / np.linalg.norm(to_target)) > 0.999


@pytest.mark.parametrize("views", [3, 1])
def test_grasps_from_points_lift_the_true_object_in_pybullet(views):
    from pickplan.core import robots
    from pickplan.omg import isf
    from pickplan.omg.grasps import physics
    from pickplan.omg.grasps.points import grasps_from_points

    scene, lib = _known_scene()
    perceived = perceive(render_observation(scene, views=views))
    gs = grasps_from_points(
        perceived.target_points,
        perceived.target_normals,
        perceived.plane,
        isf.hand_sdf(robots.panda()),
        n=5,
        seed=0,
        scene_distance=lambda X: perceived.sdf.distance(X, cutoff=0.1)[0],
    )
    assert len(gs) == 5 and gs.name == "points"
    # judged on the true object: the grasps (world frame) in the object's frame, the object resting as in the scene
    model = lib.get("004_sugar_box")
    T_obj = next(o.pose for o in scene.objects if o.name == "004_sugar_box")
    upright = int(np.argmax([r[2, 2] for r in model.resting_poses]))
    lifted = physics.lift_test(
        model, np.linalg.inv(T_obj) @ gs.poses, physics.LiftSettings(rest_index=upright, table_clearance=-0.004)
    )
    assert (lifted == 1).sum() >= 4, lifted


def test_the_support_plane_is_found_among_outliers():
    rng = np.random.default_rng(2)
    n_true = np.array([0.05, -0.03, 1.0])
    n_true /= np.linalg.norm(n_true)
    xy = rng.uniform(-0.5, 0.5, (3000, 2))
    on = np.column_stack([xy, (0.02 - n_true[0] * xy[:, 0] - n_true[1] * xy[:, 1]) / n_true[2]])
    on += rng.normal(0, 0.001, on.shape)
    clutter = rng.uniform([-0.3, -0.3, 0.03], [0.3, 0.3, 0.3], (1500, 3))
    n, d = support_plane(np.vstack([on, clutter]), seed=0)
    assert n @ n_true > 0.9999 and abs(d - 0.02) < 0.002
    with pytest.raises(ValueError, match="no near-horizontal plane"):
        support_plane(np.column_stack([np.zeros(50), rng.uniform(size=(50, 2))]), seed=0)
