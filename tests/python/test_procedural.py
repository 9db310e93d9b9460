"""Procedural object families, drop probabilities of resting poses, and scenes posed as they come."""

import json

import numpy as np
import pybullet as pb
import pytest
import trimesh

from pickplan.cli import scenes as scenes_cli
from pickplan.core import objects, procedural, stability
from pickplan.sim import scenes

OPENING = 0.08  # a parallel gripper's opening, to state what each family is for


@pytest.fixture(scope="module")
def lib():
    return objects.library("procedural")


def test_every_family_object_is_a_watertight_solid_with_convex_parts(lib):
    assert len(lib) == len(procedural.FAMILIES) * procedural.VARIANTS
    for name in lib.names:
        model = lib.get(name)
        assert model.mesh.is_watertight and model.mesh.volume > 0, name
        assert model.mass > 0 and 0 < model.friction <= 1.5, name
        assert all(p.is_convex for p in model.collision_parts), name
        # the parts are the solids the mesh is the union of: same volume up to their overlaps
        assert sum(p.volume for p in model.collision_parts) >= model.mesh.volume * 0.999, name
        assert model.resting_poses and abs(sum(model.resting_probabilities) - 1) < 1e-9, name


def test_objects_are_the_same_in_every_process(lib):
    mesh, _, _ = procedural.generate("scissors_01")
    assert np.array_equal(mesh.vertices, lib.get("scissors_01").mesh.vertices)
    assert not np.allclose(mesh.extents, procedural.generate("scissors_02")[0].extents)
    assert objects.model_from_source("x", "procedural:pen_00") is lib.get("pen_00")
    with pytest.raises(KeyError, match="unknown procedural object"):
        procedural.generate("spoon_00")


def test_families_cover_what_the_paper_objects_do_not(lib):
    def lying_height(name):  # height in the most likely resting pose
        m = lib.get(name)
        T = m.resting_poses[int(np.argmax(m.resting_probabilities))]
        return np.ptp((m.mesh.vertices @ T[:3, :3].T)[:, 2])

    for k in range(procedural.VARIANTS):
        assert lib.get(f"small_{k:02d}").extents.max() < 0.03
        for thin in ("pen", "scissors", "flat_box", "dish"):
            assert lying_height(f"{thin}_{k:02d}") < 0.025, thin
        long_box = np.sort(lib.get(f"long_box_{k:02d}").extents)
        assert long_box[2] > OPENING and long_box[0] < OPENING
        pot = lib.get(f"pot_{k:02d}")
        assert np.sort(pot.extents)[1] > OPENING  # its body: too wide to grasp around, only by a handle
        for shaped in ("scissors", "pot", "jar", "clamp"):  # not convex: handles, loops, lids
            m = lib.get(f"{shaped}_{k:02d}")
            assert m.mesh.volume < 0.97 * m.mesh.convex_hull.volume, shaped


def test_drop_probabilities_of_a_box_are_its_faces_solid_angles():
    a, b, c = 0.2, 0.1, 0.05
    box = trimesh.creation.box((a, b, c))
    poses, _ = objects.compute_resting_poses(box, np.zeros(3))
    p = stability.resting_probabilities(box, np.zeros(3), poses)

    def omega(u, v, d):  # solid angle of a u x v rectangle at distance d from its centre's normal
        return 4 * np.arcsin(u * v / np.sqrt((u * u + 4 * d * d) * (v * v + 4 * d * d)))

    expected = {round(c, 4): omega(a, b, c / 2), round(b, 4): omega(a, c, b / 2), round(a, 4): omega(b, c, a / 2)}
    for T, prob in zip(poses, p):
        height = round(float(np.ptp((box.vertices @ np.asarray(T)[:3, :3].T)[:, 2])), 4)
        assert prob == pytest.approx(expected[height] / (4 * np.pi), abs=1e-9)


def test_a_face_the_com_overhangs_drains_into_its_neighbours():
    # a prism on an obtuse triangle: its centroid does not project onto the short side AB, so the
    # object cannot rest on that face, and the solid angle of that face goes to the faces it tips onto
    A, B, C = (0.0, 0.0), (0.1, 0.0), (0.3, 0.1)
    verts = [[x, y, z] for y in (0.0, 0.05) for x, z in (A, B, C)]
    prism = trimesh.Trimesh(
        vertices=verts, faces=[[0, 1, 2], [3, 5, 4], [0, 3, 4], [0, 4, 1], [1, 4, 5], [1, 5, 2], [2, 5, 3], [2, 3, 0]]
    )
    prism.fix_normals()
    com = prism.center_mass
    poses, _ = objects.compute_resting_poses(prism, com)
    p = stability.resting_probabilities(prism, com, poses)
    assert len(poses) == 4 and abs(sum(p) - 1) < 1e-9  # five faces, four resting poses
    omega = stability.triangle_solid_angles(prism.triangles, com)
    assert omega.sum() == pytest.approx(4 * np.pi, rel=1e-9)
    # each resting pose gets at least its own face's solid angle; together they get all of AB's too
    down = [np.asarray(T)[:3, :3].T @ [0, 0, -1.0] for T in poses]
    own = [omega[np.abs(prism.face_normals @ n - 1) < 1e-9].sum() / (4 * np.pi) for n in down]
    assert all(pi >= oi - 1e-12 for pi, oi in zip(p, own)) and sum(p) - sum(own) > 0.01


def test_stable_scenes_hold_still_after_reloading(tmp_path):
    settings = scenes.SceneSettings(orientation="stable", min_objects=8, max_objects=10)
    scene = scenes.generate_scene(5, objects.library("procedural"), settings)
    assert 1 <= len(scene.objects) <= 10
    path = tmp_path / "s.json"
    scene.save(path)
    reloaded = scenes.Scene.load(path)
    client = pb.connect(pb.DIRECT)
    try:
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        ids = scenes.load_into_pybullet(reloaded, client)
        lib = objects.library("procedural")
        before = {o.name: scenes.object_pose(client, ids[o.name], lib.get(o.name)) for o in reloaded.objects}
        for _ in range(240):
            pb.stepSimulation(physicsClientId=client)
        for o in reloaded.objects:
            after = scenes.object_pose(client, ids[o.name], lib.get(o.name))
            assert np.linalg.norm(after[:3, 3] - before[o.name][:3, 3]) < 0.003, o.name
    finally:
        pb.disconnect(client)


def test_the_scenes_command_takes_poses_objects_and_clutter(tmp_path):
    out = tmp_path / "set"
    assert (
        scenes_cli.main(
            [
                "scenes",
                "--n",
                "2",
                "--seed",
                "1",
                "--objects",
                "procedural",
                "--poses",
                "stable",
                "--clutter",
                "8-10",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    index = json.loads((out / "index.json").read_text())
    assert index["orientation"] == "stable" and index["clutter"] == [8, 10] and index["objects"] == "procedural"
    assert all(1 <= len(e["objects"]) <= 10 for e in index["scenes"])
    assert scenes_cli.clutter_range("4") == (4, 4)
    for bad in ("0-3", "5-2", "many"):
        with pytest.raises(Exception, match="expected"):
            scenes_cli.clutter_range(bad)
