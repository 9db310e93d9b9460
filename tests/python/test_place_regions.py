"""The bench's place regions (eval.place_regions): the covered share and the free disc of a region by
exact geometry; generated regions are seeded, free regions and bins clear of the clutter, a partly
cluttered region reaches into the clutter and leaves room for the target."""

import numpy as np
from scipy.spatial import ConvexHull

from pickplan.core import objects
from pickplan.eval.place_regions import RegionKind, RegionSettings, _cover, _hulls_xy, place_task
from pickplan.sim import scenes

from conftest import standing_scene


def _square(lo, hi):
    return ConvexHull(np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])).equations


def test_cover_is_the_share_and_the_largest_free_disc():
    lo, hi, step = np.array([0.0, 0.0]), np.array([0.2, 0.1]), 0.01

    def near(radius, truth):  # centres on a grid of cells: up to one cell short, never more
        return truth - step <= radius <= truth + 1e-12

    share, radius = _cover([], lo, hi, step)
    assert share == 0.0 and near(radius, 0.05)  # empty: the disc touches both long sides
    share, radius = _cover([_square((0.1, -0.1), (0.3, 0.2))], lo, hi, step)  # the right half covered
    assert share == 0.5 and near(radius, 0.05)
    share, radius = _cover([_square((0.0, 0.04), (0.2, 0.06))], lo, hi, step)  # a 2 cm bar across the middle
    assert abs(share - 0.2) <= 0.1 and near(radius, 0.02)
    share, radius = _cover([_square((0.0, 0.0), (0.2, 0.1))], lo, hi, step)  # all of it
    assert share == 1.0 and radius <= 0.0


def _overlaps(scene, request, skip=None):
    lo, hi = np.array(request.region_min[:2]), np.array(request.region_max[:2])
    return [
        name
        for name, xy in _hulls_xy(scene)
        if name != skip and np.all(xy.max(axis=0) > lo) and np.all(xy.min(axis=0) < hi)
    ]


def test_regions_are_seeded_clear_or_partly_cluttered():
    scene, _ = standing_scene(
        (
            ("004_sugar_box", (0.5, 0.0)),
            ("005_tomato_soup_can", (0.55, 0.25)),
            ("025_mug", (0.45, -0.28)),
            ("010_potted_meat_can", (0.62, 0.3)),
        ),
        "004_sugar_box",
    )
    for kind in RegionKind:
        with_region, request = place_task(scene, kind, seed=5)
        assert place_task(scene, kind, seed=5)[1] == request
        floor = float(scene.table.pose[2, 3] + 0.5 * scene.table.size[2])
        assert request.region_min[2] == floor
        if kind is RegionKind.cluttered:
            assert _overlaps(scene, request, skip=scene.target)  # some object stands in it
        else:
            assert not _overlaps(scene, request)
        if kind is RegionKind.bin:  # the walls stand around the region, outside it
            walls = dict(_hulls_xy(with_region))["bin"]
            assert np.all(walls.min(axis=0) < request.region_min[:2]) and np.all(
                walls.max(axis=0) > request.region_max[:2]
            )
        else:
            assert with_region is scene


def test_more_candidates_are_drawn_until_the_target_has_room():
    """A bowl among a cracker box, a can and a mug (a bench scene's layout): none of the first 12
    candidate regions leaves it a free disc of its radius (a region it cannot be set down in, "region
    blocked" whatever the planner does); the later ones do, and the region chosen is one of those."""
    from pickplan.eval.place_regions import RegionSettings, _footprints, _radius_xy

    scene, _ = standing_scene(
        (
            ("003_cracker_box", (0.749, 0.192)),
            ("002_master_chef_can", (0.52, 0.283)),
            ("025_mug", (0.569, -0.303)),
            ("024_bowl", (0.38, 0.302)),
        ),
        "024_bowl",
    )
    room = _radius_xy(scene) + RegionSettings().clutter_margin
    footprints = _footprints(scene, scene.target)

    def cover(request):
        return _cover(footprints, np.array(request.region_min[:2]), np.array(request.region_max[:2]))

    _, first = place_task(scene, RegionKind.cluttered, seed=29, settings=RegionSettings(clutter_batches=1))
    assert cover(first)[1] < room
    _, request = place_task(scene, RegionKind.cluttered, seed=29)
    share, radius = cover(request)
    assert radius >= room and share > 0.0 and _overlaps(scene, request, skip=scene.target)


def test_a_region_grows_to_hold_a_target_longer_than_it_and_no_other():
    """A 28 cm hammer lying on the table: every kind of region (a bin's inside too) holds its footprint,
    turned to fit, with ``fit_margin`` on each side; a soup can's regions keep the default sizes."""
    lib = objects.library("procedural")
    hammer = lib.get("hammer_00")
    pose = np.asarray(hammer.resting_poses[0], dtype=float).copy()
    pose[:2, 3] = (0.55, 0.1)
    settings = RegionSettings()
    scene = scenes.Scene(
        np.eye(4),
        scenes.default_table(),
        [scenes.SceneObject("hammer_00", "procedural:hammer_00", pose)],
        "hammer_00",
        seed=0,
    )
    xy = (hammer.mesh.vertices @ pose[:3, :3].T)[:, :2]
    length = float(np.ptp(xy @ np.linalg.eigh(np.cov((xy - xy.mean(0)).T))[1], axis=0).max())
    assert length > max(settings.size)
    for kind in RegionKind:
        _, request = place_task(scene, kind, seed=1, settings=settings)
        size = np.asarray(request.region_max)[:2] - np.asarray(request.region_min)[:2]
        assert size.max() >= length + 2 * settings.fit_margin - 1e-9, (kind, size)
    can = standing_scene((("005_tomato_soup_can", (0.55, 0.1)),), "005_tomato_soup_can")[0]
    for kind in RegionKind:
        _, request = place_task(can, kind, seed=1, settings=settings)
        size = np.asarray(request.region_max)[:2] - np.asarray(request.region_min)[:2]
        default = settings.bin_inner if kind is RegionKind.bin else settings.size
        np.testing.assert_allclose(size, default, atol=1e-9)
