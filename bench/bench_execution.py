"""Wall and CPU time of ``pickplan.sim.execution.execute_plan`` on fixed inputs.

Inputs: generated scenes (seeds 0..N-1, built-in objects); in each, every object narrow enough for
the open Panda hand (< 75 mm across) is grasped top-down with the hand-made trajectories of
``tests/python/test_execution.py`` (start -> pre-grasp -> grasp, 29 waypoints at 0.1 s).

    .venv/bin/python bench/bench_execution.py --scenes 6 [--record]

Prints one line per execution and mean / median / worst wall time, CPU time and time per step.
"""

import argparse
import os
import statistics
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "python"))

from test_execution import grasp_trajectory, top_down_grasp  # noqa: E402  (the test's grasp builder)

from pickplan.sim import execution  # noqa: E402
from pickplan.core import robots
from pickplan.sim import scenes


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=6, help="scene seeds 0..N-1")
    ap.add_argument("--record", action="store_true", help="also render frames (RecordSettings defaults)")
    args = ap.parse_args(argv)
    robot = robots.panda()
    record = execution.RecordSettings() if args.record else None
    walls, cpus, per_step, ok = [], [], [], 0
    for seed in range(args.scenes):
        scene = scenes.generate_scene(seed)
        for o in scene.objects:
            _, width, _ = top_down_grasp(scene, o.name)
            if width > 0.075:
                continue
            scene.target = o.name
            Q = grasp_trajectory(robot, scene, o.name)
            c0 = time.process_time()
            r = execution.execute_plan(scene, Q, record=record)
            cpu = time.process_time() - c0
            walls.append(r.seconds)
            cpus.append(cpu)
            per_step.append(cpu / r.steps)
            ok += r.success
            print(
                f"seed {seed} {o.name:22s} {r.status:9s} lift {r.target_lift:.3f} m  steps {r.steps}  "
                f"wall {r.seconds:.2f} s  cpu {cpu:.2f} s  frames {len(r.frames)}",
                flush=True,
            )
    if not walls:
        print("no graspable objects")
        return 1
    n = len(walls)
    print(f"\n{n} executions, {ok} lifted ({100.0 * ok / n:.0f} %)")
    rows = (("wall", walls, "s", 1.0), ("cpu", cpus, "s", 1.0), ("cpu per step", per_step, "ms", 1e3))
    for label, xs, unit, k in rows:
        print(
            f"{label:13s} mean {k * statistics.mean(xs):.3f} {unit}  median {k * statistics.median(xs):.3f} {unit}"
            f"  worst {k * max(xs):.3f} {unit}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
