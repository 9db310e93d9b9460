"""The target as the object nearest a point (perception.target), judged against PyBullet's
segmentation of the rendered views; the shared back-projection against the closed-form pinhole."""

import numpy as np
import pytest

from pickplan.core.observation import ObservationError
from pickplan.perception.field import backproject, support_plane, view_points
from pickplan.perception.target import TargetSettings, target_near_point
from pickplan.sim import scenes as scenes_mod
from pickplan.sim.observe import render_observation

from conftest import known_scene


@pytest.fixture(scope="module")
def rendered():
    scene, lib = known_scene()
    obs = render_observation(scene, views=2)
    plane = support_plane(view_points(obs.depth, obs.K, obs.camera_pose, 4))
    return scene, lib, obs, plane


def _segmentation(scene, name, views):
    """PyBullet's own mask of object ``name`` (the renderer's segmentation buffer)."""
    one = scenes_mod.Scene(scene.robot_base, scene.table, scene.objects, name, seed=scene.seed)
    return render_observation(one, views=views).target_mask


def _iou(a, b):
    return (a & b).sum() / (a | b).sum()


def test_backprojection_is_the_pinhole_model():
    K = np.array([[500.0, 0, 320], [0, 510.0, 240], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T[:3, 3] = [0.1, 0.2, 0.3]
    depth = np.full((480, 640), 2.0)
    depth[10, 20] = 0.0
    X = backproject(depth, K, T)
    r, c = 100, 400
    cam = np.array([(c + 0.5 - 320) / 500 * 2.0, (r + 0.5 - 240) / 510 * 2.0, 2.0])
    np.testing.assert_allclose(X[r, c], T[:3, :3] @ cam + T[:3, 3], atol=1e-12)
    assert np.isnan(X[10, 20]).all()


@pytest.mark.parametrize("name", ["004_sugar_box", "005_tomato_soup_can"])
def test_the_object_nearest_a_point_is_the_segmented_object(rendered, name):
    scene, lib, obs, plane = rendered
    o = next(o for o in scene.objects if o.name == name)
    mesh = lib.get(name).mesh.copy()
    mesh.apply_transform(o.pose)
    # a point 2 cm above the object's top: near it, not on it
    point = np.array([*mesh.centroid[:2], mesh.bounds[1][2] + 0.02])
    mask = target_near_point(obs.depth, obs.K, obs.camera_pose, point, plane)
    truth = _segmentation(scene, name, 2)
    for v in range(2):
        assert _iou(mask[v], truth[v]) > 0.9, (name, v, _iou(mask[v], truth[v]))


def test_a_point_far_from_every_object_is_refused(rendered):
    _, _, obs, plane = rendered
    with pytest.raises(ObservationError, match="no object within 0.05 m"):
        target_near_point(obs.depth, obs.K, obs.camera_pose, (0.3, -0.4, 0.02), plane)
    with pytest.raises(ObservationError, match="3 finite coordinates"):
        target_near_point(obs.depth, obs.K, obs.camera_pose, (0.5, np.nan, 0.1), plane)


def test_a_larger_radius_reaches_the_same_object(rendered):
    scene, lib, obs, plane = rendered
    point = np.array([0.55, -0.12, 0.05])  # beside the sugar box, away from the can
    with pytest.raises(ObservationError):
        target_near_point(obs.depth, obs.K, obs.camera_pose, point, plane, TargetSettings(max_distance=0.01))
    mask = target_near_point(obs.depth, obs.K, obs.camera_pose, point, plane, TargetSettings(max_distance=0.15))
    truth = _segmentation(scene, "004_sugar_box", 2)
    assert _iou(mask[0], truth[0]) > 0.9
