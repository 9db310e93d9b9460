"""The ungraspable verdict (issue 20): boxes whose widths are known exactly, the planner's status,
and sweeps that count ungraspable targets apart with per-object rows."""
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from pickplan.cli.bench import object_markdown, object_rows, settings_from_args
from pickplan.core import objects
from pickplan.core.graspability import graspability
from pickplan.eval.experiments import SweepSettings, sweep_fingerprint
from pickplan.eval.summaries import summarize, summarize_by_object
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanStatus
from pickplan.sim import scenes


def _box(extents):
    return SimpleNamespace(mesh=trimesh.creation.box(extents=extents))


def _turned_about_x(angle):
    T = np.eye(4)
    T[:3, :3] = trimesh.transformations.rotation_matrix(angle, [1, 0, 0])[:3, :3]
    return T


@pytest.mark.parametrize("extents, opening, graspable, reason, narrowest", [
    ((0.06, 0.15, 0.03), 0.08, True, "", 0.06),       # 6 cm across fits the 8 cm opening
    ((0.20, 0.15, 0.03), 0.08, False, "flat face", None),   # only the 3 cm height is narrow
    ((0.06, 0.15, 0.03), 0.05, False, "flat face", None),   # the same box, a 5 cm gripper
    ((0.10, 0.12, 0.20), 0.08, False, "wider than the 8 cm opening in every direction", None),
    ((0.06, 0.15, 0.03), 0.02, False, "wider than the 2 cm opening in every direction", None),
])
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
    scene = scenes.Scene(robot_base=np.eye(4), table=scenes.default_table(scenes.SceneSettings()),
                         objects=[scenes.SceneObject(model.name, model.source, pose)], target=model.name)
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
    return {"target": target, "method": method, "status": status, "valid": True, "graspable": graspable,
            "planned": status not in ("no_goals", "ungraspable"), "planning_success": planning,
            "execution_success": execution, "execution_run": True, "smoothness": 1.0, "collision": 0.0,
            "grasp_cost": 1.0, "plan_time": 0.01, "goal_set_time": 0.01, "goal_set_size": 3, **extra}


def test_sweep_summaries_count_ungraspable_apart_with_per_object_rows():
    records = [_record("pen_00", "OMG", "success", True, True),
               _record("pen_00", "OMG", "no_goals", goal_reasons={"support_penetration": 7, "unreachable": 2}),
               _record("dish_00", "OMG", "success", True, False),
               _record("flat_box_02", "OMG", "ungraspable", graspable=False,
                       reason="ungraspable: wider than the 8 cm opening in every direction")]
    summary = summarize(records, ["OMG"])["OMG"]
    assert summary["valid"] == 3 and summary["ungraspable"] == 1 and summary["no_goals"] == 1
    assert summary["planning"] == pytest.approx(2 / 3) and summary["execution"] == pytest.approx(1 / 3)
    rows = summarize_by_object(records, ["OMG"])
    assert rows["pen_00"]["OMG"]["planning"] == 0.5 and rows["pen_00"]["OMG"]["no_goals"] == 1
    assert rows["pen_00"]["OMG"]["no_goals_reasons"] == {"support_penetration": 7, "unreachable": 2}
    assert rows["dish_00"]["OMG"]["execution"] == 0.0
    assert rows["flat_box_02"]["OMG"]["graspable"] == 0 and rows["flat_box_02"]["OMG"]["ungraspable"] == 1
    text = object_markdown(rows, ["OMG"])
    assert "| pen_00 | 50% / 50% (2) | OMG 1 (support_penetration 7, unreachable 2) | 0 |" in text
    assert "| flat_box_02 | - | 0 | 1 (ungraspable: wider than the 8 cm opening in every direction) |" in text
    csv_rows = object_rows(rows)
    assert {r["object"] for r in csv_rows} == {"pen_00", "dish_00", "flat_box_02"}
    assert next(r for r in csv_rows if r["object"] == "pen_00")["no_goals_reasons"] == \
        "support_penetration:7;unreachable:2"


def test_bench_takes_the_scene_settings():
    import argparse

    from pickplan.cli.bench import add_bench_commands

    parser = argparse.ArgumentParser()
    add_bench_commands(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["bench", "planners", "--objects", "procedural", "--poses", "stable",
                              "--clutter", "8-12"])
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
