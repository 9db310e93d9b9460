"""Depth observations at the door (issue 39): corrupt archives, wrong containers and versions,
masks that are not boolean, intrinsics no camera has, NaN colours and a target pixel of the wrong
length are InputErrors naming the file and the field (exit 2), never an internal error or a plan
on garbage. Each case here was an internal error (exit 3), accepted, or named no file before."""

import numpy as np
import pytest

from pickplan.cli.main import main as cli_main
from pickplan.core.errors import InputError
from pickplan.core.observation import Observation
from pickplan.perception.field import perceive
from pickplan.sim.observe import CameraRig, render_observation

from conftest import known_scene

RIG = CameraRig(width=160, height=120)


@pytest.fixture(scope="module")
def fields():
    """The arrays of a valid one-view observation, as Observation.save writes them."""
    scene, _ = known_scene()
    obs = render_observation(scene, views=1, rig=RIG)
    return {
        "depth": obs.depth,
        "K": obs.K,
        "camera_pose": obs.camera_pose,
        "target_mask": obs.target_mask.astype(np.uint8),
        "rgb": obs.rgb,
        "format": np.array("pickplan.observation"),
        "version": np.array(1),
    }


def _write(tmp_path, arrays, name="obs.npz"):
    path = tmp_path / name
    with open(path, "wb") as f:
        np.savez_compressed(f, **{k: v for k, v in arrays.items() if v is not None})
    return str(path)


def _changed(fields, **changes):
    out = {k: np.array(v, copy=True) if isinstance(v, np.ndarray) else v for k, v in fields.items()}
    out.update(changes)
    return out


def _entry(f, key, index, value):
    """``{key: f[key] with f[key][index] = value}``."""
    a = np.array(f[key], dtype=float)
    a[index] = value
    return {key: a}


def _refused(path, field, words, capsys=None):
    with pytest.raises(InputError) as err:
        Observation.load(path)
    assert err.value.path == path and err.value.field == field and words in str(err.value), str(err.value)
    if capsys is not None:  # the command line: exit 2, the file and the field named
        capsys.readouterr()
        assert cli_main(["plan", "--observation", path]) == 2
        err_text = capsys.readouterr().err
        assert f"{path}: " in err_text and "internal error" not in err_text, err_text


def test_the_valid_observation_loads(fields, tmp_path):
    obs = Observation.load(_write(tmp_path, fields))
    assert obs.views == 1 and obs.target_mask.dtype == bool and obs.rgb.dtype == np.uint8


def test_a_truncated_or_bit_flipped_archive_is_named(fields, tmp_path, capsys):
    """Was BadZipFile / zlib.error: exit 3."""
    data = open(_write(tmp_path, fields), "rb").read()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(data[: len(data) // 2])
    _refused(str(truncated), None, "not a readable .npz observation", capsys)
    flipped = bytearray(data)
    for i in range(len(data) // 4, len(data) // 2, 97):
        flipped[i] ^= 0xFF
    path = tmp_path / "flipped.npz"
    path.write_bytes(bytes(flipped))
    _refused(str(path), None, "not a readable .npz observation", capsys)


def test_a_npy_renamed_npz_is_named(tmp_path, capsys):
    """Was a TypeError: exit 3."""
    path = tmp_path / "array.npz"
    with open(path, "wb") as f:
        np.save(f, np.zeros((4, 4)))
    _refused(str(path), None, "a single .npy array, not an .npz archive", capsys)


@pytest.mark.parametrize(
    "change, field, words",
    [
        (lambda f: _entry(f, "K", (0, 0, 0), 1e-300), "K", "fx = 1e-300 px gives a field of view"),  # an IndexError
        (lambda f: _entry(f, "K", (0, 0, 1), 1e9), "K", "skew 1e+09 px"),  # it planned
        (lambda f: {"K": f["K"].astype(str)}, "K", "expected numbers, got an array of <U"),  # named no file
        (
            lambda f: {"target_mask": np.full(f["depth"].shape, np.nan)},
            "target_mask",
            "expected booleans or 0/1 integers, got an array of float64",
        ),  # was "everything is the target"
        (lambda f: {"target_mask": 2 * f["target_mask"]}, "target_mask", "expected 0 or 1, got values 0..2"),
        (lambda f: {"rgb": np.full(f["rgb"].shape, np.nan)}, "rgb", "expected colours in 0..255"),  # cast silently
        (lambda f: {"version": np.array(2)}, "version", "reads observation version 1, got 2"),  # not checked
        (lambda f: {"version": None}, "version", "missing"),
        (
            lambda f: {"target_mask": None, "target_pixel": np.array([60, 80, 5])},
            "target_pixel",
            "one (row, col) pair per view: shape (1, 2), got (3,)",
        ),  # "cannot reshape array of size 3"
        (
            lambda f: {"target_mask": None, "target_pixel": np.array([[60.5, 80.0]])},
            "target_pixel",
            "expected numbers, got an array of float64",
        ),
        (lambda f: {"depth": np.full(f["depth"].shape, 1e30, np.float32)}, "depth", "more than a depth camera's"),
        (lambda f: _entry(f, "camera_pose", (0, 2, 3), 1e6), "camera_pose", "m from the robot base"),
    ],
)
def test_bad_fields_are_named(fields, tmp_path, capsys, change, field, words):
    _refused(_write(tmp_path, _changed(fields, **change(fields))), field, words, capsys)


def test_no_table_in_view_names_the_observation(fields, tmp_path, capsys):
    """Was "support plane: no near-horizontal plane in the points" naming no input."""
    tilt = np.eye(4)
    tilt[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # the world turned 90 degrees: the table stands upright
    path = _write(tmp_path, _changed(fields, camera_pose=tilt @ fields["camera_pose"]))
    with pytest.raises(InputError) as err:
        perceive(Observation.load(path))
    assert err.value.path == path and err.value.field == "depth" and "no near-horizontal plane" in str(err.value)
    assert cli_main(["plan", "--observation", path]) == 2
    assert f"{path}: depth: support plane: no near-horizontal plane" in capsys.readouterr().err


def test_every_problem_of_an_observation_is_named_at_once(fields, tmp_path):
    bad = _changed(
        fields, K=fields["K"] * 1e-300, target_mask=fields["target_mask"] * 3.0, rgb=np.full(fields["rgb"].shape, -1)
    )
    with pytest.raises(InputError) as err:
        Observation.load(_write(tmp_path, bad))
    assert [p.field for p in err.value.problems] == ["K", "target_mask", "rgb"], str(err.value)
