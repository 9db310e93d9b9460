"""IK and goal sets: poses reproduced, limits respected, collision filtering checked in PyBullet."""

import numpy as np
import pybullet as pb
import pytest

from pickplan import _core
from pickplan.core.ik import IkSettings
from pickplan.omg import goals
from pickplan.sim import scenes
from pickplan.omg import world


def _side_grasps(model, n_angles=24, heights=(0.35, 0.55, 0.75)):
    """Horizontal grasps around the object's z axis, fingers at the centre line (object frame)."""
    lo, hi = model.mesh.bounds
    out = []
    for a in np.linspace(0, 2 * np.pi, n_angles, endpoint=False):
        for h in heights:
            z = np.array([-np.cos(a), -np.sin(a), 0.0])
            y = np.array([-np.sin(a), np.cos(a), 0.0])
            T = np.eye(4)
            T[:3, :3] = np.stack([np.cross(y, z), y, z], axis=1)
            centre = (lo + hi) / 2
            centre[2] = lo[2] + h * (hi[2] - lo[2])
            T[:3, 3] = centre - 0.105 * z
            out.append(T)
    return np.array(out)


@pytest.fixture(scope="module")
def scene_world():
    sc = scenes.generate_scene(0)
    sc.target = "006_mustard_bottle" if any(o.name == "006_mustard_bottle" for o in sc.objects) else sc.target
    return world.World(sc)


def test_ik_recovers_1000_random_poses(panda):
    active = [True] * 7 + [False] * 2
    ik = _core.IkSolver(panda.native, "panda_hand", IkSettings().to_native(active))
    Q = panda.random_configurations(1000, seed=3)
    Q[:, 7:] = 0.04
    targets = panda.fk_batch(Q)[:, panda.link_index("panda_hand")]
    sols, ok = ik.solve_batch(targets, panda.ready_configuration)
    assert ok.mean() >= 0.99, ok.mean()
    reached = panda.fk_batch(sols[ok])[:, panda.link_index("panda_hand")]
    pos_err = np.linalg.norm(reached[:, :3, 3] - targets[ok, :3, 3], axis=1)
    rot_err = np.array(
        [np.arccos(np.clip((np.trace(a[:3, :3].T @ b[:3, :3]) - 1) / 2, -1, 1)) for a, b in zip(reached, targets[ok])]
    )
    assert pos_err.max() <= 1e-3 and rot_err.max() <= 0.01
    assert np.all(sols >= panda.lower_limits - 1e-12) and np.all(sols <= panda.upper_limits + 1e-12)
    np.testing.assert_array_equal(sols[:, 7:], 0.04)  # inactive finger joints keep the seed's values


def test_solve_all_returns_distinct_solutions_of_one_pose(panda):
    active = [True] * 7 + [False] * 2
    ik = _core.IkSolver(panda.native, "panda_hand", IkSettings().to_native(active))
    target = panda.link_pose(panda.ready_configuration, "panda_hand")
    sols = ik.solve_all(target, panda.ready_configuration)
    assert len(sols) >= 2  # a 7-DOF arm has a family of solutions
    Q = np.array([s.q for s in sols])
    assert np.abs(Q[0] - panda.ready_configuration).max() < 1e-3  # nearest to the start first
    for i in range(len(Q)):
        for j in range(i):
            assert np.abs(Q[i] - Q[j]).max() >= 0.05


def test_goal_set_reaches_grasps_with_a_straight_standoff(scene_world):
    w = scene_world
    grasps = _side_grasps(w.target_model)
    # IK and the standoff, not the grasps: these synthetic ones close across the bottle's 9.7 cm as well
    # (the quality rejects those: the open pads already press on it, "slips")
    gs = goals.build_goal_set(w, grasps, settings=goals.GoalSetSettings(max_goals=100, quality=None))
    assert len(gs) >= 3, gs.reason_counts()
    assert len(gs.reasons) == len(grasps) and set(gs.reasons) <= {
        "ok",
        "unreachable",
        "in_collision",
        "standoff_unreachable",
        "standoff_in_collision",
        "approach_clearance",
        "duplicate",
        "over_cap",
    }
    hand = w.robot.link_index("panda_hand")
    for g, tail, gi in zip(gs.goals, gs.tails, gs.grasp_index):
        np.testing.assert_array_equal(tail[-1], g)
        want = w.target_pose @ grasps[gi]
        poses = w.robot.fk_batch(tail)[:, hand]
        assert np.abs(poses[-1] - want).max() < 2e-3
        # The approach is a straight line along the hand's z axis, ending 8 cm back.
        back = np.einsum("ij,nj->ni", want[:3, :3].T, poses[:, :3, 3] - want[:3, 3])
        np.testing.assert_allclose(back[:, :2], 0, atol=2e-3)
        np.testing.assert_allclose(back[:, 2], -np.linspace(0.08, 0, 5), atol=2e-3)
        assert np.abs(np.diff(tail, axis=0)).max() <= 0.5


def test_collision_filter_agrees_with_pybullet(scene_world):
    w = scene_world
    grasps = _side_grasps(w.target_model)
    gs = goals.build_goal_set(w, grasps, settings=goals.GoalSetSettings(max_goals=100))
    cid = pb.connect(pb.DIRECT)
    try:
        bodies = scenes.load_into_pybullet(w.scene, cid)
        robot = bodies["robot"]
        movable = [
            j
            for j in range(pb.getNumJoints(robot, physicsClientId=cid))
            if pb.getJointInfo(robot, j, physicsClientId=cid)[2] != pb.JOINT_FIXED
        ]
        others = [b for name, b in bodies.items() if name not in ("robot", w.target)]
        moving_links = set(j for j in range(pb.getNumJoints(robot, physicsClientId=cid)))

        def min_distance(q):
            for k, j in enumerate(movable):
                pb.resetJointState(robot, j, q[k], physicsClientId=cid)
            d = np.inf
            for b in others:
                for c in pb.getClosestPoints(robot, b, 0.01, physicsClientId=cid):
                    if c[3] in moving_links:  # link index >= 0: not the base mounted on the table
                        d = min(d, c[8])
            return d

        # Every accepted goal (and its approach) is free in PyBullet too, up to Bullet's ~1 mm margins.
        for tail in gs.tails:
            for q in tail:
                assert min_distance(q) > -2e-3
    finally:
        pb.disconnect(cid)


def test_unreachable_object_gives_empty_goal_set_with_reasons(scene_world):
    far = _side_grasps(scene_world.target_model)[:6].copy()
    far[:, :3, 3] += [3.0, 0.0, 0.0]  # 3 m beyond the object
    gs = goals.build_goal_set(scene_world, far, settings=goals.GoalSetSettings(quality=None))
    assert len(gs) == 0 and gs.reasons == ["unreachable"] * 6
    assert gs.goals.shape == (0, 9)
    judged = goals.build_goal_set(scene_world, far)  # the grasp quality first: the pads close on nothing
    assert len(judged) == 0 and judged.reasons == ["misses"] * 6


def test_bad_grasps_raise(scene_world):
    with pytest.raises(ValueError, match=r"grasps: expected shape \(N, 4, 4\), got \(3, 4\)"):
        goals.build_goal_set(scene_world, np.zeros((3, 4)))
    bad = np.tile(np.eye(4), (2, 1, 1))
    bad[1, :3, :3] *= 2.0
    with pytest.raises(ValueError, match=r"grasps \[1\]: not a rigid transform"):
        goals.build_goal_set(scene_world, bad)


def test_world_caches_are_per_world_and_release_the_world(scene_world):
    """Checkers and refiners are built once per world and die with it: alternating between worlds
    must not rebuild them (a shared module-level cache of 4 entries did), nor keep worlds alive."""
    import gc
    import weakref

    from pickplan.omg import isf

    goal, hand = scene_world.checker("goal"), scene_world.checker("hand")
    refiner = scene_world.grasp_refiner(isf.IsfSettings(), 0)
    others = [world.World(scenes.generate_scene(seed)) for seed in (1, 2, 3)]
    for w in others:
        w.checker("goal"), w.checker("hand"), w.grasp_refiner(isf.IsfSettings(), 0)
    assert scene_world.checker("goal") is goal and scene_world.checker("hand") is hand
    assert scene_world.grasp_refiner(isf.IsfSettings(), 0) is refiner
    assert scene_world.grasp_refiner(isf.IsfSettings(), 1) is not refiner  # another seed: another refiner
    refs = [weakref.ref(w) for w in others]
    del others, w
    gc.collect()
    assert all(r() is None for r in refs)


def test_native_ik_path_weights_and_errors(panda):
    """The binding of the one IK solver: solve_path's poses checked by FK, frozen joints kept, and
    bad sizes raise ValueError naming the problem."""
    s = _core.IkSettings()
    s.weights = [1.0] * 7 + [0.0] * 2
    s.rotation_error = _core.IkRotationError.sine_axis
    ik = _core.IkSolver(panda.native, "panda_hand", s)
    q0 = np.array(panda.ready_configuration, dtype=float)
    targets = np.repeat(panda.link_pose(q0, "panda_hand")[None], 5, axis=0)
    targets[:, 0, 3] += 0.03 * np.arange(1, 6)
    Q, ok = ik.solve_path(targets, q0)
    assert ok.all() and Q.shape == (5, 9)
    reached = panda.fk_batch(Q)[:, panda.link_index("panda_hand")]
    assert np.abs(reached[:, :3, 3] - targets[:, :3, 3]).max() < s.position_tolerance
    np.testing.assert_array_equal(Q[:, 7:], np.broadcast_to(q0[7:], (5, 2)))
    bad = _core.IkSettings()
    bad.weights = [1.0]
    with pytest.raises(ValueError, match="weights: expected 9 entries"):
        _core.IkSolver(panda.native, "panda_hand", bad)
    with pytest.raises(ValueError, match=r"target poses: expected shape \(N, 4, 4\)"):
        ik.solve_path(np.eye(4), q0)
    with pytest.raises(ValueError, match="expected 9 joint values, got 7"):
        ik.solve_path(targets, q0[:7])
