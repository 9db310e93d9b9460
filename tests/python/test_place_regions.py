"""The bench's place regions (eval.place_regions): the covered share of a region and whether a footprint
fits among its free cells, by exact geometry; generated regions are seeded, free regions and bins clear of the clutter, a partly
cluttered region reaches into the clutter and leaves room for the target."""

import numpy as np
from scipy.spatial import ConvexHull

from pickplan.core import objects
from pickplan.eval.place_regions import (
    RegionKind,
    RegionSettings,
    _cover,
    _fits,
    _footprints,
    _hulls_xy,
    _room,
    place_task,
)
from pickplan.sim import scenes

from conftest import standing_pose, standing_scene


def _square(lo, hi):
    return ConvexHull(np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])).equations


def _bar(length, width):
    return np.array([[0.0, 0.0], [length, 0.0], [length, width], [0.0, width]]) + [0.3, 0.7]  # anywhere


def test_cover_is_the_share_and_fits_places_the_footprint_among_the_free_cells():
    lo, hi = np.array([0.0, 0.0]), np.array([0.2, 0.1])
    assert _cover([], lo, hi) == 0.0
    assert _cover([_square((0.1, -0.1), (0.3, 0.2))], lo, hi) == 0.5  # the right half covered
    assert abs(_cover([_square((0.0, 0.04), (0.2, 0.06))], lo, hi) - 0.2) <= 0.1  # a 2 cm bar across the middle
    assert _cover([_square((0.0, 0.0), (0.2, 0.1))], lo, hi) == 1.0
    # a 16 x 3 cm bar fits the empty 20 x 10 cm box with 1 cm around it (a disc of its reach would not)
    assert _fits([], lo, hi, _bar(0.16, 0.03), 0.01)
    assert not _fits([], lo, hi, _bar(0.19, 0.03), 0.01)  # 21 cm with its margin
    assert not _fits([], lo, hi, _bar(0.10, 0.09), 0.01)  # 11 cm across with its margin
    half = [_square((0.1, -0.1), (0.3, 0.2))]  # 10 x 10 cm free: the 16 cm bar at no heading
    assert not _fits(half, lo, hi, _bar(0.16, 0.03), 0.01) and _fits(half, lo, hi, _bar(0.07, 0.03), 0.01)
    middle = [_square((0.0, 0.04), (0.2, 0.06))]  # two free strips 20 x 4 cm
    assert _fits(middle, lo, hi, _bar(0.15, 0.02), 0.005) and not _fits(middle, lo, hi, _bar(0.15, 0.04), 0.005)


def test_the_room_a_target_has():
    """The room: 2 where a disc of the target's reach stands ``margin`` from the box's sides, 1 where only
    its footprint turned to fit does, 0 where nothing does; ``clearance`` from the clutter apart from the
    margin from the sides (a hand goes down beside the target, past the region's side too)."""
    lo, hi = np.array([0.0, 0.0]), np.array([0.2, 0.1])
    assert _room([], lo, hi, _bar(0.04, 0.04), 0.01) == 2  # a 4 cm square: reach 2.8 cm + 1 < 4-5 cm
    assert _room([], lo, hi, _bar(0.08, 0.08), 0.01) == 1  # reach 5.7 cm: no disc, the square itself fits
    assert _room([], lo, hi, _bar(0.16, 0.03), 0.01) == 1  # reach 8.1 cm: only along the box
    assert _room([_square((0.1, -0.1), (0.3, 0.2))], lo, hi, _bar(0.16, 0.03), 0.01) == 0
    # the right half covered leaves a 10 x 10 cm square: an 8 cm square stands in it 1 cm from its sides
    # and from the clutter; with clutter 5 mm above the box too, it has 3 cm on two opposite sides
    # nowhere, and with nothing beside the box, the sides' 1 cm is all it needs
    right, square = [_square((0.1, -0.1), (0.3, 0.2))], _bar(0.08, 0.08)
    corner = right + [_square((-0.1, 0.105), (0.3, 0.2))]
    assert _fits(corner, lo, hi, square, 0.01) and not _fits(corner, lo, hi, square, 0.01, 0.03)
    assert _fits(right, lo, hi, square, 0.01, 0.03)  # the fingers along y: no clutter there
    assert _fits([], lo, hi, square, 0.01, 0.03) and _fits(corner, lo, hi, _bar(0.06, 0.06), 0.01, 0.03)
    # clutter 5 mm beyond the box's sides counts (a hand reaches past them): a frame around a 10 cm box
    # leaves a 9 cm square 1 cm every way, and without the frame the square has all the room it needs
    box_lo, box_hi = np.array([0.0, 0.0]), np.array([0.1, 0.1])
    frame = [_square((-0.1, -0.1), (-0.005, 0.2)), _square((0.105, -0.1), (0.2, 0.2))]
    frame += [_square((-0.1, -0.1), (0.2, -0.005)), _square((-0.1, 0.105), (0.2, 0.2))]
    nine = _bar(0.09, 0.09)
    assert _fits(frame, box_lo, box_hi, nine, 0.005) and not _fits(frame, box_lo, box_hi, nine, 0.005, 0.03)
    assert _fits([], box_lo, box_hi, nine, 0.005, 0.03)


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
    candidate regions leaves it a free disc of its reach 1 cm from the sides and the clutter (room for it
    turned any way: else "region blocked" whatever the planner does); the later ones do, and the region
    chosen is one of those (none with 3 cm for the fingers: the bowl is 16 cm across, its region 24 x 20)."""
    scene, _ = standing_scene(
        (
            ("003_cracker_box", (0.749, 0.192)),
            ("002_master_chef_can", (0.52, 0.283)),
            ("025_mug", (0.569, -0.303)),
            ("024_bowl", (0.38, 0.302)),
        ),
        "024_bowl",
    )
    footprints, target = _footprints(scene, scene.target), dict(_hulls_xy(scene))[scene.target]
    settings = RegionSettings()

    def box(request):
        return np.array(request.region_min[:2]), np.array(request.region_max[:2])

    _, first = place_task(scene, RegionKind.cluttered, seed=29, settings=RegionSettings(clutter_batches=1))
    assert _room(footprints, *box(first), target, settings.clutter_margin) < 2
    _, request = place_task(scene, RegionKind.cluttered, seed=29)
    assert _room(footprints, *box(request), target, settings.clutter_margin) == 2
    assert _cover(footprints, *box(request)) > 0.0
    assert _overlaps(scene, request, skip=scene.target)


def test_a_long_target_among_clutter_gets_a_region_it_fits_in():
    """A 28 cm hammer (its region grown to 30 x 20 cm): a disc of its reach fits no such region, so the
    disc alone never found room and fell back to a region the hammer could not stand in; its footprint
    turned along the region does fit one, clear of the clutter, and that is the region chosen (touching
    its sides and the clutter: the hammer takes this scene's room between the can, the mug and the box)."""
    lib = objects.library("procedural")
    hammer = lib.get("hammer_00")
    pose = np.asarray(hammer.resting_poses[0], dtype=float).copy()
    pose[:2, 3] = (0.55, 0.3)
    objs = [scenes.SceneObject("hammer_00", "procedural:hammer_00", pose)]
    for name, xy in (
        ("005_tomato_soup_can", (0.5, -0.25)),
        ("025_mug", (0.62, -0.3)),
        ("004_sugar_box", (0.45, -0.05)),
    ):
        objs.append(scenes.SceneObject(name, f"builtin:{name}", standing_pose(lib_builtin().get(name), xy)))
    scene = scenes.Scene(np.eye(4), scenes.default_table(), objs, "hammer_00", seed=0)
    footprints, target = _footprints(scene, "hammer_00"), dict(_hulls_xy(scene))["hammer_00"]
    for seed in range(4):
        _, request = place_task(scene, RegionKind.cluttered, seed=seed)
        lo, hi = np.array(request.region_min[:2]), np.array(request.region_max[:2])
        assert _fits(footprints, lo, hi, target, 0.0) and _cover(footprints, lo, hi) > 0.0, seed


def lib_builtin():
    return objects.library("builtin")


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
