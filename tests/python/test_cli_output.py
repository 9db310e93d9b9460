"""What the command line shows: pickplan's own output only (no PyBullet banner, from a fresh
process where PyBullet is imported for the first time), the library's notes on the ``pickplan``
logger shown by default and hidden by ``--quiet``, and ``-q`` / ``-v`` before or after the command."""

import logging
import os
import subprocess
import sys

import numpy as np
import pytest

from pickplan.cli.main import build_parser, main
from pickplan.cli.output import level_of

BANNER = "pybullet build time"


def _cli(*argv, cwd):
    return subprocess.run(
        [sys.executable, "-m", "pickplan.cli", *argv], capture_output=True, text=True, cwd=cwd, timeout=600
    )


def test_commands_that_run_pybullet_show_no_banner_and_observe_writes_its_views(tmp_path):
    scenes = _cli("scenes", "--n", "1", "--seed", "3", "--out", str(tmp_path / "scenes"), cwd=tmp_path)
    assert scenes.returncode == 0, scenes.stderr
    assert scenes.stdout.startswith("wrote 1 scenes to")
    obs_path = tmp_path / "obs.npz"
    observe = _cli(
        "observe",
        "--scene",
        str(tmp_path / "scenes" / "scene_0000.json"),
        "--views",
        "2",
        "--out",
        str(obs_path),
        cwd=tmp_path,
    )
    assert observe.returncode == 0, observe.stderr
    for run in (scenes, observe):
        assert BANNER not in run.stdout and BANNER not in run.stderr
    assert observe.stdout.startswith(f"wrote {obs_path}: 2 view(s) of 640 x 480")
    # what observe wrote: two depth views of the scene; back-projected, the pixels with a return lie
    # on the table top (z = 0) or on the objects above it, and the target's on the target
    from pickplan.core.observation import Observation
    from pickplan.sim.scenes import Scene

    obs = Observation.load(str(obs_path))
    scene = Scene.load(str(tmp_path / "scenes" / "scene_0000.json"))
    assert obs.views == 2 and obs.depth.shape == (2, 480, 640)
    for v in range(2):
        rows, cols = np.nonzero(obs.depth[v] > 0)
        assert len(rows) > 0.3 * obs.depth[v].size
        d = obs.depth[v][rows, cols].astype(float)
        K = obs.K[v]
        cam = np.column_stack([(cols + 0.5 - K[0, 2]) / K[0, 0] * d, (rows + 0.5 - K[1, 2]) / K[1, 1] * d, d])
        world = cam @ obs.camera_pose[v][:3, :3].T + obs.camera_pose[v][:3, 3]
        assert world[:, 2].min() > -0.005 and np.mean(np.abs(world[:, 2]) < 0.003) > 0.3
        target = world[obs.target_mask[v][rows, cols]]
        centre = scene.object(scene.target).pose[:3, 3]
        assert len(target) > 100 and np.abs(target[:, :2] - centre[:2]).max() < 0.15


def test_quiet_hides_the_library_notes_and_verbose_shows_its_details(capsys):
    note = logging.getLogger("pickplan.tests.note")
    for argv, info, debug in (
        (["robots", "list"], True, False),
        (["-q", "robots", "list"], False, False),
        (["robots", "list", "--quiet"], False, False),
        (["robots", "-v", "list"], True, True),
    ):
        assert main(argv) == 0
        capsys.readouterr()
        note.info("an info note")
        note.debug("a debug note")
        err = capsys.readouterr().err
        assert ("an info note" in err) == info and ("a debug note" in err) == debug, argv
    main(["robots", "list"])  # leave the default level for the tests after this one


@pytest.mark.parametrize(
    "argv, level",
    [
        (["demo"], logging.INFO),
        (["-q", "demo"], logging.WARNING),
        (["demo", "--quiet"], logging.WARNING),
        (["-v", "demo"], logging.DEBUG),
        (["plan", "-v", "--scene", "s.json"], logging.DEBUG),
        (["bench", "planners", "-q", "--quick"], logging.WARNING),
        (["metamodel", "build", "--quiet"], logging.WARNING),
    ],
)
def test_verbosity_flags_stand_before_or_after_the_command(argv, level):
    assert level_of(build_parser().parse_args(argv)) == level


def test_quiet_and_verbose_together_are_a_usage_error(capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser().parse_args(["demo", "-q", "-v"])
    assert exc.value.code == 2


def test_the_library_prints_nothing_it_only_logs():
    """No ``print`` in library code outside the command line (the architecture's rule for output)."""
    import ast

    import pickplan

    root = os.path.dirname(pickplan.__file__)
    found = []
    for dirpath, _, files in os.walk(root):
        if os.path.relpath(dirpath, root).split(os.sep)[0] == "cli":
            continue
        for name in files:
            if name.endswith(".py"):
                path = os.path.join(dirpath, name)
                for node in ast.walk(ast.parse(open(path).read())):
                    if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "print":
                        found.append(f"{os.path.relpath(path, root)}:{node.lineno}")
    assert not found, f"print() in library code: {found}"
