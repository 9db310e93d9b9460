"""Issue 24: the faster planner plans what the planner before it planned. The reference plans in
tests/data/omg_reference.npz were made by main at 50b7e25 (before issue 24 was merged) (tests/data/make_omg_reference.py):
the same goals chosen at every iteration and trajectories equal to 1e-9, on built-in scenes, with
a world of its own and with worlds sharing one ModelCache (objects and robot data reused). The reference
predates issue 21's transit that avoids the target (session 11), which changes plans on purpose: the
comparison runs with it off (``transit_avoids_target=False``), as the planner was then, and so does
issue 33's grasp quality, which drops the goals of grasps that slip (``GoalSetSettings(quality=None)``).
Session 20's one pad derivation for every gripper moved the trajectories (ISF), not one decision: the
reference's trajectories were replanned then (``make_omg_reference.py --rebase``)."""

import json
import os

import numpy as np
import pytest

from pickplan.omg import planner as omg
from pickplan.omg.goals import GoalSetSettings
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.world import World
from pickplan.sim.scenes import Scene

REFERENCE = os.path.join(os.path.dirname(__file__), "..", "data", "omg_reference.npz")
CASES = (("s1", True), ("s2", True), ("s3", True), ("s2full", False), ("s4full", False))


@pytest.fixture(scope="module")
def reference():
    with np.load(REFERENCE, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def check_same(ref, prefix, result):
    assert str(result.status.value) == str(ref[prefix + "status"])
    np.testing.assert_array_equal(result.goal_set, ref[prefix + "goal_set"])
    np.testing.assert_array_equal(np.asarray(result.history["goal"]), ref[prefix + "goals_chosen"])
    grasp, source, iterations, refined = ref[prefix + "scalars"]
    assert (result.grasp_index, result.goal_source, result.iterations, int(result.refined)) == (
        grasp,
        source,
        iterations,
        refined,
    )
    np.testing.assert_allclose(result.trajectory, ref[prefix + "trajectory"], rtol=0, atol=1e-9)


def plan_case(reference, p, pre_terminate, cache):
    """The stored scene and grasps planned as the reference was: the settings of its day."""
    scene = Scene.from_dict(json.loads(str(reference[p + "scene"])))
    settings = omg.OMGSettings(
        pre_terminate=pre_terminate, transit_avoids_target=False, goals=GoalSetSettings(quality=None)
    )
    world = World(scene, settings.world, cache=cache)
    return omg.OMGPlanner(None, scene, settings, world=world).plan(grasps=reference[p + "grasps"])


@pytest.mark.parametrize("shared_cache", [False, True], ids=["own_world", "shared_cache"])
def test_plans_equal_the_reference(reference, shared_cache):
    cache = ModelCache() if shared_cache else None
    for prefix, pre_terminate in CASES:
        check_same(reference, prefix + "_", plan_case(reference, prefix + "_", pre_terminate, cache))


def test_shared_cache_reuses_object_and_robot_data(reference):
    """A second world of the same scene builds no grid, FCL shape or hand SDF: every one is a hit."""
    cache = ModelCache()
    scene = Scene.from_dict(json.loads(str(reference["s2_scene"])))
    first = World(scene, cache=cache)
    first.checker("goal"), first.checker("hand"), first.grasp_refiner()
    misses = (cache.grids.misses, cache.shapes.misses)
    second = World(scene, cache=cache)
    second.checker("goal"), second.checker("hand"), second.grasp_refiner()
    assert (cache.grids.misses, cache.shapes.misses) == misses
    assert cache.grids.hits >= len(scene.objects) and cache.shapes.hits > 0
    assert second.robot is not first.robot and second.body is first.body
