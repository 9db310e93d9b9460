"""The cache entries pickplan ships (assets/cache, core.io.cache_entry, omg.shipped): read only when their
SHA-256 matches the manifest, never when made by another generator version, and equal to what the
generator makes now (re-simulated on a sample of one small object)."""

import os
import shutil
import warnings

import numpy as np
import pytest

from pickplan.core import io, objects
from pickplan.omg import shipped
from pickplan.omg.grasps import grasp_set, physics, simulated

SMALL = "005_tomato_soup_can"  # its default set: the first round's candidates but one


def _shipped_folder(tmp_path, files: dict, labels: dict = None) -> str:
    folder = tmp_path / "shipped"
    entries = {}
    for rel, data in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)
        entries[rel] = {"sha256": io.file_sha256(str(path)), "label": (labels or {}).get(rel, "")}
    io.write_json(str(folder / io.SHIPPED_MANIFEST), {"format": io.SHIPPED_FORMAT, "entries": entries})
    return str(folder)


def test_cache_entry_reads_a_shipped_copy_only_when_its_checksum_matches(tmp_path, monkeypatch):
    monkeypatch.setenv(io.CACHE_ENV, str(tmp_path / "user"))
    folder = _shipped_folder(
        tmp_path, {"grasps/a.npz": b"grasps of a", "grasps/b.npz": b"grasps of b"}, {"grasps/b.npz": "b / panda"}
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert io.cache_entry("grasps", "a.npz", shipped=folder) == os.path.join(folder, "grasps", "a.npz")
        assert io.cache_entry("grasps", "c.npz", label="c / panda", shipped=folder) is None  # not shipped: compute
        assert io.cache_entry("grasps", "a.npz", shipped=str(tmp_path / "none")) is None  # no manifest
    # one flipped byte: not used, and said so
    path = os.path.join(folder, "grasps", "a.npz")
    with open(path, "r+b") as f:
        f.write(b"G")
    with pytest.warns(UserWarning, match="checksum mismatch"):
        assert io.cache_entry("grasps", "a.npz", shipped=folder) is None
    os.unlink(path)
    with pytest.warns(UserWarning, match="missing or checksum mismatch"):
        assert io.cache_entry("grasps", "a.npz", shipped=folder) is None
    # the same object's entry under another name: another generator version made it
    with pytest.warns(UserWarning, match="another version of its generator"):
        assert io.cache_entry("grasps", "b2.npz", label="b / panda", shipped=folder) is None
    # the user's own entry comes first
    io.write_bytes(io.cache_dir("grasps", "a.npz"), b"mine")
    assert io.cache_entry("grasps", "a.npz", shipped=folder) == io.cache_dir("grasps", "a.npz")


def test_a_malformed_manifest_is_an_input_error(tmp_path):
    (tmp_path / io.SHIPPED_MANIFEST).write_text('{"format": 99, "entries": {}}')
    with pytest.raises(ValueError, match="manifest.json.*format"):
        io.read_manifest(str(tmp_path))


def test_every_builtin_default_grasp_set_ships_under_the_name_this_version_asks_for():
    """A change to the shake test's settings, the candidates' settings, a mesh or CACHE_VERSION renames
    the entries: this fails until `make builtin-cache` is run again."""
    entries = io.read_manifest(io.shipped_dir())
    wanted = shipped.grasp_entries()
    assert len(wanted) == len(objects.library("builtin").names) * len(shipped.SHIPPED_ROBOTS)
    missing = [rel for _, rel, _, _ in wanted if rel not in entries]
    assert not missing, f"stale shipped cache (run `make builtin-cache`): {missing}"
    for _, rel, label, _ in wanted:
        assert io.file_sha256(os.path.join(io.shipped_dir(), rel)) == entries[rel]["sha256"]
        assert entries[rel]["label"] == label
    assert len(entries) == len(wanted)  # nothing shipped that no one reads


def test_shipped_grasps_are_what_the_generator_makes_now():
    """The shipped set of one object against the generator run again on a sample: its poses are the
    round's candidates that held, in order (to rounding); two of them hold again in the shake test with
    the same drift (its score, to 0.05: 1 mm) and the candidates it left out (at most two) fail."""
    model = objects.library("builtin").get(SMALL)
    ((_, rel, _, gripper),) = shipped.grasp_entries([SMALL])
    gs = simulated.read_grasp_file(os.path.join(io.shipped_dir(), rel), SMALL)
    cand, seeds = physics.shake_candidates(model, int(np.ceil(len(gs.poses) * 3.0)), 0, 0, gripper=gripper)
    flat = cand.poses.reshape(len(cand), -1)
    # the same poses to rounding (numpy and trimesh releases differ in the last bit of a few of them)
    gaps = np.abs(flat[None, :, :] - gs.poses.reshape(len(gs.poses), 1, -1)).max(axis=2)
    idx = [int(i) for i in gaps.argmin(axis=1)]
    assert gaps[np.arange(len(idx)), idx].max() < 1e-9
    assert idx == sorted(idx)
    left_out = [i for i in range(idx[-1]) if i not in set(idx)][:2]
    assert left_out
    obj, settings = physics.SimObject(model), physics.SimSettings()
    for k in (0, len(idx) // 2):
        r = physics.shake_test(obj, cand.poses[idx[k]], seeds[idx[k]], settings, gripper)
        # held again, with the drift it had to a millimetre (a score of 0.05): the candidates agree to rounding,
        # and the simulator carries a last-bit difference in a pose through its contacts (0.5 mm seen)
        assert r["held"] and 1.0 - r["drift"] / settings.max_drift == pytest.approx(gs.scores[k], abs=0.05)
    for i in left_out:
        assert not physics.shake_test(obj, cand.poses[i], seeds[i], settings, gripper)["held"]


def test_the_planner_default_grasps_of_a_builtin_object_come_from_the_shipped_copy(tmp_path, monkeypatch):
    monkeypatch.setenv(io.CACHE_ENV, str(tmp_path / "user"))
    model = objects.library("builtin").get(SMALL)
    ((_, rel, _, _),) = shipped.grasp_entries([SMALL])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        gs = grasp_set(model, "simulated", 100, seed=0)
    assert np.array_equal(gs.poses, simulated.read_grasp_file(os.path.join(io.shipped_dir(), rel), SMALL).poses)
    assert not os.path.exists(tmp_path / "user")  # read in place, not copied


def test_a_new_generator_version_is_said_and_another_request_is_not(tmp_path, monkeypatch):
    """Only a request the shipped data answers, made by another version of the generator, warns (then the
    set is simulated again); any other request (another count or seed) is simply not shipped."""
    monkeypatch.setenv(io.CACHE_ENV, str(tmp_path / "user"))
    model = objects.library("builtin").get(SMALL)
    other = (model, 3, 5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert (
            io.cache_entry(simulated.CACHE_FOLDER, simulated.cache_name(*other), label=simulated.entry_label(*other))
            is None
        )
    monkeypatch.setattr(simulated, "CACHE_VERSION", simulated.CACHE_VERSION + 1)
    shipped_request = (model, 100, 0)
    with pytest.warns(UserWarning, match="another version of its generator"):
        assert (
            io.cache_entry(
                simulated.CACHE_FOLDER,
                simulated.cache_name(*shipped_request),
                label=simulated.entry_label(*shipped_request),
            )
            is None
        )


def test_a_regenerated_entry_replaces_the_objects_old_one_in_the_manifest(tmp_path, monkeypatch):
    """``shipped.build`` drops an object's entry of an older name, also one made for a request whose
    settings have since changed (another label); (simulation stubbed: the real one is the test above)."""
    folder = tmp_path / "cache"
    shutil.copytree(io.shipped_dir(), folder)
    ((_, rel, _, _),) = shipped.grasp_entries([SMALL])
    old = "grasps/" + SMALL + "-simulated-000000000000000000000000.npz"
    os.rename(folder / rel, folder / old)
    entries = io.read_manifest(str(folder))
    entries[old] = entries.pop(rel)
    owner = entries[old]["label"].rsplit(" / ", 1)[0]
    entries[old] = dict(entries[old], label=owner + " / 000000000000")
    io.write_json(str(folder / io.SHIPPED_MANIFEST), {"format": io.SHIPPED_FORMAT, "entries": entries})
    stored = simulated.read_grasp_file(str(folder / old), SMALL)
    monkeypatch.setattr(simulated, "simulated_grasps", lambda *a, **k: stored)
    out = shipped.build(str(folder), [SMALL])
    assert rel in out and old not in out and not (folder / old).exists()
    assert io.read_manifest(str(folder)) == out
