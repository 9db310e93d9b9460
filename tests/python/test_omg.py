"""The OMG planner end to end, and C-Space ISF, checked against independent truth."""

import warnings
from dataclasses import replace

import numpy as np
import pytest

from pickplan.omg import grasps
from pickplan.omg import isf
from pickplan.core import objects
from pickplan.omg import planner as omg
from pickplan.sim import scenes
from pickplan.omg import world
from conftest import ycb_dir_or_skip

SETTINGS = omg.OMGSettings(grasp_kind="antipodal")


@pytest.fixture(scope="module")
def scene():
    return scenes.generate_scene(1)  # built-in objects; the target is the tomato soup can


@pytest.fixture(scope="module")
def result(scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return omg.OMGPlanner(None, scene, SETTINGS).plan()


def test_plan_succeeds_and_is_consistent(scene, result):
    assert result.status == "success", result.metrics
    traj = result.trajectory
    assert traj.shape == (SETTINGS.chomp.n + 1, 9)
    np.testing.assert_array_equal(traj[0], np.asarray(scene.robot_configuration))
    np.testing.assert_array_equal(traj[-1], result.goal)
    m = result.metrics
    assert m.collision_free and m.smoothness < 30
    # The reported smoothness is f_prior of the waypoints (dt = 0.1 s), recomputed here.
    assert m.smoothness == pytest.approx(0.5 * np.sum(np.diff(traj, axis=0) ** 2) / 0.1**2, rel=1e-9)
    assert np.all(traj >= result_world(scene).robot.lower_limits - 1e-9)
    assert result.timings["total"] > 0 and result.iterations >= 1
    assert len(result.history["objective"]) == result.iterations


def result_world(scene):
    return world.World(scene)


def test_plan_is_free_of_obstacles_by_exact_fcl(scene, result):
    w = result_world(scene)
    from pickplan import _core

    dense = _core.interpolate(result.trajectory[0], result.trajectory[1:], 200)
    free = ~w.checker("obstacles").in_collision_batch(dense)
    assert free.all()  # independent of the SDF: exact meshes, target excluded


def test_hand_ends_at_the_chosen_grasp(scene, result):
    w = result_world(scene)
    gset = grasps.grasp_set(w.target_model, "antipodal", SETTINGS.grasp_count, seed=SETTINGS.seed)
    want = w.target_pose @ gset.poses[result.grasp_index]
    # ISF moves the hand a little away from the original grasp, toward a better fit.
    assert np.linalg.norm(result.hand_pose[:3, 3] - want[:3, 3]) < 0.03


def test_same_seed_same_plan(scene, result):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        again = omg.OMGPlanner(None, scene, SETTINGS).plan()
    np.testing.assert_array_equal(again.trajectory, result.trajectory)


def test_unreachable_grasps_give_a_no_goals_status(scene):
    far = np.tile(np.eye(4), (3, 1, 1))
    far[:, :3, 3] = [3.0, 0.0, 0.0]
    # judged by IK alone (no quality): out of reach; with the quality, the pads there meet nothing
    alone = replace(SETTINGS, goals=replace(SETTINGS.goals, quality=None))
    r = omg.OMGPlanner(None, scene, alone).plan(grasps=far)
    assert r.status == "no_goals" and r.goal_reasons == {"unreachable": 3}
    r = omg.OMGPlanner(None, scene, SETTINGS).plan(grasps=far)
    assert r.status == "no_goals" and r.goal_reasons == {"misses": 3}


def test_bad_start_raises(scene):
    planner = omg.OMGPlanner(None, scene, SETTINGS)
    with pytest.raises(ValueError, match="expected 9 joint values, got 7"):
        planner.plan(start=np.zeros(7))
    robot = planner.world().robot
    q = planner.world().start.copy()
    q[3] = robot.upper_limits[3] + 0.5
    lo, hi = robot.lower_limits[3], robot.upper_limits[3]
    with pytest.raises(
        ValueError,
        match=rf"start: joint panda_joint4 = {q[3]:.4f} is outside its limits "
        rf"\[{lo:.4f}, {hi:.4f}\]",
    ):
        planner.plan(start=q)


def test_isf_decreases_f_grasp_on_ycb_simulated_grasps(tmp_path):
    folder = ycb_dir_or_skip()
    lib = objects.library(folder)
    sc = scenes.generate_scene(3, library=lib)
    w = world.World(sc)
    from pickplan.omg import goals

    gset = grasps.grasp_set(w.target_model, "simulated", 100)
    # every stored grasp (the grasp quality would drop most of this target's): ISF is what is tested
    gs = goals.build_goal_set(w, gset.poses, settings=goals.GoalSetSettings(max_goals=10, quality=None))
    assert len(gs) >= 3, gs.reason_counts()
    refiner = isf.GraspRefiner(w)
    before = np.array([refiner.cost(g)[0].total for g in gs.goals])
    after = np.array([refiner.refine(g, 10)[1].total for g in gs.goals])
    assert np.all(after <= before)  # a step is only taken when f_grasp decreases
    assert after.mean() < before.mean()  # and on these grasps it does decrease


def test_isf_pushes_a_penetrating_hand_out(scene):
    w = world.World(scene)
    from pickplan.omg import goals

    gset = grasps.grasp_set(w.target_model, "antipodal", 60, seed=0)
    gs = goals.build_goal_set(w, gset.poses, settings=goals.GoalSetSettings(max_goals=5))
    refiner = isf.GraspRefiner(w, isf.IsfSettings(max_joint_step=0.02))
    robot = w.robot
    # Push the hand 2 cm further along its approach axis: the palm now sits in the object.
    T = robot.link_pose(gs.goals[0], robot.hand_link).copy()
    T[:3, 3] += 0.02 * T[:3, 2]
    ik = goals.ik_solver(w)
    q = ik.solve(T, gs.goals[0]).q
    before, _ = refiner.cost(q)
    assert before.hand > 0.5
    q2, after = refiner.refine(q, 40)
    assert after.hand < 0.2 * before.hand


def test_world_merges_the_target_out_and_in(scene):
    """Grasping and the success test leave the target out; the transit that avoids it keeps it in: each
    reads a merged grid of its own, within the resampling error of the per-object grids."""
    w = result_world(scene)
    assert w.sdf.merged_excludes == [(scene.target,), ()]
    center = w.target_pose[:3, 3]
    rng = np.random.default_rng(0)
    pts = center + rng.uniform(-0.15, 0.15, (3000, 3))
    tol = w.sdf.merged_info.resolution * np.sqrt(3) / 2
    unmerged = world.World(scene, world.WorldSettings(sdf=replace(world.WorldSettings().sdf, merged=False)))
    assert unmerged.sdf.merged_excludes == []
    for exclude in ((scene.target,), ()):
        d, _ = w.sdf.distance(pts, 0.2, exclude=exclude)
        d_ref, _ = unmerged.sdf.distance(pts, 0.2, exclude=exclude)
        assert np.max(np.abs(d - d_ref)) <= tol
    near_target = w.sdf.distance(pts, 0.2, exclude=())[0] < w.sdf.distance(pts, 0.2, exclude=(scene.target,))[0] - 0.02
    assert near_target.sum() > 100  # the target is in one and out of the other


def test_one_planner_plans_scene_after_scene_as_new_planners_do(monkeypatch):
    """A long-lived planner (``plan(scene=...)``) gives each scene the plan a new planner gives it, and
    builds an object's grasp set once for every scene that holds it."""
    settings = omg.OMGSettings(grasp_kind="antipodal")
    sequence = [scenes.generate_scene(s) for s in (4, 5, 4)]
    planner = omg.OMGPlanner(None, settings=settings)
    with pytest.raises(ValueError, match="no scene"):
        planner.plan()
    for scene in sequence:
        ours = planner.plan(scene=scene)
        theirs = omg.OMGPlanner(None, scene, settings).plan()
        assert ours.status == theirs.status
        np.testing.assert_array_equal(ours.trajectory, theirs.trajectory)
    generated, original = [], grasps.grasp_set
    monkeypatch.setattr(omg.grasps_mod, "grasp_set", lambda *a, **k: generated.append(a) or original(*a, **k))
    planner.plan(scene=sequence[1])
    assert generated == []  # known objects: no grasp set generated again
    omg.OMGPlanner(None, settings=settings).plan(scene=sequence[1])
    assert len(generated) == 1  # a new planner's cache knows nothing: generated once
