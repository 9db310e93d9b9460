"""The ``pickplan`` command line: ``pickplan demo``, and more as the library grows."""
from __future__ import annotations

import argparse
import os
import sys
import time
from typing import Optional, Sequence

import numpy as np


def _kinematics_demo(out: str, seed: int) -> int:
    """Poses the Panda in PyBullet at seeded configurations and checks native FK against it."""
    import pybullet as pb

    from . import robots, viz
    from .io import write_text

    robot = robots.panda()
    cid = pb.connect(pb.DIRECT)
    try:
        import pybullet_data

        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        pb.loadURDF("plane.urdf", physicsClientId=cid)
        body = pb.loadURDF(robot.urdf_path, useFixedBase=True, physicsClientId=cid)
        index = {pb.getJointInfo(body, j, physicsClientId=cid)[12].decode(): j
                 for j in range(pb.getNumJoints(body, physicsClientId=cid))}
        Q = np.vstack([robot.ready_configuration, robot.random_configurations(3, seed=seed)])
        t0 = time.perf_counter()
        poses = robot.fk_batch(Q)
        t_fk = (time.perf_counter() - t0) / len(Q)
        images, rows = [], []
        hand = robot.link_index(robot.hand_link)
        for b, q in enumerate(Q):
            for k, name in enumerate(robot.joint_names):
                pb.resetJointState(body, index[robot.link_names[robot.native.link_q_index.index(k)]], q[k],
                                   physicsClientId=cid)
            state = pb.getLinkState(body, index[robot.hand_link], computeForwardKinematics=True, physicsClientId=cid)
            err = float(np.abs(poses[b, hand, :3, 3] - np.array(state[4])).max())
            rows.append((b, *np.round(poses[b, hand, :3, 3], 4), err))
            images.append(viz.render(cid, 400, 300))
        os.makedirs(out, exist_ok=True)
        viz.write_png(os.path.join(out, "demo.png"), viz.tile(images, 2))
        lines = ["| config | hand x | hand y | hand z | |FK - PyBullet| (m) |", "|---|---|---|---|---|"]
        lines += [f"| {b} | {x} | {y} | {z} | {e:.1e} |" for b, x, y, z, e in rows]
        lines.append(f"\nnative FK: {t_fk * 1e6:.1f} us per configuration (Python call included)")
        table = "\n".join(lines) + "\n"
        write_text(os.path.join(out, "metrics.md"), table)
        print(table)
        print(f"wrote {os.path.join(out, 'demo.png')} and {os.path.join(out, 'metrics.md')}")
        return 0
    finally:
        pb.disconnect(cid)


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="pickplan", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="the main job: plan and execute a grasp in a generated scene")
    demo.add_argument("--out", default="out/demo", help="folder for the picture and the metrics table")
    demo.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    if args.command == "demo":
        return _kinematics_demo(args.out, args.seed)
    parser.error(f"unknown command {args.command}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
