"""MoveIt's scene files into pickplan's scene model: PlanningScene YAML and the .scene text, against
hand-computed geometry; malformed files named with their field; MotionBenchMaker's files as they are."""

import os

import numpy as np
import pytest

from pickplan.core.errors import InputError
from pickplan.core.shapes import ShapeKind
from pickplan.sim import moveit
from pickplan.sim.scenes import Scene

from conftest import mbm_dir_or_skip

S = float(np.sqrt(0.5))

YAML = """
name: kitchen
robot_state:
  joint_state:
    name: [panda_joint1, panda_joint2]
    position: [0.1, -0.2]
allowed_collision_matrix:
  entry_names: [a, b, c]
  entry_values:
    - [false, true, false]
    - [true, false, false]
    - [false, false, false]
world:
  collision_objects:
    - id: board
      primitives:
        - type: box
          dimensions: [1.2, 0.4, 0.02]
      primitive_poses:
        - position: [0.5, 0.0, 0.3]
          orientation: [0, 0, %(s)r, %(s)r]
    - id: can
      header: {frame_id: world}
      pose:
        position: {x: 1.0, y: 2.0, z: 0.0}
        orientation: {x: 0.0, y: 0.0, z: 1.0, w: 0.0}
      primitives:
        - type: 3
          dimensions: [0.14, 0.03]
        - {type: sphere, dimensions: [0.05]}
      primitive_poses:
        - position: {x: 0.1, y: 0.0, z: 0.07}
          orientation: {x: 0, y: 0, z: 0, w: 1}
        - position: [0.0, 0.0, 0.2]
          orientation: [0, 0, 0, 1]
""" % {"s": S}


def test_planning_scene_yaml_gives_hand_computed_primitives_and_poses(tmp_path):
    path = tmp_path / "kitchen.yaml"
    path.write_text(YAML)
    ms = moveit.read_moveit_scene(str(path))
    assert ms.name == "kitchen"
    assert [o.name for o in ms.obstacles] == ["board", "can/0", "can/1"]
    board, can, ball = ms.obstacles
    assert board.shape.kind is ShapeKind.box and board.shape.size == (1.2, 0.4, 0.02)
    # 90 degrees about z: the board's x axis along world y
    np.testing.assert_allclose(board.pose[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(board.pose[:3, 3], [0.5, 0.0, 0.3])
    # MoveIt's cylinder dimensions are [height, radius]; the primitive pose is relative to the object's
    # pose (a half turn about z at (1, 2, 0)): (0.1, 0, 0.07) lands at (0.9, 2, 0.07)
    assert can.shape.kind is ShapeKind.cylinder and can.shape.size == (0.03, 0.14)
    np.testing.assert_allclose(can.pose[:3, 3], [0.9, 2.0, 0.07], atol=1e-12)
    np.testing.assert_allclose(can.pose[:3, :3], np.diag([-1, -1, 1]), atol=1e-12)
    assert ball.shape.kind is ShapeKind.sphere and ball.shape.size == (0.05,)
    np.testing.assert_allclose(ball.pose[:3, 3], [1.0, 2.0, 0.2], atol=1e-12)
    assert ms.joint_state == {"panda_joint1": 0.1, "panda_joint2": -0.2}
    assert ms.allowed_collisions == (("a", "b"),)
    # into the scene model: a JSON round trip keeps every obstacle
    scene = ms.to_scene()
    assert scene.table is None and scene.target is None
    again = Scene.from_json(scene.to_json())
    assert [o.name for o in again.obstacles] == ["board", "can/0", "can/1"]
    np.testing.assert_array_equal(again.obstacles[1].pose, can.pose)
    assert again.obstacles[1].shape == can.shape


NEW_FORMAT = """shelf scene
* shelf
0.5 0 0
0 0 0 1
2
box
1.0 0.4 0.02
0 0 0.3
0 0 0 1
0 0 0 0
cylinder
0.03 0.14
0.1 0 0.37
0 0 %(s)r %(s)r
0 0 0 0
0
* ball
0 0 1
0 0 0 1
1
sphere
0.04
0 0.2 0
0 0 0 1
1 0 0 1
1
grip
0 0 0.04
0 0 0 1
.
""" % {"s": S}

OLD_FORMAT = """old
* crate
1
box
0.2 0.3 0.4
1 2 3
0 0 0 1
0.5 0.5 0.5 1
.
"""


def test_scene_text_in_both_formats(tmp_path):
    path = tmp_path / "shelf.scene"
    path.write_text(NEW_FORMAT)
    ms = moveit.read_moveit_scene(str(path))
    assert ms.name == "shelf scene"
    assert [o.name for o in ms.obstacles] == ["shelf/0", "shelf/1", "ball"]
    board, can, ball = ms.obstacles
    assert board.shape.size == (1.0, 0.4, 0.02)
    np.testing.assert_allclose(board.pose[:3, 3], [0.5, 0.0, 0.3])
    assert can.shape.kind is ShapeKind.cylinder and can.shape.size == (0.03, 0.14)  # text: radius, length
    np.testing.assert_allclose(can.pose[:3, 3], [0.6, 0.0, 0.37])
    np.testing.assert_allclose(can.pose[:3, :3], [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(ball.pose[:3, 3], [0.0, 0.2, 1.0])
    old = tmp_path / "old.scene"
    old.write_text(OLD_FORMAT)
    crate = moveit.read_moveit_scene(str(old)).obstacles[0]
    assert crate.name == "crate" and crate.shape.size == (0.2, 0.3, 0.4)
    np.testing.assert_allclose(crate.pose[:3, 3], [1, 2, 3])


@pytest.mark.parametrize(
    "text, field",
    [
        (
            YAML.replace("dimensions: [1.2, 0.4, 0.02]", "dimensions: [1.2, 0.4]"),
            "world.collision_objects[0].primitives[0].dimensions",
        ),
        (
            YAML.replace("dimensions: [0.14, 0.03]", "dimensions: [0.14, -0.03]"),
            "world.collision_objects[1].primitives[0].dimensions",
        ),
        (YAML.replace("type: box", "type: cone"), "world.collision_objects[0].primitives[0].type"),
        (
            YAML.replace("orientation: {x: 0, y: 0, z: 0, w: 1}", "orientation: {x: 0, y: 0, z: 0, w: 3}"),
            "world.collision_objects[1].primitive_poses[0].orientation",
        ),
        (
            YAML.replace("position: [0.0, 0.0, 0.2]", "position: [0.0, zero, 0.2]"),
            "world.collision_objects[1].primitive_poses[1].position[1]",
        ),
        (YAML.replace("    - id: can\n", "    - name: can\n"), "world.collision_objects[1].id"),
        (YAML.replace("    - [false, false, false]\n", ""), "allowed_collision_matrix.entry_values"),
    ],
)
def test_malformed_yaml_names_file_and_field(tmp_path, text, field):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        moveit.read_moveit_scene(str(path))
    assert err.value.field == field and err.value.path == str(path)
    assert str(path) in str(err.value) and field in str(err.value)


def test_malformed_scene_text_names_the_line(tmp_path):
    path = tmp_path / "bad.scene"
    path.write_text(NEW_FORMAT.replace("1.0 0.4 0.02", "1.0 wide 0.02"))
    with pytest.raises(InputError, match=r"bad.scene: line 7") as err:
        moveit.read_moveit_scene(str(path))
    assert "shelf" in str(err.value)
    path.write_text(NEW_FORMAT.replace("sphere", "cone"))
    with pytest.raises(InputError, match="cone"):
        moveit.read_moveit_scene(str(path))
    path.write_text(NEW_FORMAT[:-3])  # no "." at the end
    with pytest.raises(InputError, match="file ends"):
        moveit.read_moveit_scene(str(path))
    with pytest.raises(InputError, match="malformed YAML"):
        moveit.parse_planning_scene(moveit._yaml("world: [", "x.yaml"))


def test_motionbenchmaker_files_load_without_edits():
    from pickplan.eval.mbm import SETS, read_problems

    root = mbm_dir_or_skip()
    # One set of the five (reading all 500 takes half a minute; `bench mbm` reads them all)
    problems = list(read_problems(os.path.join(root, "problems_panda.tar.bz2"), SETS[:1]))
    assert len(problems) == 100 and {p.set for p in problems} == {"bookshelf_small_panda"}
    by = {(p.set, p.index): p for p in problems}
    p = by[("bookshelf_small_panda", 1)]
    names = [o.name for o in p.scene.obstacles]
    assert names == ["Can1", "Can2", "Can3", "shelf_bottom", "shelf_top", "side_left", "side_right"]
    can = p.scene.obstacles[0]
    assert can.shape.kind is ShapeKind.cylinder and can.shape.size == (0.03, 0.14)
    np.testing.assert_allclose(can.pose[:3, 3], [0.2477726773362563, -1.073506349336661, 0.2979866994332424])
    angle = 2 * np.arctan2(-0.5233762232815127, 0.8521017127688338)  # the quaternion's turn about z
    np.testing.assert_allclose(can.pose[:2, 0], [np.cos(angle), np.sin(angle)], atol=1e-12)
    assert p.request.start["panda_joint4"] == -2.356 and p.request.goal["panda_joint1"] == 1.48904932702624
    assert len(p.scene.allowed_collisions) > 0
    assert {o.shape.kind for p in problems for o in p.scene.obstacles} == {ShapeKind.box, ShapeKind.cylinder}
    srdf = moveit.read_srdf_disabled(os.path.join(root, "panda", "panda.srdf"))
    assert ("panda_link0", "panda_link1") in srdf or ("panda_link1", "panda_link0") in srdf


def test_bench_mbm_plans_and_checks_two_problems(tmp_path):
    """``bench mbm`` end to end on two box problems: our paths pass the independent checker, every path
    is no shorter than the straight line in joint space; runs.csv has a row per problem and planner."""
    from pickplan.eval.mbm import MbmSettings, read_problems, run_mbm

    archive = os.path.join(mbm_dir_or_skip(), "problems_panda.tar.bz2")
    settings = MbmSettings(
        problems=archive,
        sets=("box_panda",),
        planners=("pickplan", "ompl"),
        limit=3,
        out=str(tmp_path),
        progress=False,
        time_limit=5.0,
    )
    rows = run_mbm(settings)
    assert [(r["problem"], r["planner"]) for r in rows] == [(1, "pickplan"), (1, "ompl"), (2, "pickplan"), (2, "ompl")]
    assert all(r["solved"] for r in rows)
    # ours pass the checker; OMPL's may not (it checks states 0.5 % of the space apart: corners get cut),
    # and a rejected path names the state and the bodies
    assert all(r["success"] and r["min_clearance"] >= 0 for r in rows if r["planner"] == "pickplan")
    assert all(r["success"] or " with " in r["checker"] for r in rows)
    problems = {p.index: p for p in read_problems(archive, ("box_panda",), limit=3)}
    for r in rows:
        goal = problems[r["problem"]].request.goal
        assert r["path_length"] >= 0.999 * np.linalg.norm(
            [goal[j] - problems[r["problem"]].request.start[j] for j in goal]
        )  # no shorter than the straight line
    text = (tmp_path / "runs.csv").read_text().splitlines()
    assert len(text) == 5 and text[0].startswith("set,problem,planner,solved,valid,success")
    assert "| box_panda | pickplan | 100.0 % (2/2)" in (tmp_path / "summary.md").read_text()
