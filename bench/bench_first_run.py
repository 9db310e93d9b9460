"""The first plan on a fresh install (issue 36): `pickplan plan --scene S` in a subprocess with an empty
cache (``PICKPLAN_CACHE_DIR`` an empty folder) and an empty per-user temp folder (``TMPDIR``), on scenes of
built-in objects; wall time (and the child's CPU time) per run, ``--repeat`` fresh runs per scene, then
one run again in the last run's cache (what every later plan costs).

    .venv/bin/python bench/bench_first_run.py --scenes 3 --repeat 3
    .venv/bin/python bench/bench_first_run.py --python /other/venv/bin/python   # another install, same scenes
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

from pickplan.core.io import write_json


def _scenes(n: int, seed: int, folder: str) -> list:
    """``pickplan scenes`` of built-in objects, made in their own cache (not timed)."""
    env = dict(os.environ, PICKPLAN_CACHE_DIR=os.path.join(folder, "cache"))
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pickplan",
            "-q",
            "scenes",
            "--n",
            str(n),
            "--seed",
            str(seed),
            "--objects",
            "builtin",
            "--out",
            os.path.join(folder, "scenes"),
        ],
        env=env,
        check=True,
    )
    return [os.path.join(folder, "scenes", f"scene_{i:04d}.json") for i in range(n)]


def _run(python: str, scene: str, cache: str, tmp: str, out: str) -> dict:
    os.makedirs(tmp, exist_ok=True)
    env = dict(os.environ, PICKPLAN_CACHE_DIR=cache, TMPDIR=tmp)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(
        [python, "-m", "pickplan", "plan", "--scene", scene, "--out", out], env=env, capture_output=True, text=True
    )
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode not in (0, 1):  # 1: ran, no plan
        sys.exit(f"pickplan plan failed on {scene}:\n{proc.stderr}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu, "status": proc.returncode, "stderr_lines": len(proc.stderr.splitlines())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", type=int, default=3)
    ap.add_argument("--seed", type=int, default=0, help="seed of the scene set (`pickplan scenes --seed`)")
    ap.add_argument("--repeat", type=int, default=3, help="fresh runs per scene")
    ap.add_argument("--python", default=sys.executable, help="the interpreter whose pickplan plans")
    ap.add_argument("--out", default=None, help="also write the runs as JSON here")
    args = ap.parse_args()
    rows, runs = [], []
    with tempfile.TemporaryDirectory(prefix="pickplan-first-run-") as root:
        for k, scene in enumerate(_scenes(args.scenes, args.seed, root)):
            with open(scene) as f:
                data = json.load(f)
            fresh = []
            for r in range(args.repeat):
                run_dir = os.path.join(root, f"s{k}-r{r}")
                fresh.append(
                    _run(
                        args.python,
                        scene,
                        os.path.join(run_dir, "cache"),
                        os.path.join(run_dir, "tmp"),
                        os.path.join(run_dir, "out"),
                    )
                )
            warm = _run(
                args.python,
                scene,
                os.path.join(run_dir, "cache"),
                os.path.join(run_dir, "tmp"),
                os.path.join(run_dir, "out"),
            )
            runs.append({"scene": os.path.basename(scene), "target": data["target"], "fresh": fresh, "warm": warm})
            walls = [x["wall"] for x in fresh]
            rows.append(
                f"| {os.path.basename(scene)} | {data['target']} | {len(data['objects'])} | "
                f"{np.median(walls):.1f} | {min(walls):.1f}-{max(walls):.1f} | "
                f"{np.median([x['cpu'] for x in fresh]):.1f} | {warm['wall']:.1f} |"
            )
    print(f"load average at the end: {os.getloadavg()[0]:.1f}")
    print("| scene | target | objects | fresh wall s (median) | range | fresh CPU s | again, warm cache, wall s |")
    print("|---|---|---|---|---|---|---|")
    print("\n".join(rows))
    allw = [x["wall"] for run in runs for x in run["fresh"]]
    print(f"\nall fresh runs: median {np.median(allw):.1f} s, max {max(allw):.1f} s ({len(allw)} runs)")
    if args.out:
        write_json(args.out, runs)


if __name__ == "__main__":
    main()
