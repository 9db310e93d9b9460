"""The pick a pick and place carries (``omg.verified_pick``): its grasp, as planned, lifted in PyBullet and
planned again without each grasp that falls; on a tabletop too, a failed pick once more from a sampled start."""

import time
from dataclasses import replace

import numpy as np

from pickplan.omg.grasps import verify
from pickplan.omg.grasps.physics import LiftSettings, SimObject, lift_trial
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanStatus
from pickplan.omg.verified_pick import verified_pick
from pickplan.omg.world import CheckerKind

from conftest import known_scene, standing_scene


def _held_alone(world, q, settings: verify.VerifySettings, standoff: float) -> bool:
    """The grasp at ``q`` lifted once in PyBullet, no cache."""
    rest, _ = verify._table_rest(world._target_on_table)
    lift = replace(settings.lift, approach=standoff)
    grasp = np.linalg.solve(world.target_pose, world.robot.link_pose(q, world.robot.hand_link))
    trial = lift_trial(SimObject(world.target_model), [rest], grasp, lift, world.robot.info)
    return verify._held(trial, settings)


def test_a_pick_whose_grasp_falls_is_planned_again_without_it(tmp_path, monkeypatch):
    """The known sugar box with a 3.5 N squeeze: the first plan's grasp falls in a lift alone; the verified
    pick drops it (and the others that fall) and ends at a grasp that holds when lifted alone. With 2 N
    every plan's grasp falls: no_goals, and the reason says so."""
    monkeypatch.setenv("PICKPLAN_CACHE_DIR", str(tmp_path))
    weak = verify.VerifySettings(budget=5, lift=LiftSettings(table_clearance=-0.002, finger_force=3.5))
    planner = OMGPlanner(None, known_scene()[0], OMGSettings(grasp_kind="antipodal"))
    world, standoff = planner.world(), planner.settings.goals.standoff
    first = planner.plan()
    assert first.success and not _held_alone(world, first.goal, weak, standoff)
    fell: set = set()
    pick, goals = verified_pick(planner, None, None, weak, fell, time.process_time)
    assert pick.success and first.grasp_index in fell and pick.grasp_index not in fell
    assert _held_alone(world, pick.goal, weak, standoff)
    hopeless = replace(weak, lift=replace(weak.lift, finger_force=2.0))
    fell = set()
    pick, _ = verified_pick(planner, None, None, hopeless, fell, time.process_time)
    assert pick.status.value == "no_goals" and len(fell) == hopeless.budget and "fell in a lift" in pick.reason


def test_a_plan_that_misses_its_success_test_after_a_fall_is_set_aside_too(tmp_path, monkeypatch):
    """The sugar box with a 3.5 N squeeze again; the plan after the first fall is marked as missing the
    success test (``not_smooth``, as a far goal's plan does). The verified pick sets its grasp aside as it
    does a grasp that fell, plans again among the rest, and ends at a grasp that holds when lifted alone
    (it returned the failed plan before)."""
    monkeypatch.setenv("PICKPLAN_CACHE_DIR", str(tmp_path))
    weak = verify.VerifySettings(budget=5, lift=LiftSettings(table_clearance=-0.002, finger_force=3.5))
    planner = OMGPlanner(None, known_scene()[0], OMGSettings(grasp_kind="antipodal"))
    world, standoff = planner.world(), planner.settings.goals.standoff
    failed_grasps, real = [], planner.plan

    def plan(start=None, grasps=None, **kw):
        result = real(start, grasps=grasps, **kw)
        if failed_grasps or not result.success:
            return result
        failed_grasps.append(np.asarray(grasps)[result.grasp_index])
        return replace(result, status=PlanStatus.not_smooth)

    monkeypatch.setattr(planner, "plan", plan)
    fell: set = set()
    pick, goals = verified_pick(planner, None, None, weak, fell, time.process_time)
    assert failed_grasps and pick.success, pick.status
    assert not np.allclose(goals.grasps[pick.grasp_index], failed_grasps[0])
    assert _held_alone(world, pick.goal, weak, standoff)


def test_a_tabletop_pick_that_fails_runs_once_more_from_a_sampled_start():
    """A soup can ringed by a cracker box, a sugar box and a mustard bottle, with a 5-iteration loop: from
    the straight line the plan ends in collision; the verified pick runs the loop once more from an
    RRT-Connect start (as the planner does among furniture) and passes the success test, every
    configuration clear of the other objects by FCL (the target left out)."""
    can, r, a = np.array([0.53, 0.023]), 0.137, 2.782
    ring = [can + r * np.array([np.cos(t), np.sin(t)]) for t in (a, a + 1.8, a - 1.8)]
    names = ("003_cracker_box", "004_sugar_box", "006_mustard_bottle")
    scene = standing_scene(
        (("005_tomato_soup_can", tuple(can)),) + tuple(zip(names, map(tuple, ring))), "005_tomato_soup_can"
    )[0]
    planner = OMGPlanner(None, scene, OMGSettings(grasp_kind="antipodal", iterations=5))
    first = planner.plan()
    assert first.status.value == "in_collision"
    pick, _ = verified_pick(planner, None, None, None, set(), time.process_time)
    assert pick.success and pick.history.get("sampled_start")
    checker = planner.world().checker(CheckerKind.obstacles)
    assert not checker.in_collision_batch(pick.trajectory).any()


def test_a_world_from_depth_has_no_sampled_start_and_a_failed_plan_stays_as_it_was():
    """A perceived world (a fused field, no meshes) and the carry of its observed points have no FCL
    checker to sample a start in: ``sampled_retry`` returns the failed plan as it was (it raised before,
    and a pick and place from depth whose transfer failed ended in an exception)."""
    from pickplan.omg.attach import HeldWorld, held_from_plan
    from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
    from pickplan.omg.planner import PlanStatus, sampled_retry
    from pickplan.sim.observe import render_observation

    world = PerceivedWorld(render_observation(known_scene()[0], views=3, seed=0))
    planner = PerceivedPlanner(world, OMGSettings())
    pick, goals = planner.plan_with_goals()
    assert pick.success
    for w in (world, HeldWorld(world, held_from_plan(world, pick.goal))):
        failed = replace(pick, status=PlanStatus.in_collision)
        assert sampled_retry(planner.settings, w, pick.trajectory[0], goals, {}, failed) is failed
