"""Exit codes mean one thing each (cli/exit_codes.py): 0 success, 1 ran but no plan, 2 bad input
with a message naming the file or option, 3 internal error; never a bare traceback."""

import json
import socket
import types

import pytest

import importlib

from pickplan.cli import exit_codes
from pickplan.cli.exit_codes import ExitCode
from pickplan.sim import scenes

cli = importlib.import_module("pickplan.cli.main")  # the package re-exports main() under the same name


@pytest.fixture(scope="module")
def scene_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("scene") / "scene.json"
    scenes.generate_scene(seed=2).save(str(path))
    return path


def _run(capsys, argv):
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, err


def test_robot_configuration_of_5_exits_bad_input_naming_file_and_field(capsys, scene_file, tmp_path):
    d = json.loads(scene_file.read_text())
    d["robot_configuration"] = 5
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(d))
    code, err = _run(capsys, ["plan", "--scene", str(bad)])
    assert code == ExitCode.BAD_INPUT == 2
    assert f"{bad}: robot_configuration: expected a list of joint values, got int 5" in err


def test_deeply_nested_json_exits_bad_input(capsys, tmp_path):
    deep = tmp_path / "deep.json"
    deep.write_text('{"a": ' * 50_000 + "1" + "}" * 50_000)
    code, err = _run(capsys, ["plan", "--scene", str(deep)])
    assert code == 2 and "deep.json" in err and "nested too deeply" in err


def test_out_naming_a_file_exits_bad_input(capsys, scene_file, tmp_path):
    taken = tmp_path / "taken"
    taken.write_text("x")
    for argv in (
        ["plan", "--scene", str(scene_file), "--out", str(taken)],
        ["scenes", "--n", "1", "--out", str(taken)],
        ["bench", "planners", "--quick", "--out", str(taken)],
    ):
        code, err = _run(capsys, argv)
        assert code == 2, argv
        assert f"--out: '{taken}' is a file; expected a folder" in err


def test_metamodel_naming_a_folder_exits_bad_input(capsys, tmp_path):
    code, err = _run(capsys, ["pickup", "cases", "--metamodel", str(tmp_path), "--out", str(tmp_path / "o")])
    assert code == 2 and f"--metamodel: '{tmp_path}' is a folder; expected a file" in err


def test_metamodel_with_nan_sigma_r_exits_bad_input(capsys, tmp_path):
    from test_reliability import _metamodel

    d = _metamodel()
    d["levels"][0]["sigma_r"] = float("nan")
    path = tmp_path / "mm.json"
    path.write_text(json.dumps(d))
    code, err = _run(capsys, ["pickup", "cases", "--metamodel", str(path), "--out", str(tmp_path / "o")])
    assert code == 2 and f"{path}: levels[0].sigma_r: expected a finite number, got nan" in err


def test_bad_ray_address_exits_bad_input_without_waiting_for_ray(capsys, tmp_path):
    code, err = _run(capsys, ["bench", "planners", "--quick", "--ray", "not an address", "--out", str(tmp_path)])
    assert code == 2 and "--ray: expected 'local', 'auto' or HOST:PORT, got 'not an address'" in err
    with socket.socket() as s:  # a loopback port that nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    code, err = _run(capsys, ["bench", "planners", "--quick", "--ray", f"127.0.0.1:{port}", "--out", str(tmp_path)])
    assert code == 2 and f"--ray: no Ray cluster answers at 127.0.0.1:{port}" in err


def test_plan_exits_ok_on_success_and_no_plan_otherwise(capsys, scene_file, tmp_path):
    """Each exit code is asked for, not whichever came: the seeded scene plans (exit 0); with its
    target moved to the table's far corner, out of the arm's reach, no grasp gives a goal (exit 1)."""
    far = json.loads(scene_file.read_text())
    target = next(o for o in far["objects"] if o["name"] == far["target"])
    target["pose"][0][3], target["pose"][1][3] = 1.02, 0.72  # 1.25 m from the base; the Panda reaches 0.85 m
    (tmp_path / "far.json").write_text(json.dumps(far))
    for scene, out, code_wanted, status_wanted in (
        (scene_file, tmp_path / "ok", ExitCode.OK, "success"),
        (tmp_path / "far.json", tmp_path / "far", ExitCode.NO_PLAN, "no_goals"),
    ):
        code, _ = _run(capsys, ["plan", "--scene", str(scene), "--grasps", "antipodal", "--out", str(out)])
        assert code == code_wanted
        assert json.loads((out / "plan.json").read_text())["status"] == status_wanted


def test_internal_errors_exit_3_with_one_line_not_a_traceback(capsys, monkeypatch):
    def broken(args):
        raise TypeError("unsupported operand")

    code = exit_codes.run_command("plan", broken, types.SimpleNamespace())
    err = capsys.readouterr().err
    assert code == ExitCode.INTERNAL_ERROR == 3
    assert "internal error (TypeError: unsupported operand); this is a bug" in err and "Traceback" not in err


def test_exit_codes_are_documented_in_the_readme():
    import os

    readme = open(os.path.join(os.path.dirname(__file__), "..", "..", "README.md")).read()
    for code in ExitCode:
        assert f"| {code.value} |" in readme, code
