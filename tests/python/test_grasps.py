"""Grasp sets: convention (YCB files + PyBullet), antipodal / approach geometry, the physics-verified
"simulated" set (determinism, cache, workers, lift and transport tests), hand contacts, bad input."""

import os

import numpy as np
import pytest

from conftest import ycb_dir_or_skip

from pickplan.omg import grasps as G
from pickplan.omg.grasps import physics as S
from pickplan.omg.grasps import simulated as SG
from pickplan.core import io, objects


@pytest.fixture(scope="module")
def builtins():
    return objects.library("builtin")


@pytest.fixture(scope="module")
def ycb():
    return objects.library(ycb_dir_or_skip())


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv(S.CACHE_ENV, str(tmp_path / "cache"))


def _hand_surface(n=400, seed=0):
    """Points on the hand + open finger collision meshes (panda_hand frame), via the Panda model."""
    import trimesh
    from pickplan.core.robots import panda

    robot = panda()
    q = robot.ready_configuration
    T_hand = robot.link_pose(q, "panda_hand")
    pts = []
    for k, link in enumerate(("panda_hand", "panda_leftfinger", "panda_rightfinger")):
        mesh = robot.collision_meshes(link)
        p, _ = trimesh.sample.sample_surface(mesh, n, seed=seed + k)
        T = np.linalg.inv(T_hand) @ robot.link_pose(q, link)
        pts.append(p @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(pts)


_SDFS = {}


def _sdf(model):
    """A fine native SDF grid of the object mesh: an inside test independent of FCL (2 mm voxels,
    ~1 mm interpolation error near the surface; trimesh's ``contains`` is ~10 ms a point)."""
    from pickplan.core import sdf

    if model.source not in _SDFS:
        _SDFS[model.source] = sdf.mesh_sdf(model.mesh, sdf.SdfSettings(resolution=0.002, margin=0.05, cache_dir=""))
    return _SDFS[model.source]


def _depth(model, pts):
    return _sdf(model).distance(np.ascontiguousarray(pts, dtype=float).reshape(-1, 3))[0]


def _hand_points_inside(model, poses, hand_pts, tol=0.0015):
    """Per pose: how many hand surface points lie deeper than ``tol`` inside the object."""
    P = np.einsum("nij,mj->nmi", poses[:, :3, :3], hand_pts) + poses[:, None, :3, 3]
    return (_depth(model, P) < -tol).reshape(len(poses), -1).sum(1)


def _straddles(model, pose, contacts):
    """The two pads on opposite sides of the object: some pad point's closing segment (left pad ->
    its mirror on the right pad, 8 cm) starts and ends outside the mesh and passes through it."""
    left = contacts.points[contacts.finger == 0]
    right = left * [1, -1, 1]
    t = np.linspace(0, 1, 41)[None, :, None]
    seg = left[:, None] + t * (right - left)[:, None]
    d = _depth(model, seg @ pose[:3, :3].T + pose[:3, 3]).reshape(len(left), -1)
    return bool(np.any((d[:, 0] > 0) & (d[:, -1] > 0) & (d.min(1) < -0.001)))


# --- bad input ----------------------------------------------------------------------------------
def test_bad_input_errors(builtins):
    with pytest.raises(ValueError, match=r"grasps: expected shape \(N, 4, 4\), got \(3, 4\)"):
        G.check_grasps(np.zeros((3, 4)))
    bad = np.tile(np.eye(4), (3, 1, 1))
    bad[2, :3, :3] *= 1.5
    with pytest.raises(ValueError, match="pose 2 is not a rigid transform"):
        G.check_grasps(bad)
    bad[2] = np.diag([1.0, 1.0, -1.0, 1.0])  # a reflection
    with pytest.raises(ValueError, match="pose 2"):
        G.GraspSet("approach", bad, "x")
    with pytest.raises(ValueError, match="scores: expected 1 values, got 2"):
        G.GraspSet("approach", np.eye(4)[None], "x", scores=[1.0, 2.0])
    can = builtins.get("005_tomato_soup_can")
    with pytest.raises(ValueError, match=r"no stored 'graspit' grasps; available: none"):
        G.load_grasp_set(can, "graspit")
    with pytest.raises(ValueError, match="unknown grasp set kind 'best'"):
        G.grasp_set(can, "best")
    with pytest.raises(ValueError, match="n: expected a positive number"):
        G.antipodal_grasps(can, 0, 0)
    with pytest.raises(ValueError, match="seed: expected an integer"):
        G.approach_grasps(can, 3, None)
    with pytest.raises(ValueError, match="friction > 0"):
        G.antipodal_grasps(can, 3, 0, friction=0.0)
    with pytest.raises(ValueError, match="workers: expected >= 1"):
        SG.simulated_grasps(can, 2, 0, workers=0)
    with pytest.raises(ValueError, match="opening"):
        G.hand_contacts(0.05)


# --- hand contacts -------------------------------------------------------------------------------
def test_the_panda_pads_face_each_other_at_the_tips_and_move_with_the_fingers():
    c = G.hand_contacts()
    counts = np.bincount(c.finger)
    assert len(counts) == 2 and all(20 <= k <= 40 for k in counts), counts
    np.testing.assert_allclose(np.linalg.norm(c.normals, axis=1), 1.0)
    left, right = c.points[c.finger == 0], c.points[c.finger == 1]
    assert np.allclose(left[:, 1], 0.04, atol=1e-3) and np.allclose(right[:, 1], -0.04, atol=1e-3)
    assert np.all(c.normals[c.finger == 0] @ [0, 1, 0] < -0.99)  # inward: towards the other finger
    assert abs(c.points[:, 2].mean() - G.PAD_DEPTH) < 2e-3
    closed = G.hand_contacts(0.01)
    assert np.allclose(closed.points[closed.finger == 0, 1], 0.01, atol=1e-3)
    # the pad points lie on the finger surfaces of the Panda model at its open configuration
    from pickplan.core.robots import panda
    import trimesh

    robot = panda()
    q = robot.ready_configuration
    T_hand = robot.link_pose(q, "panda_hand")
    for k, link in enumerate(("panda_leftfinger", "panda_rightfinger")):
        T = np.linalg.inv(robot.link_pose(q, link)) @ T_hand
        p = c.points[c.finger == k] @ T[:3, :3].T + T[:3, 3]
        _, dist, _ = trimesh.proximity.closest_point(robot.collision_meshes(link), p)
        assert dist.max() < 1e-6  # ray hits: on the surface


# --- YCB convention ------------------------------------------------------------------------------
def test_ycb_simulated_grasps_straddle_the_object(ycb):
    contacts = G.hand_contacts()
    for name in ("006_mustard_bottle", "003_cracker_box"):
        model = ycb.get(name)
        gs = G.load_grasp_set(model, "simulated")
        assert gs.poses.shape == (100, 4, 4) and gs.name == "simulated"
        np.testing.assert_allclose(gs.poses, model.grasps["simulated"] @ G.YCB_TO_HAND)
        ok = np.mean([_straddles(model, T, contacts) for T in gs.poses])
        raw = np.mean([_straddles(model, T, contacts) for T in model.grasps["simulated"]])
        assert ok >= 0.9, f"{name}: only {ok:.0%} straddle"
        assert raw <= 0.2, f"{name}: the unconverted file grasps straddle too ({raw:.0%})"
        assert len(G.grasp_set(model, "graspit")) == len(model.grasps["graspit"])


def test_ycb_simulated_grasps_close_on_the_object_in_pybullet(ycb):
    model = ycb.get("006_mustard_bottle")
    gs = G.load_grasp_set(model, "simulated")
    for T in gs.poses[:3]:
        r = S.close_on_object(model, T)
        assert r["gap"] > 0.005 and r["left"] and r["right"], r
    raw = S.close_on_object(model, model.grasps["simulated"][0])  # without +pi/2: closes on nothing
    assert raw["gap"] < 0.005 or not (raw["left"] and raw["right"]), raw


# --- antipodal / approach ----------------------------------------------------------------------------
def _check_antipodal(model, gs, hand_pts, friction=0.3):
    cone = np.arctan(friction) + 1e-6
    c, nrm = gs.info["contacts"], gs.info["normals"]
    pad = gs.poses @ np.array([0, 0, G.PAD_DEPTH, 1.0])
    np.testing.assert_allclose(pad[:, :3], c.mean(axis=1), atol=1e-6)  # pad centre at the pair midpoint
    axis = c[:, 1] - c[:, 0]
    w = np.linalg.norm(axis, axis=1)
    axis /= w[:, None]
    assert np.all(np.abs(np.einsum("ni,ni->n", axis, gs.poses[:, :3, 1])) > 1 - 1e-9)  # closes along it
    assert np.all(np.arccos(np.clip(-np.einsum("ni,ni->n", nrm[:, 0], axis), -1, 1)) <= cone)
    assert np.all(np.arccos(np.clip(np.einsum("ni,ni->n", nrm[:, 1], axis), -1, 1)) <= cone)
    assert np.all(w <= 0.08) and np.allclose(w, gs.info["width"])
    assert np.abs(_depth(model, c)).max() < 1.5e-3  # the pair lies on the surface
    assert np.all(_hand_points_inside(model, gs.poses, hand_pts) == 0)
    assert not G.HandObjectChecker(model).in_collision(gs.poses).any()


def test_antipodal_grasps_builtin(builtins):
    hand_pts = _hand_surface()
    for name in ("005_tomato_soup_can", "025_mug"):
        model = builtins.get(name)
        gs = G.antipodal_grasps(model, 12, seed=1)
        assert len(gs) == 12 and gs.name == "antipodal" and gs.object_name == name
        _check_antipodal(model, gs, hand_pts)
        again = G.grasp_set(model, "antipodal", 12, 1)
        np.testing.assert_array_equal(gs.poses, again.poses)
        assert not np.allclose(G.antipodal_grasps(model, 12, seed=2).poses, gs.poses)


def test_antipodal_grasps_ycb_mesh(ycb):
    model = ycb.get("006_mustard_bottle")
    _check_antipodal(model, G.antipodal_grasps(model, 8, seed=0), _hand_surface())


def test_approach_grasps_are_free_tight_and_point_at_the_object(builtins):
    hand_pts = _hand_surface()
    for name in ("003_cracker_box", "025_mug"):
        model = builtins.get(name)
        gs = G.approach_grasps(model, 16, seed=3)
        assert len(gs) == 16 and gs.name == "approach"
        np.testing.assert_array_equal(gs.poses, G.approach_grasps(model, 16, seed=3).poses)
        centre = model.mesh.bounds.mean(axis=0)
        to_centre = centre - gs.poses[:, :3, 3]
        to_centre /= np.linalg.norm(to_centre, axis=1, keepdims=True)
        assert np.all(np.einsum("ni,ni->n", to_centre, gs.poses[:, :3, 2]) > 1 - 1e-9)
        assert np.all(_hand_points_inside(model, gs.poses, hand_pts) == 0)
        check = G.HandObjectChecker(model)
        assert not check.in_collision(gs.poses).any()
        closer = gs.poses.copy()
        closer[:, :3, 3] += 0.005 * gs.poses[:, :3, 2]  # 5 mm further in: touching (tight back-off)
        assert check.in_collision(closer).mean() >= 0.8


# --- simulated ----------------------------------------------------------------------------------------
def test_simulated_grasps_deterministic_cached_and_worker_independent(builtins, tmp_path, capsys):
    model = builtins.get("005_tomato_soup_can")
    a = SG.simulated_grasps(model, 3, seed=5, oversample=2, cache=False, progress=True)
    assert "shake round 1" in capsys.readouterr().err
    b = SG.simulated_grasps(model, 3, seed=5, oversample=2)  # computes and writes the cache
    assert len(a) == 3 and a.name == "simulated"
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.scores, b.scores)
    files = os.listdir(io.cache_dir(SG.CACHE_FOLDER))
    assert len(files) == 1 and files[0].startswith("005_tomato_soup_can-simulated-")
    c = SG.simulated_grasps(model, 3, seed=5, oversample=2)  # from the cache
    np.testing.assert_array_equal(a.poses, c.poses)
    assert int(c.info["tested"]) == int(a.info["tested"])
    d = SG.simulated_grasps(model, 3, seed=5, oversample=2, workers=2, cache=False)
    np.testing.assert_array_equal(a.poses, d.poses)
    assert not np.allclose(SG.simulated_grasps(model, 3, seed=6, oversample=2, cache=False).poses, a.poses)
    assert G.grasp_set(model, "simulated", 3, 5, oversample=2).poses.shape == (3, 4, 4)


def test_simulated_grasps_lift_from_the_table(builtins):
    model = builtins.get("005_tomato_soup_can")
    sim = SG.simulated_grasps(model, 3, seed=0, oversample=2, cache=False)
    r_sim = S.lift_test(model, sim.poses)
    assert (r_sim >= 0).sum() >= 2 and S.lift_rate(r_sim) == 1.0


# The transport test (lift, raise, carry, tilt and swirl; grasps.physics module docstring) separates the
# "Simulated" grasps from their antipodal candidates on the elongated / heavy objects. The same
# protocol on 40 candidates x 8 objects per library is in bench/README.md ("Simulated vs antipodal:
# transport test"). Pooled over the built-in cracker box, sugar box, mustard and bleach bottles there:
# simulated 39/43 = 0.91 (Wilson 95 % [0.78, 0.96]), all candidates 48/77 = 0.62 ([0.51, 0.72]),
# shake-rejected 9/34 = 0.26; difference simulated - all 0.29 (normal 95 % CI [0.15, 0.43]),
# simulated - rejected 0.65 ([0.48, 0.82]). The margins below are those lower bounds. This test runs
# the two objects with the largest gap (a subset of those figures: simulated 8/8, all 13/31,
# rejected 5/23); seeded, deterministic, 19 s at load average 2.
TRANSPORT_OBJECTS = ("006_mustard_bottle", "021_bleach_cleanser")
TRANSPORT_CANDIDATES = 40


def test_simulated_grasps_survive_transport_more_often_than_antipodal(builtins):
    sim_ok = sim_n = all_ok = all_n = rej_ok = rej_n = 0
    for name in TRANSPORT_OBJECTS:
        rows = S.shake_and_transport(builtins.get(name), TRANSPORT_CANDIDATES, seed=0, workers=1)
        held = np.array([r["shake"]["held"] for r in rows], bool)
        ok = np.array([r["transport"]["held"] for r in rows], bool)
        assert len(rows) >= 8 and held.any() and (~held).any(), (name, len(rows), held.sum())
        sim_ok, sim_n = sim_ok + int(ok[held].sum()), sim_n + int(held.sum())
        rej_ok, rej_n = rej_ok + int(ok[~held].sum()), rej_n + int((~held).sum())
        all_ok, all_n = all_ok + int(ok.sum()), all_n + len(ok)
    sim, raw, rej = sim_ok / sim_n, all_ok / all_n, rej_ok / rej_n
    report = f"simulated {sim_ok}/{sim_n}, antipodal {all_ok}/{all_n}, shake-rejected {rej_ok}/{rej_n}"
    assert sim >= 0.78, report
    assert sim - raw >= 0.15, report
    assert sim - rej >= 0.48, report


def test_transport_test_reports_not_applicable_and_failures(builtins):
    model = builtins.get("021_bleach_cleanser")
    cand, _ = S.shake_candidates(model, 6, seed=0)
    out, trials = S.transport_test(model, cand.poses, details=True)
    assert out.shape == (6,) and set(out.tolist()) <= {-1, 0, 1}
    for o, t in zip(out, trials):
        assert (o == -1) == (not t["applicable"])
        assert (o == 1) == (t["held"] and t["stage"] == "held")
        if o == 0:
            assert t["stage"] in ("lift", "raise", "carry", "tilt", "swirl", "dropped")
    with pytest.raises(ValueError, match="workers"):
        S.transport_test(model, cand.poses, workers=0)
