"""The native pieces of the depth-to-trajectory path (issue 36) against independent truth: numpy's
quantiles, brute-force inlier counts, the local-section rule written out in numpy (the Python
implementation the native one replaced, kept here as the oracle), and exact geometry."""

import numpy as np
import pytest

from pickplan import _core
from pickplan.omg.grasps.points import PointGraspSettings, local_candidates
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.perceived_world import PerceivedWorld
from pickplan.perception.field import support_plane
from pickplan.sim.observe import render_observation

from conftest import known_scene


def test_sorted_quantiles_are_numpys_to_the_last_bit():
    rng = np.random.default_rng(3)
    for n in list(range(1, 40)) + [97, 1000]:
        v = np.sort(rng.normal(0.0, 0.05, n))
        q = np.array([0.0, 0.01, 0.25, 0.5, 0.7, 0.99, 1.0])
        assert np.array_equal(_core.sorted_quantiles(v, q), np.quantile(v, q)), n


def test_most_inliers_is_the_first_brute_force_maximum():
    rng = np.random.default_rng(0)
    P = rng.uniform(-1, 1, (5000, 3)) * [1, 1, 0.02]
    N = rng.normal(size=(40, 3))
    N[::3] = [0.0, 0.0, 1.0]  # some near the points' plane: most hypotheses are left early, some not
    N /= np.linalg.norm(N, axis=1, keepdims=True)
    D = rng.uniform(-0.01, 0.01, 40)
    N, D = np.vstack([N, N[[9, 3]]]), np.append(D, D[[9, 3]])  # ties: the first one keeps it
    want = [int((np.abs(P @ n - d) < 0.006).sum()) for n, d in zip(N, D)]
    assert _core.most_inliers(P, N, D, 0.006) == (int(np.argmax(want)), max(want))
    assert _core.most_inliers(P, N[:0], D[:0], 0.006) == (-1, 0)
    with pytest.raises(ValueError, match="offsets"):
        _core.most_inliers(P, N, D[:3], 0.006)


def test_the_support_plane_of_a_tilted_table_is_exact():
    rng = np.random.default_rng(1)
    n = np.array([0.05, -0.03, 1.0])
    n /= np.linalg.norm(n)
    xy = rng.uniform(-0.5, 0.5, (4000, 2))
    table = np.column_stack([xy, (0.02 - n[0] * xy[:, 0] - n[1] * xy[:, 1]) / n[2]])
    clutter = rng.uniform([-0.2, -0.2, 0.05], [0.2, 0.2, 0.3], (1500, 3))
    found, d = support_plane(np.vstack([table, clutter]))
    assert np.allclose(found, n, atol=1e-9) and d == pytest.approx(0.02, abs=1e-9)


def _reference_sections(ry, rx, height, s: PointGraspSettings):
    """The local-section rule in numpy (module docstring of ``local_candidates``)."""
    out = []
    band = (np.abs(rx) <= s.pad_width / 2) & (np.abs(ry) <= s.max_width)
    for a in np.flatnonzero(band.sum(axis=0) >= 3):
        v = np.sort(ry[band[:, a], a])
        cuts = np.flatnonzero(np.diff(v) > 2 * s.clearance)
        k = np.searchsorted(v, 0.0)
        lo = v[cuts[cuts < k][-1] + 1] if (cuts < k).any() else v[0]
        hi = v[cuts[cuts >= k][0]] if (cuts >= k).any() else v[-1]
        sel = band[:, a] & (ry[:, a] >= lo) & (ry[:, a] <= hi)
        if sel.sum() < 3:
            continue
        q0, q1 = np.quantile(ry[sel, a], [s.section_trim, 1 - s.section_trim])
        if not s.min_width <= q1 - q0 <= s.max_width - s.width_margin:
            continue
        halves = [ry[sel, a][rx[sel, a] < 0], ry[sel, a][rx[sel, a] >= 0]]
        if min(len(h) for h in halves) < 2:
            continue
        ends = np.array([np.quantile(h, [s.section_trim, 1 - s.section_trim]) for h in halves])
        if np.abs(ends[0] - ends[1]).max() > np.tan(s.max_face_turn) * s.pad_width / 2:
            continue
        out.append([a, q0, q1, rx[sel, a].min(), rx[sel, a].max(), height[sel].max()])
    return np.array(out).reshape(-1, 6)


def test_native_local_sections_follow_the_rule_exactly():
    s = PointGraspSettings(max_width=0.08, pad_length=0.02, pad_width=0.02, width_margin=0.006)
    native = _core.SectionSettings()
    native.pad_width, native.max_width, native.gap = s.pad_width, s.max_width, 2 * s.clearance
    native.trim, native.min_width, native.fit_width = s.section_trim, s.min_width, s.max_width - s.width_margin
    native.face_tolerance = np.tan(s.max_face_turn) * s.pad_width / 2
    rng = np.random.default_rng(5)
    found = 0
    for trial in range(30):  # bars of random widths and angles, a neighbouring part, noise
        w = rng.uniform(0.005, 0.09)
        bar = np.column_stack([rng.uniform(-0.1, 0.1, 400), rng.uniform(-w / 2, w / 2, 400)])
        other = np.column_stack(
            [rng.uniform(-0.1, 0.1, 100), rng.uniform(0.0, 0.01, 100) + w / 2 + rng.uniform(0, 0.02)]
        )
        F2 = np.vstack([bar, other]) + rng.normal(0, 0.001, (500, 2))
        turn = rng.uniform(0, np.pi)
        F2 = F2 @ np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
        height = rng.uniform(0, 0.05, 500)
        angles = np.pi * np.arange(12) / 12
        Y2 = np.column_stack([np.cos(angles), np.sin(angles)])
        X2 = np.column_stack([-Y2[:, 1], Y2[:, 0]])
        rel = F2 - F2[trial]
        ry, rx = rel @ Y2.T, rel @ X2.T
        got = _core.local_sections(ry, rx, height, native)
        want = _reference_sections(ry, rx, height, s)
        assert np.array_equal(got, want), trial
        found += len(got)
    assert found > 20  # the rule passed some sections, not only refused them


def test_local_grasps_across_a_bar_span_its_width():
    # a 3 cm wide bar lying along x: every local grasp closes across it, well within 45 degrees of y
    # (the ends' test on trimmed quantiles lets a section turn a little beyond max_face_turn), none along it; a section turned by t spans 3 cm / cos t along the pads' centre line and
    # up to pad_width tan t more at the pads' edges (less the trimmed tails)
    rng = np.random.default_rng(2)
    P = np.column_stack([rng.uniform(0.3, 0.5, 3000), rng.uniform(-0.015, 0.015, 3000), rng.uniform(0.0, 0.02, 3000)])
    s = PointGraspSettings(max_width=0.08, pad_length=0.02, pad_width=0.02, width_margin=0.006)
    cands = local_candidates(P, (np.array([0.0, 0.0, 1.0]), 0.0), s, np.random.default_rng(0))
    assert cands
    turns = set()
    for frame, _, width in cands:
        turn = np.arccos(min(1.0, abs(frame[1, 1])))  # the closing axis against y
        assert turn < np.pi / 4
        assert 0.03 / np.cos(turn) - 0.002 <= width <= 0.03 / np.cos(turn) + s.pad_width * np.tan(turn) + 1e-9
        turns.add(round(turn, 6))
    assert 0.0 in turns


def test_native_section_and_plane_inputs_are_checked():
    with pytest.raises(ValueError, match="rx"):
        _core.local_sections(np.zeros((5, 3)), np.zeros((4, 3)), np.zeros(5), _core.SectionSettings())
    bad = _core.SectionSettings()
    bad.trim = 0.7
    with pytest.raises(ValueError, match="trim"):
        _core.local_sections(np.zeros((5, 3)), np.zeros((5, 3)), np.zeros(5), bad)
    with pytest.raises(ValueError):
        _core.sorted_quantiles(np.zeros(0), np.array([0.5]))


def test_worlds_share_the_robots_points_through_the_cache():
    scene, _ = known_scene()
    obs = render_observation(scene, views=1)
    cache = ModelCache()
    a, b = PerceivedWorld(obs, cache=cache), PerceivedWorld(obs, cache=cache)
    assert a.body is b.body and a.hand_points is b.hand_points
    fresh = PerceivedWorld(obs)  # its own cache: the same samples, built again
    assert fresh.body is not a.body
    assert np.array_equal(fresh.body.points, a.body.points) and np.array_equal(fresh.hand_points[0], a.hand_points[0])


def test_the_target_distance_grid_is_brute_force_exact():
    rng = np.random.default_rng(4)
    P = rng.normal(0.0, 0.03, (300, 3)) + [0.5, 0.0, 0.1]
    lo, res, dims = np.array([0.4, -0.1, 0.0]), 0.01, np.array([21, 19, 17])
    got = _core.point_distance_grid(P, lo, res, dims)
    z, y, x = np.meshgrid(*(np.arange(k) for k in dims[::-1]), indexing="ij")
    nodes = lo + res * np.stack([x, y, z], axis=-1)
    want = np.sqrt(((nodes[..., None, :] - P) ** 2).sum(axis=-1)).min(axis=-1)
    assert got.shape == (17, 19, 21)
    assert np.allclose(got, want, rtol=1e-6, atol=1e-7)
    with pytest.raises(ValueError, match="points"):
        _core.point_distance_grid(np.zeros((0, 3)), lo, res, dims)


def test_points_in_frames_are_the_points_in_each_box():
    rng = np.random.default_rng(6)
    P = rng.uniform(-0.05, 0.05, (2000, 3))
    frames = []
    for _ in range(50):
        Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = Q * np.sign(np.linalg.det(Q)), rng.uniform(-0.03, 0.03, 3)
        frames.append(T)
    G = np.array(frames)
    half = rng.uniform(0.005, 0.03, (50, 3))
    want = [int((np.abs((P - T[:3, 3]) @ T[:3, :3]) < h).all(axis=1).sum()) for T, h in zip(G, half)]
    assert list(_core.points_in_frames(G, P, half)) == want
    assert max(want) > 10


def test_antipodal_partners_are_the_radius_pairs_within_both_friction_cones():
    # points on two parallel faces 4 cm apart (normals outward) and a few on a third face: the pairs
    # across the two faces within the cone pass, with their exact widths; pairs on one face do not
    rng = np.random.default_rng(7)
    left = np.column_stack([np.zeros(30), rng.uniform(-0.02, 0.02, (30, 2))])
    right = np.column_stack([np.full(30, 0.04), rng.uniform(-0.02, 0.02, (30, 2))])
    P = np.vstack([left, right])
    N = np.vstack([np.tile([-1.0, 0, 0], (30, 1)), np.tile([1.0, 0, 0], (30, 1))])
    cone = np.cos(np.arctan(0.3))
    keep, order = rng.uniform(size=60) < 0.8, rng.permutation(60)
    seeds = rng.permutation(60)[:40]
    for radius in (0.045, 1.0):  # some partners beyond the radius, and none
        i, j = _core.radius_pairs(P, seeds, radius, keep, order)
        D = P[j] - P[i]
        w = np.linalg.norm(D, axis=1)
        with np.errstate(invalid="ignore", divide="ignore"):
            m = np.minimum(-(D / w[:, None] * N[i]).sum(axis=1), (N[j] * D / w[:, None]).sum(axis=1))
        want = np.flatnonzero((w >= 0.004) & (m >= cone))
        gi, gj, margins, widths = _core.antipodal_partners(P, N, seeds, radius, keep, order, 0.004, cone)
        assert np.array_equal(gi, i[want]) and np.array_equal(gj, j[want]) and len(want) > 10
        assert np.all((gi < 30) != (gj < 30))  # across the two faces only
        assert np.allclose(widths, w[want], rtol=0, atol=1e-15) and np.allclose(margins, m[want], atol=1e-15)
    with pytest.raises(ValueError, match="order"):
        _core.antipodal_partners(P, N, seeds, 0.1, keep, order[:5], 0.004, cone)


def test_radius_pairs_are_a_kd_tree_ball_query_sorted_or_in_its_order():
    """Against scipy's cKDTree: sorted per query by default; the tree's unsorted answer (what the
    antipodal pairs' seeded subset draws from) with the tree's indices as the order."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(3)
    P = rng.normal(0, 0.04, (2000, 3))
    keep = rng.uniform(size=2000) < 0.7
    tree = cKDTree(P)
    seeds = rng.choice(2000, 300, replace=False)
    for radius in (0.008, 0.074):
        i, j = _core.radius_pairs(P, np.arange(2000), radius)
        near = tree.query_ball_point(P, radius)
        assert np.array_equal(i, np.repeat(np.arange(2000), [len(a) for a in near]))
        assert np.array_equal(j, np.concatenate(near))
        i, j = _core.radius_pairs(P, seeds, radius, keep, tree.indices)
        near = [[k for k in a if keep[k]] for a in tree.query_ball_point(P[seeds], radius, return_sorted=False)]
        assert np.array_equal(i, np.repeat(seeds, [len(a) for a in near]))
        assert np.array_equal(j, np.concatenate(near))
    with pytest.raises(ValueError, match="keep"):
        _core.radius_pairs(P, seeds, 0.01, keep[:5])


def test_clear_in_frames_is_the_per_point_distance_test():
    """SceneSdf.clear_in_frames against SceneSdf.distance point by point, both directions."""
    from pickplan.core.sdf import SceneSdf, SdfQuery
    from pickplan.core.shapes import Shape

    rng = np.random.default_rng(4)
    scene = SceneSdf()
    scene.add_primitive("box", Shape.box(0.1, 0.06, 0.04), np.eye(4))
    F = np.tile(np.eye(4), (150, 1, 1))
    F[:, :3, :3] = np.linalg.qr(rng.normal(size=(150, 3, 3)))[0] * np.sign(rng.uniform(-1, 1, (150, 1, 1)))
    F[:, :3, :3] *= np.linalg.det(F[:, :3, :3])[:, None, None]  # rotations
    F[:, :3, 3] = rng.uniform(-0.15, 0.15, (150, 3))
    pts = rng.normal(0, 0.05, (6, 3))
    world = np.einsum("kij,mj->kmi", F[:, :3, :3], pts) + F[:, None, :3, 3]
    d = scene.distance(world.reshape(-1, 3), cutoff=0.05)[0].reshape(150, -1)
    want = d.min(axis=1) > 0.01
    got = SdfQuery(scene, cutoff=0.05).clear_in_frames(F, pts, 0.01)
    assert np.array_equal(got, want) and 0 < want.sum() < 150
    local = np.einsum("kji,kmj->kmi", F[:, :3, :3], pts[None] - F[:, None, :3, 3])
    near = (local**2).sum(axis=2) < 0.12**2
    d = np.where(near, scene.distance(local.reshape(-1, 3), cutoff=0.05)[0].reshape(150, -1), np.inf)
    want = d.min(axis=1) > 0.01
    got = scene.clear_in_frames(F, pts, 0.01, cutoff=0.05, inverse=True, reach=0.12)
    assert np.array_equal(got, want) and 0 < want.sum() < 150
