"""Online goal selection against Fixed on a constructed scene (issue 6: "a constructed scene where the
initially cheapest goal is blocked late: the online policies switch and succeed where Fixed fails").

The scene below is a dense built-in scene (frozen from ``generate_scene(32, SceneSettings(6-7
objects, x 0.4-0.7, y -0.25-0.25))``, poses rounded) where the goal with the lowest initial
estimate cannot succeed while others can: the end of its fixed 8 cm standoff approach passes the
mug within a few millimetres (0.1 mm by FCL at the grasp, 6 mm by the success test's SDF), under
the 1 cm the success test demands of the approach; the goal-set filter (FCL, no margin) accepts it.
With the current planner semantics no policy can see that: the approach tail is neither optimized
by CHOMP nor charged by the goal-cost estimate (``obstacle_tail``), so that goal's estimate only
falls as CHOMP converges towards it (the cheapest of the 30 at every one of the 50 iterations)
and no policy ever switches away. The first test pins these facts down; the second states the
issue's requirement and is expected to fail until the estimate (or the goal-set filter) accounts
for the approach's clearance.
"""
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

from pickplan import grasps, objects, omg, scenes
from pickplan.world import World

ONLINE = ("FTC", "FTL", "EXP", "MD")
SETTINGS = omg.OMGSettings(refine=False)  # Table I setting: selection only, no ISF


def _pose(x, y, z, yaw, flip=None):
    """Upright (flip None), upside down ("z") or lying on its side ("x": the object's z axis along
    the world's horizontal)."""
    c, s = math.cos(yaw), math.sin(yaw)
    Rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    F = {None: np.eye(3), "z": np.diag([1.0, -1.0, -1.0]),
         "x": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])}[flip]
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = Rz @ F, (x, y, z)
    return T


# name: (x, y, z, yaw, flip) of the object (mesh) frame
OBJECTS = {
    "024_bowl": (0.5804, 0.2065, 0.0010, 0.2675, None),          # the target
    "002_master_chef_can": (0.5379, -0.0915, 0.1410, 2.0674, "z"),
    "005_tomato_soup_can": (0.4121, -0.1334, 0.1030, 0.3199, "z"),
    "004_sugar_box": (0.6163, -0.1771, 0.0480, 0.6769, "x"),
    "006_mustard_bottle": (0.4484, -0.2167, 0.0010, -0.2564, None),
    "025_mug": (0.5081, 0.0486, 0.0010, -1.0882, None),
    "021_bleach_cleanser": (0.6774, 0.0819, 0.0010, -2.8490, None),
}


@pytest.fixture(scope="module")
def scene():
    objs = [scenes.SceneObject(name, "builtin:" + name, _pose(*p)) for name, p in OBJECTS.items()]
    from pickplan.robots import PandaInfo
    return scenes.Scene(np.eye(4), scenes.default_table(scenes.SceneSettings()), objs, "024_bowl",
                        None, list(PandaInfo.ready))


@pytest.fixture(scope="module")
def world(scene):
    return World(scene)


@pytest.fixture(scope="module")
def grasp_poses(world):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return grasps.antipodal_grasps(world.target_model, 100, seed=0).poses


@pytest.fixture(scope="module")
def runs(scene, world, grasp_poses):
    return {p: omg.OMGPlanner(None, scene, replace(SETTINGS, selection=p), world=world).plan(grasps=grasp_poses)
            for p in ("Fixed",) + ONLINE}


def test_cheapest_goal_fails_others_succeed_and_no_policy_switches(scene, world, grasp_poses, runs):
    fixed = runs["Fixed"]
    assert fixed.goal_set_size >= 10 and fixed.status == "in_collision", (fixed.status, fixed.goal_set_size)
    first = fixed.grasp_index  # Fixed keeps the goal with the best initial estimate
    # the same goal planned alone fails, and so does every policy that stays on it
    alone = omg.OMGPlanner(None, scene, SETTINGS, world=world).plan(grasps=grasp_poses[[first]])
    assert alone.status == "in_collision"
    # the failure is in the approach tail: clearance under its 1 cm, above 0 (the goal set's FCL filter)
    assert 0.0 < alone.metrics["min_clearance"] < SETTINGS.metrics.tail_clearance
    # other goals succeed on their own
    ok = 0
    gs_index = [g for g in range(len(grasp_poses)) if g != first]
    for g in gs_index[:40]:
        r = omg.OMGPlanner(None, scene, SETTINGS, world=world).plan(grasps=grasp_poses[[g]])
        ok += r.status == "success"
        if ok >= 3:
            break
    assert ok >= 3
    # today: no online policy leaves the initial goal, so all fail like Fixed
    for p in ONLINE:
        assert runs[p].history["switches"] == 0 and runs[p].grasp_index == first, p
        assert runs[p].status == fixed.status, p


@pytest.mark.xfail(strict=True, reason="the goal-cost estimate does not charge the standoff approach, where the "
                                       "initially cheapest goal fails; see the module docstring")
def test_online_policies_switch_and_succeed_where_fixed_fails(runs):
    assert runs["Fixed"].status != "success"
    for p in ONLINE:
        assert runs[p].history["switches"] > 0 and runs[p].status == "success", (p, runs[p].status)
