"""Fuzz suite (issues 26, 39): seeded random mutations of valid scene files, grasp arrays, meta-model
files, pick-up problem files, URDFs, meshes, robot descriptions (TOML; `robots check` and
`load_robot` must agree on each) and depth observations (.npz), each case run in a child process (many per process, but a crash or a hang
is caught and pinned on its case) with a time limit. Every case must end in a valid result with
finite numbers or a documented error with a message (fuzz_cases.ALLOWED_ERRORS) that, for the file
kinds of fuzz_cases.NAMED_FILES, names the file: never a signal, a hang past the limit, NaN in a
result, two readers that disagree, or another exception type (in the CLI: exit 2, never 3).

PICKPLAN_FUZZ_COUNT cases per kind (default 300; `make fuzz FUZZ_COUNT=5000` runs more),
PICKPLAN_FUZZ_SEED the seed (default 0)."""

import base64
import collections
import json
import os
import queue
import random
import signal
import subprocess
import sys
import threading
import warnings

import numpy as np
import pytest
import trimesh

import fuzz_cases
from conftest import ycb_dir_or_none

COUNT = int(os.environ.get("PICKPLAN_FUZZ_COUNT", "300"))
SEED = int(os.environ.get("PICKPLAN_FUZZ_SEED", "0"))
CASE_SECONDS = float(os.environ.get("PICKPLAN_FUZZ_CASE_SECONDS", "30"))
WORKER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "fuzz_cases.py")

URDF = """<?xml version="1.0"?>
<robot name="fuzz">
  <link name="base"><collision><origin xyz="0 0 0.05" rpy="0 0 0"/><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="upper"><collision><geometry><cylinder radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="lower"><collision><origin xyz="0 0 0.1"/><geometry><mesh filename="{mesh}" scale="1 1 2"/></geometry></collision></link>
  <link name="tip"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="finger"><collision><geometry><box size="0.01 0.02 0.04"/></geometry></collision></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.1" rpy="0 0.1 0"/>
    <axis xyz="0 0 1"/><limit lower="-2.9" upper="2.9" effort="10" velocity="2"/></joint>
  <joint name="slide" type="prismatic"><parent link="upper"/><child link="lower"/><origin xyz="0 0 0.3"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2" effort="10" velocity="0.5"/></joint>
  <joint name="wrist" type="continuous"><parent link="lower"/><child link="tip"/><origin xyz="0 0 0.2"/><axis xyz="0 1 0"/></joint>
  <joint name="grip" type="prismatic"><parent link="tip"/><child link="finger"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" effort="1" velocity="0.1"/><mimic joint="slide" multiplier="0.5" offset="0"/></joint>
</robot>
"""


def _obj_text(mesh) -> str:
    lines = ["v %.6f %.6f %.6f" % tuple(v) for v in mesh.vertices] + ["f %d %d %d" % tuple(f + 1) for f in mesh.faces]
    return "\n".join(lines) + "\n"


def _stl_text(mesh) -> str:
    return trimesh.exchange.stl.export_stl_ascii(mesh)


@pytest.fixture(scope="module")
def bases(tmp_path_factory):
    """One valid input of each kind, the seed of every mutation."""
    from pickplan.omg import grasps as G
    from pickplan.sim import scenes
    from test_reliability import _metamodel

    folder = tmp_path_factory.mktemp("fuzz_bases")
    box = trimesh.creation.box(extents=[0.05, 0.04, 0.1])
    (folder / "link.obj").write_text(_obj_text(box))
    ycb = ycb_dir_or_none()  # absent in CI: a failure, not a silent fallback
    stored = [os.path.join(ycb, d, "grasps_graspit.npy") for d in sorted(os.listdir(ycb))] if ycb else []
    stored = [p for p in stored if os.path.isfile(p)]
    if ycb:
        assert stored, f"{ycb}: no object with a grasps_graspit.npy"
        grasps = np.load(stored[0])[:40]
    else:
        from pickplan.core import objects

        warnings.warn("fuzzing generated grasps: the YCB folder with stored GraspIt grasps is absent", stacklevel=1)
        grasps = G.grasp_set(objects.library("builtin").get(objects.library("builtin").names[0]), "antipodal", 40).poses
    mm = _metamodel()
    mm["surface_degree"] = [3, 2]
    for lv in mm["levels"]:
        lv["surface"]["coeffs"] = (0.9 - 0.1 * np.add.outer(np.arange(4), np.arange(3))).tolist()
    cylinder = trimesh.creation.cylinder(radius=0.03, height=0.1, sections=12)
    from pickplan.pickup.nlp import cases

    problem = json.load(open(cases.case_path(5)))
    problem["part"]["metamodel"] = "standin"
    problem["obstacles"].append({"box": {"center": [5.0, -1.0, 0.3], "size": [0.4, 0.8, 0.6], "yaw": 0.4}})
    from pickplan.core import description
    from pickplan.sim.observe import CameraRig, render_observation
    from conftest import known_scene

    obs = render_observation(known_scene()[0], views=1, rig=CameraRig(width=80, height=60))
    observation = {
        "depth": obs.depth,
        "K": obs.K,
        "camera_pose": obs.camera_pose,
        "rgb": obs.rgb,
        "target_mask": obs.target_mask.astype(np.uint8),
        "format": np.array("pickplan.observation"),
        "version": np.array(1),
    }
    robots = [open(description.description_path(name)).read() for name in ("panda", "ur5_2f85")]
    return {
        "scene": scenes.generate_scene(seed=2).to_dict(),
        "grasps": np.asarray(grasps, float),
        "metamodel": mm,
        "problem": problem,
        "robot": robots,
        "observation": observation,
        "urdf": URDF.format(mesh=str(folder / "link.obj")),
        "mesh": {"mesh.stl": _stl_text(cylinder), "collision.obj": _obj_text(cylinder.convex_hull)},
    }


def make_cases(kind: str, base, n: int, seed: int) -> list:
    rng = random.Random(f"{kind}/{seed}")
    cases = []
    for _ in range(n):
        if kind == "problem" and rng.random() < 0.1:  # an integer longer than Python converts from text
            payload = fuzz_cases.replace_numbers(json.dumps(base), rng, [fuzz_cases.HUGE_INTEGER])
        elif kind in ("scene", "metamodel", "problem"):
            payload = fuzz_cases.mutate_json(base, rng)
        elif kind == "robot":
            payload = fuzz_cases.mutate_toml(rng.choice(base), rng)
        elif kind == "observation":
            payload = base64.b64encode(fuzz_cases.mutate_observation(base, rng)).decode()
        elif kind == "grasps":
            payload = base64.b64encode(fuzz_cases.mutate_array(base, rng)).decode()
        elif kind == "urdf":
            payload = fuzz_cases.mutate_text(base, rng)
        else:  # mesh: mutate one of the two files, sometimes drop one
            payload = dict(base)
            name = rng.choice(sorted(base))
            payload[name] = None if rng.random() < 0.05 else fuzz_cases.mutate_text(base[name], rng)
        cases.append({"kind": kind, "payload": payload})
    return cases


def run_cases(cases: list, folder) -> dict:
    """Outcome per case index; a child that dies or stalls is replaced and the case it was running
    is recorded as a crash (with the signal) or a hang."""
    path = os.path.join(folder, "cases.json")
    with open(path, "w") as f:
        json.dump(cases, f)
    results, start = {}, 0
    while start < len(cases):
        first = start
        with open(os.path.join(folder, "stderr.txt"), "w") as err:
            proc = subprocess.Popen(
                [sys.executable, WORKER, path, str(start)],
                stdout=subprocess.PIPE,
                stderr=err,
                text=True,
                start_new_session=True,
            )
            lines: queue.Queue = queue.Queue()
            threading.Thread(
                target=lambda: [lines.put(x) for x in proc.stdout] + [lines.put(None)], daemon=True
            ).start()
            current = None
            while True:
                try:  # the first case also pays for the imports
                    line = lines.get(timeout=CASE_SECONDS + (30 if current is None else 0))
                except queue.Empty:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
                    stuck = start if current is None else current
                    results[stuck] = {"outcome": "hang", "error": f"no answer within {CASE_SECONDS:.0f} s"}
                    start = stuck + 1
                    break
                if line is None:
                    code = proc.wait()
                    if current is not None and current not in results:
                        why = f"signal {-code}" if code < 0 else f"exit code {code}"
                        results[current] = {"outcome": "crash", "error": why}
                        start = current + 1
                    elif code != 0:
                        pytest.fail(
                            f"fuzz worker failed outside any case (exit {code}): {open(err.name).read()[-2000:]}"
                        )
                    else:  # a clean exit: every case from ``first`` on has its line, or the rest run again
                        missing = [i for i in range(first, len(cases)) if i not in results]
                        if missing and missing[0] == first:
                            pytest.fail(
                                f"fuzz worker exited cleanly without case {first}: {open(err.name).read()[-2000:]}"
                            )
                        start = missing[0] if missing else len(cases)
                    break
                if line.startswith("BEGIN "):
                    current = int(line.split()[1])
                elif line.startswith("{"):
                    r = json.loads(line)
                    results[r.pop("i")] = r
                    start = max(start, current + 1)
    return results


KINDS = ("scene", "grasps", "metamodel", "problem", "urdf", "mesh", "robot", "observation")


@pytest.mark.parametrize("kind", KINDS)
def test_fuzzed_inputs_end_in_a_clear_error_or_a_valid_result(kind, bases, tmp_path):
    cases = make_cases(kind, bases[kind], COUNT, SEED)
    results = run_cases(cases, str(tmp_path))
    assert sorted(results) == list(range(len(cases)))
    counts = collections.Counter(r["outcome"] for r in results.values())
    print(f"\nfuzz {kind}: {len(cases)} cases, " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    findings = {i: r for i, r in results.items() if r["outcome"] not in ("valid", "error")}
    for i, r in list(findings.items())[:10]:
        print(f"  case {i}: {r['outcome']}: {r.get('error')}\n    input: {str(cases[i]['payload'])[:300]!r}")
    assert not findings, f"{len(findings)} of {len(cases)} {kind} cases crashed, hung, gave NaN or an unclear error"
    assert counts["valid"] > 0 and counts["error"] > 0  # the mutations reach both outcomes


def test_the_harness_pins_a_crash_and_a_hang_on_their_cases(tmp_path, monkeypatch):
    """A harness that cannot fail is a defect: a case that kills its process and one that never
    returns must be reported as such, and the cases after them still run."""
    monkeypatch.setattr(sys.modules[__name__], "CASE_SECONDS", 5.0)
    crash = "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"
    hang = "import time; time.sleep(60)"
    cases = [{"kind": "exec", "payload": p} for p in ("1 + 1", crash, "2 + 2", hang, "raise ValueError('bad')")]
    results = run_cases(cases, str(tmp_path))
    assert [results[i]["outcome"] for i in range(5)] == ["valid", "crash", "valid", "hang", "error"]
    assert results[1]["error"] == f"signal {int(signal.SIGSEGV)}"
