"""Sweeps under faults (issue 26): a real `pickplan bench` run SIGKILLed as a whole process group and
resumed, a Ray worker killed mid-task, and a resume that would mix two sweeps' units.

The truth each run is held to is an uninterrupted run of the same units: the same per-unit results,
the same table, every unit exactly once."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from pickplan.core.errors import InputError
from pickplan.eval import experiments as E
from pickplan.eval.summaries import summarize

METHODS = ("Fixed", "MD")
KILL_AFTER_UNITS = 1  # unit files on disk before the kill; a run has len(METHODS) * scenes units
DEADLINE_S = 45.0  # one bench run; a slower one is a hang, not a result


@pytest.fixture(scope="module")
def scene_dir(tmp_path_factory):
    """Two generated scenes (built-in objects), shared by the tests."""
    out = str(tmp_path_factory.mktemp("fault_scenes"))
    E.scene_files(E.SweepSettings("selection", out=out, scenes=2, workers=0, progress=False))
    return os.path.join(out, "scenes")


def _settings(scene_dir, out, **changes):
    return E.SweepSettings(
        **{
            **dict(
                table="selection",
                out=str(out),
                scene_dir=scene_dir,
                runs=1,
                methods=METHODS,
                quick=True,
                workers=2,
                execute=False,
                progress=False,
            ),
            **changes,
        }
    )


@pytest.fixture(scope="module")
def reference(scene_dir, tmp_path_factory):
    """The uninterrupted sweep's records, run serially in this process."""
    out = tmp_path_factory.mktemp("reference")
    return E.run_sweep(_settings(scene_dir, out, workers=0))


def _bench_command(scene_dir, out, *extra):
    return [
        sys.executable,
        "-m",
        "pickplan",
        "bench",
        "selection",
        "--quick",
        "--scene-dir",
        scene_dir,
        "--methods",
        *METHODS,
        "--workers",
        "2",
        "--no-execute",
        "--no-progress",
        "--out",
        str(out),
        *extra,
    ]


def _start(command):
    """The command in a process group of its own (its workers and Ray's processes join it)."""
    return subprocess.Popen(command, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def _unit_files(out):
    folder = os.path.join(out, "units")
    if not os.path.isdir(folder):
        return []
    return sorted(f for f in os.listdir(folder) if f.endswith(".json") and not f.startswith("."))


def _wait_for(predicate, proc, what):
    start = time.monotonic()
    while not predicate():
        if proc.poll() is not None:
            pytest.fail(f"the sweep exited ({proc.returncode}) before {what}:\n{proc.stdout.read().decode()}")
        if time.monotonic() - start > DEADLINE_S:
            os.killpg(proc.pid, signal.SIGKILL)
            pytest.fail(f"no {what} after {DEADLINE_S:.0f} s")
        time.sleep(0.02)


def _finish(proc):
    try:
        output = proc.communicate(timeout=DEADLINE_S)[0].decode()
    except subprocess.TimeoutExpired:
        pytest.fail(f"the sweep did not finish within {DEADLINE_S:.0f} s")
    finally:  # whatever the group left behind (a pool or Ray process): nothing outlives the test
        try:
            os.killpg(proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    assert proc.returncode == 0, output
    return output


def _outcome(records):
    """What a unit's result is, without its timings."""
    return {
        (r["scene"], r["method"], r["run"]): (
            r["status"],
            r["planning_success"],
            r["goal_set_size"],
            r["smoothness"],
            r["collision"],
            r["min_clearance"],
        )
        for r in records
    }


def _check_same_as_reference(out, reference):
    """Every unit exactly once, each as in the uninterrupted run, and the same table."""
    expected = {
        E.unit_key({"scene_name": r["scene"], "method": r["method"], "run": r["run"]}) + ".json" for r in reference
    }
    assert set(_unit_files(out)) == expected
    with open(os.path.join(out, "runs.json")) as f:
        records = json.load(f)
    keys = [(r["scene"], r["method"], r["run"]) for r in records]
    assert len(keys) == len(set(keys)) == len(reference)  # none lost, none counted twice
    with open(os.path.join(out, "runs.csv")) as f:
        assert len(list(csv.DictReader(f))) == len(reference)
    assert _outcome(records) == _outcome(reference)
    without_times = lambda rs: {
        m: {k: v for k, v in row.items() if "time" not in k}  # noqa: E731
        for m, row in summarize(rs, METHODS).items()
    }
    assert without_times(records) == without_times(reference)


def test_a_sweep_killed_as_a_process_group_resumes_to_the_same_table(scene_dir, reference, tmp_path):
    out = tmp_path / "killed"
    proc = _start(_bench_command(scene_dir, out))
    _wait_for(lambda: len(_unit_files(out)) >= KILL_AFTER_UNITS, proc, f"{KILL_AFTER_UNITS} unit files")
    os.killpg(proc.pid, signal.SIGKILL)  # the driver and both pool workers, mid-run
    proc.wait()
    done = len(_unit_files(out))
    assert KILL_AFTER_UNITS <= done < len(reference), "the kill did not land mid-run"
    assert not os.path.exists(out / "runs.json")

    output = _finish(_start(_bench_command(scene_dir, out)))
    assert "Table I" in output
    _check_same_as_reference(str(out), reference)


def _descendants(pid):
    """Every process below ``pid`` (from /proc), with its command line."""
    children = {}
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            with open(f"/proc/{entry}/cmdline", "rb") as f:
                cmdline = f.read().replace(b"\0", b" ").decode(errors="replace")
        except (OSError, IndexError, ValueError):
            continue  # exited meanwhile
        children.setdefault(ppid, []).append((int(entry), cmdline))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child[0])
    return found


@pytest.mark.ray
def test_a_lost_ray_worker_is_retried_and_the_table_is_the_same(scene_dir, reference, tmp_path):
    """Ray re-runs a task whose worker died (the runner's tasks have max_retries); the driver writes
    each unit once, when its result arrives, so the retried unit is neither lost nor doubled."""
    pytest.importorskip("ray")
    out = tmp_path / "ray"
    proc = _start(_bench_command(scene_dir, out, "--ray", "local"))
    busy = lambda: [pid for pid, cmd in _descendants(proc.pid) if cmd.startswith("ray::_run_chunk")]  # noqa: E731
    # A worker busy with a unit (not a grasp-set job): kill it once the first unit is on disk.
    _wait_for(lambda: len(_unit_files(out)) >= 1 and busy(), proc, "a Ray worker running a unit")
    victim = busy()[0]
    os.kill(victim, signal.SIGKILL)
    _finish(proc)
    _check_same_as_reference(str(out), reference)


def test_a_resume_that_would_mix_two_sweeps_is_refused(scene_dir, tmp_path):
    """Regression (issue 26): deleting sweep.json and resuming with another seed reused the old units."""
    calls = []

    def fake(unit):  # a finished record: the sweep's bookkeeping is what is tested
        calls.append(unit)
        return {
            "table": unit["table"],
            "scene": unit["scene_name"],
            "target": "t",
            "method": unit["method"],
            "run": unit["run"],
            "seed": int(unit["seed"]),
            "status": "no_goals",
            "valid": True,
            "planned": False,
            "planning_success": False,
            "execution_success": False,
        }

    out = tmp_path / "mixed"
    first = E.run_sweep(_settings(scene_dir, out, workers=0), unit_fn=fake)
    assert len(calls) == len(first) == 2 * len(METHODS)
    assert all("sweep" not in r for r in first)  # the fingerprint stays in the files, not the table
    stored = json.loads((out / "units" / _unit_files(out)[0]).read_text())
    assert stored["sweep"] == E.sweep_fingerprint(_settings(scene_dir, out))

    os.remove(out / "sweep.json")
    with pytest.raises(InputError, match=rf"{out}/units: .*seed: 0 there, 7 now"):
        E.run_sweep(_settings(scene_dir, out, workers=0, seed=7), unit_fn=fake)
    assert not os.path.exists(out / "sweep.json")  # nothing claims the new seed
    with pytest.raises(InputError, match="grasps: 10 there, 5 now"):
        E.run_sweep(_settings(scene_dir, out, workers=0, grasps=5), unit_fn=fake)
    assert len(calls) == len(first)  # no unit ran

    # The same settings still resume without running anything.
    assert len(E.run_sweep(_settings(scene_dir, out, workers=0), unit_fn=fake)) == len(first)
    assert len(calls) == len(first)

    # A unit copied in from another sweep (sweep.json present and matching) is refused by name too.
    other = tmp_path / "other"
    E.run_sweep(_settings(scene_dir, other, workers=0, seed=3), unit_fn=fake)
    name = _unit_files(out)[-1]
    (out / "units" / name).write_text((other / "units" / name).read_text())
    with pytest.raises(InputError, match=rf"{name} was made by a sweep with other settings \(seed: 3 there, 0 now"):
        E.run_sweep(_settings(scene_dir, out, workers=0), unit_fn=fake)

    # Through the CLI: bad input, exit code 2, one line naming the folder and the field.
    os.remove(out / "sweep.json")
    result = subprocess.run(
        _bench_command(scene_dir, out, "--seed", "4"), capture_output=True, text=True, timeout=DEADLINE_S
    )
    assert result.returncode == 2, result.stderr
    assert f"{out}/units" in result.stderr and "seed: 0 there, 4 now" in result.stderr
