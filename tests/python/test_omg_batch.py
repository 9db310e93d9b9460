"""plan_many (issue 24): plans on parallel threads equal the same plans made one by one."""

import numpy as np
import pytest

from pickplan.omg import grasps as grasps_mod
from pickplan.omg.batch import PlanJob, plan_many
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.world import World
from pickplan.sim import scenes


@pytest.fixture(scope="module")
def cases():
    """Two scenes, their worlds (one shared cache) and their targets' antipodal grasps."""
    cache = ModelCache()
    out = []
    for seed in (2, 3):
        scene = scenes.generate_scene(seed)
        world = World(scene, cache=cache)
        out.append((scene, grasps_mod.grasp_set(world.target_model, "antipodal", 40, seed=0).poses))
    return out


def test_threads_plan_what_one_thread_plans(cases):
    settings = OMGSettings()
    alone = [OMGPlanner(None, s, settings).plan(grasps=g) for s, g in cases]
    jobs = [PlanJob(s, grasps=g) for s, g in cases]
    # Each job twice, so threads race on one shared cache and on the same lazily filled grids.
    together = plan_many(jobs + jobs, settings, workers=2, cache=ModelCache())
    assert len(together) == 2 * len(cases)
    for a, b in zip(alone + alone, together):
        assert a.status == b.status and a.grasp_index == b.grasp_index
        assert a.history["goal"] == b.history["goal"]
        np.testing.assert_array_equal(a.trajectory, b.trajectory)


def test_bad_input_names_the_problem(cases):
    with pytest.raises(ValueError, match="workers"):
        plan_many([cases[0][0]], workers=0)
    with pytest.raises(ValueError, match="expected a Scene"):
        plan_many([PlanJob("scene.json")])
