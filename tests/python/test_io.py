"""The one atomic writer (pickplan.core.io): complete files or none, readable results, the folder made."""

import json
import os

import pytest

from pickplan.core import io


def test_writers_round_trip_into_a_new_folder(tmp_path):
    io.write_json(str(tmp_path / "a" / "b.json"), {"z": 1, "a": [1.5]})
    assert json.loads((tmp_path / "a" / "b.json").read_text()) == {"z": 1, "a": [1.5]}
    io.write_text(str(tmp_path / "t.md"), "rho \u03c1\n")
    assert (tmp_path / "t.md").read_bytes() == "rho \u03c1\n".encode("utf-8")
    io.write_bytes(str(tmp_path / "b.bin"), b"\x00\xff")
    assert (tmp_path / "b.bin").read_bytes() == b"\x00\xff"
    assert os.stat(tmp_path / "b.bin").st_mode & 0o777 == 0o644  # not mkstemp's owner-only mode


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path):
    path = tmp_path / "r.json"
    io.write_text(str(path), "old")
    os.chmod(path, 0o600)
    with pytest.raises(RuntimeError):
        with io.atomic_open(str(path)) as f:
            f.write("half")
            raise RuntimeError("interrupted")
    assert path.read_text() == "old" and os.listdir(tmp_path) == ["r.json"]
    io.write_text(str(path), "new")
    assert path.read_text() == "new" and os.stat(path).st_mode & 0o777 == 0o600  # the mode it had
