"""The ungraspable verdict (issue 20): boxes whose widths are known exactly, the planner's status,
and sweeps that count ungraspable targets apart with per-object rows."""

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from pickplan.cli.bench import object_markdown, object_rows, settings_from_args
from pickplan.core import objects, robots
from pickplan.core.graspability import graspability
from pickplan.eval.experiments import SweepSettings, sweep_fingerprint
from pickplan.eval.summaries import slip_cell, summarize, summarize_by_object
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanStatus
from pickplan.sim import scenes


def _box(extents):
    return SimpleNamespace(mesh=trimesh.creation.box(extents=extents))


def _turned_about_x(angle):
    T = np.eye(4)
    T[:3, :3] = trimesh.transformations.rotation_matrix(angle, [1, 0, 0])[:3, :3]
    return T


@pytest.mark.parametrize(
    "extents, opening, graspable, reason, narrowest",
    [
        ((0.06, 0.15, 0.03), 0.08, True, "", 0.06),  # 6 cm across fits the 8 cm opening
        ((0.20, 0.15, 0.03), 0.08, False, "flat face", None),  # only the 3 cm height is narrow
        ((0.06, 0.15, 0.03), 0.05, False, "flat face", None),  # the same box, a 5 cm gripper
        ((0.10, 0.12, 0.20), 0.08, False, "wider than the 8 cm opening in every direction", None),
        ((0.06, 0.15, 0.03), 0.02, False, "wider than the 2 cm opening in every direction", None),
    ],
)
def test_verdict_of_boxes_follows_their_exact_widths(extents, opening, graspable, reason, narrowest):
    verdict = graspability(_box(extents), np.eye(4), opening)
    assert verdict.graspable is graspable
    assert reason in verdict.reason and (reason or verdict.reason == "")
    if narrowest is not None:
        assert verdict.narrowest == pytest.approx(narrowest, abs=1e-6)


def test_verdict_depends_on_the_pose():
    """The 20 x 15 x 3 cm box standing on its long edge: 3 cm across is now reachable."""
    box = _box((0.20, 0.15, 0.03))
    assert not graspability(box, np.eye(4), 0.08).graspable
    standing = graspability(box, _turned_about_x(np.pi / 2), 0.08)
    assert standing.graspable and standing.narrowest == pytest.approx(0.03, abs=1e-6)


def test_open_meshes_get_a_verdict_and_bad_openings_raise():
    mesh = trimesh.creation.box(extents=(0.05, 0.05, 0.05))
    mesh.update_faces(np.arange(len(mesh.faces)) > 1)  # one face missing: not watertight
    assert not mesh.is_watertight
    assert graspability(SimpleNamespace(mesh=mesh), np.eye(4), 0.08).graspable
    with pytest.raises(ValueError, match="max_opening"):
        graspability(_box((0.05, 0.05, 0.05)), np.eye(4), 0.0)


def test_planner_reports_an_ungraspable_target_with_its_reason():
    model = objects.library("builtin").get("002_master_chef_can")  # 10 cm across
    pose = np.array(model.resting_poses[0])
    pose[:2, 3] += [0.5, 0.0]
    scene = scenes.Scene(
        robot_base=np.eye(4),
        table=scenes.default_table(scenes.SceneSettings()),
        objects=[scenes.SceneObject(model.name, model.source, pose)],
        target=model.name,
    )
    result = OMGPlanner(None, scene, OMGSettings(grasp_kind="antipodal")).plan()
    assert result.status == PlanStatus.ungraspable and not result.planned
    assert result.reason == "ungraspable: wider than the 8 cm opening in every direction"


def test_scene_targets_are_graspable_when_any_object_is():
    for seed in range(3):
        scene = scenes.generate_scene(seed, "builtin", scenes.SceneSettings(orientation="stable"))
        lib = objects.library("builtin")
        verdicts = {o.name: graspability(lib.get(o.name), o.pose, 0.08).graspable for o in scene.objects}
        assert verdicts[scene.target] or not any(verdicts.values())


def _record(target, method, status, planning=False, execution=False, graspable=True, **extra):
    return {
        "target": target,
        "method": method,
        "status": status,
        "valid": True,
        "graspable": graspable,
        "planned": status not in ("no_goals", "ungraspable"),
        "planning_success": planning,
        "execution_success": execution,
        "execution_run": True,
        "smoothness": 1.0,
        "collision": 0.0,
        "grasp_cost": 1.0,
        "plan_time": 0.01,
        "goal_set_time": 0.01,
        "goal_set_size": 3,
        **extra,
    }


def test_sweep_summaries_count_ungraspable_apart_with_per_object_rows():
    records = [
        _record("pen_00", "OMG", "success", True, True),
        _record("pen_00", "OMG", "no_goals", goal_reasons={"support_penetration": 7, "unreachable": 2}),
        _record("dish_00", "OMG", "success", True, False),
        _record(
            "flat_box_02",
            "OMG",
            "ungraspable",
            graspable=False,
            reason="ungraspable: wider than the 8 cm opening in every direction",
        ),
    ]
    summary = summarize(records, ["OMG"])["OMG"]
    assert summary["valid"] == 3 and summary["ungraspable"] == 1 and summary["no_goals"] == 1
    assert summary["planning"] == pytest.approx(2 / 3) and summary["execution"] == pytest.approx(1 / 3)
    rows = summarize_by_object(records, ["OMG"])
    assert rows["pen_00"]["OMG"]["planning"] == 0.5 and rows["pen_00"]["OMG"]["no_goals"] == 1
    assert rows["pen_00"]["OMG"]["no_goals_reasons"] == {"support_penetration": 7, "unreachable": 2}
    assert rows["dish_00"]["OMG"]["execution"] == 0.0
    assert rows["flat_box_02"]["OMG"]["graspable"] == 0 and rows["flat_box_02"]["OMG"]["ungraspable"] == 1
    text = object_markdown(rows, ["OMG"])
    assert "| pen_00 | 50% / 50% (2) | n/a | 0 / 0 / 0 / 0 | OMG 1 (support_penetration 7, unreachable 2) | 0 |" in text
    assert (
        "| flat_box_02 | - | n/a | 0 / 0 / 0 / 0 | 0 | 1 (ungraspable: wider than the 8 cm opening in every direction) |"
        in text
    )
    csv_rows = object_rows(rows)
    assert {r["object"] for r in csv_rows} == {"pen_00", "dish_00", "flat_box_02"}
    assert (
        next(r for r in csv_rows if r["object"] == "pen_00")["no_goals_reasons"]
        == "support_penetration:7;unreachable:2"
    )


def test_slip_is_the_median_over_lifted_units_and_undefined_without_one():
    """Slip in the hand: the median over lifted units only (a dropped unit's slip does not count), a
    unit slipped beyond 1 cm or 10 degrees counted; with nothing lifted (e.g. not executed) it is None,
    so two summaries of the same records are equal and the table cell reads n/a."""
    records = [
        _record("pen_00", "OMG", "success", True, True, slip=0.002, slip_rotation=1.0),
        _record("pen_00", "OMG", "success", True, True, slip=0.004, slip_rotation=12.0),
        _record("pen_00", "OMG", "success", True, True, slip=0.030, slip_rotation=2.0),
        _record("pen_00", "OMG", "success", True, False, slip=0.5, slip_rotation=90.0, execution_status="dropped"),
    ]
    row = summarize(records, ["OMG"])["OMG"]
    assert row["slip"] == pytest.approx(0.004) and row["slip_rotation"] == pytest.approx(2.0)
    assert row["slipped"] == 2 and row["dropped"] == 1
    assert slip_cell(row) == "4.0 / 2.0 (2)"
    unexecuted = [
        {
            **r,
            "execution_success": False,
            "execution_run": False,
            "slip": None,
            "slip_rotation": None,
            "trajectory_duration": 2.0,
        }
        for r in records
    ]
    first, second = summarize(unexecuted, ["OMG"]), summarize([dict(r) for r in unexecuted], ["OMG"])
    assert first["OMG"]["slip"] is None and first == second
    assert slip_cell(first["OMG"]) == "n/a"


def test_bench_takes_the_scene_settings():
    import argparse

    from pickplan.cli.bench import add_bench_commands

    parser = argparse.ArgumentParser()
    add_bench_commands(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["bench", "planners", "--objects", "procedural", "--poses", "stable", "--clutter", "8-12"])
    s = settings_from_args(args)
    assert (s.objects, s.poses, s.clutter) == ("procedural", "stable", (8, 12))
    fp = sweep_fingerprint(s)
    assert fp["objects"] == "procedural" and fp["poses"] == "stable" and fp["clutter"] == [8, 12]
    with pytest.raises(ValueError, match="poses"):
        SweepSettings("planners", poses="sideways")
    with pytest.raises(ValueError, match="clutter"):
        SweepSettings("planners", clutter=(5, 2))
    with pytest.raises(SystemExit):
        parser.parse_args(["bench", "planners", "--clutter", "12-8"])


def test_sweep_scenes_follow_the_scene_settings(tmp_path):
    from pickplan.eval.experiments import _make_scene

    path = str(tmp_path / "scene.json")
    _make_scene({"path": path, "seed": 5, "objects": "procedural", "poses": "stable", "clutter": (8, 9)})
    scene = scenes.Scene.load(path)
    assert 8 <= len(scene.objects) <= 9
    assert all(o.source.startswith("procedural:") for o in scene.objects)


def test_an_upside_down_bowl_is_closed_off_and_an_upright_one_is_not():
    bowl = objects.library("builtin").get("024_bowl")
    upside_down, upright = (np.array(T) for T in bowl.resting_poses[:2])
    assert upside_down[2, 2] < -0.99 and upright[2, 2] > 0.99
    assert graspability(bowl, upright, 0.08).graspable
    verdict = graspability(bowl, upside_down, 0.08)
    assert not verdict.graspable and "closed off from above" in verdict.reason


def test_a_cached_ray_mesh_gives_the_verdicts_of_a_private_one_on_threads():
    """Issue 24 (a new scene in 50 ms): the ray tree is built once per object (ModelCache.ray_mesh), not
    per world; verdicts for many poses on two threads sharing it equal those of a fresh private mesh."""
    from concurrent.futures import ThreadPoolExecutor

    from pickplan.omg.model_cache import ModelCache

    bowl = objects.library("builtin").get("024_bowl")
    cache = ModelCache()
    shared = cache.ray_mesh(bowl.mesh)
    assert cache.ray_mesh(bowl.mesh) is shared and shared.mesh is not bowl.mesh
    poses = [np.array(T) for T in bowl.resting_poses[:2]] + [_turned_about_x(a) for a in np.linspace(0, np.pi, 7)]
    alone = [graspability(bowl, T, 0.08) for T in poses]
    assert {v.graspable for v in alone} == {True, False}  # both verdicts occur: a wrong tree would show
    with ThreadPoolExecutor(2) as pool:
        together = list(pool.map(lambda T: graspability(bowl, T, 0.08, ray_mesh=shared), poses * 3))
    assert together == alone * 3


def test_the_verdict_and_the_generator_agree_on_every_procedural_family_and_pose():
    """Issue 33: a target the verdict calls graspable gets antipodal candidates that the support under it
    allows, in every resting pose of every procedural family (short cans lying flat among them); where
    the generator finds none, it says what it rejected (a reason the tables count, never silence)."""
    from pickplan.core import procedural
    from pickplan.omg.grasps import AntipodalSettings, antipodal_grasps
    from pickplan.omg.grasps.generators import SupportFilter

    quick = AntipodalSettings(samples_per_round=100, approach_angles=4)
    lib, hand = objects.library("procedural"), robots.panda()
    disagree, judged = [], 0
    for family in procedural.FAMILIES:
        model = lib.get(f"{family}_00")
        for i, pose in enumerate(model.resting_poses):
            if not graspability(model, pose, 0.08).graspable:
                continue
            judged += 1
            gs = antipodal_grasps(model, 1, seed=0, settings=quick, support=SupportFilter.under(pose, robot=hand))
            if len(gs) == 0:
                disagree.append((family, i, gs.rejected))
    assert judged >= 2 * len(procedural.FAMILIES) and not disagree, disagree


def test_a_graspable_target_without_candidates_is_counted_with_the_generators_reasons():
    """No grasp of the generator: the goal set says "no_candidates" and the generator's rejections
    name why (here a 20 x 15 x 3 cm slab lying flat: pairs only across its height, which the support
    under it leaves no finger room for)."""
    from pickplan.omg.goals import build_goal_set
    from pickplan.omg.grasps import AntipodalSettings, antipodal_grasps
    from pickplan.omg.grasps.generators import SupportFilter
    from pickplan.omg.world import World

    slab = objects.make_object("slab", trimesh.creation.box(extents=(0.20, 0.15, 0.03)), [], "test")
    gs = antipodal_grasps(
        slab,
        5,
        seed=0,
        settings=AntipodalSettings(max_rounds=2, samples_per_round=100),
        support=SupportFilter.under(slab.resting_poses[0]),
    )
    assert len(gs) == 0 and gs.rejected["support"] > 0 and sum(gs.rejected.values()) >= 200
    model = objects.library("builtin").get("005_tomato_soup_can")
    pose = np.array(model.resting_poses[0])
    pose[:2, 3] += [0.5, 0.0]
    scene = scenes.Scene(
        robot_base=np.eye(4),
        table=scenes.default_table(scenes.SceneSettings()),
        objects=[scenes.SceneObject(model.name, model.source, pose)],
        target=model.name,
    )
    assert build_goal_set(World(scene), np.zeros((0, 4, 4))).reason_counts() == {"no_candidates": 1}
