"""Issue 38: the ROS 2 node's request-to-trajectory latency beside the library's own, and its memory
over many requests, in one run.

    .venv/bin/python bench/bench_ros.py [--requests 500] [--library-every 5] [--scene-seed 3] [--out out/bench/ros]

One 640 x 480 view of a generated scene (``render_observation``, 32FC1) and the Panda's start are
published as a camera and a robot would (``ros.replay``, 5 Hz); the node (``pickplan ros serve
--transport shm``, its own process, a private domain, shared memory only) plans for the object
nearest a point on the target. Each request: set the point (SetParameters), call ``~/plan``, wait
for the ``JointTrajectory``; the time from the call to the trajectory is the node's latency.
Every ``--library-every``-th request the library plans the same observation in this process, as
``pickplan plan --observation`` does (``PerceivedWorld`` finding the plane itself, ``PerceivedPlanner``
from the same start, ``result.timed`` at the node's rate): the library's latency. The node's
resident memory is read from /proc every 25 requests.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time

import numpy as np

from pickplan.core import robots
from pickplan.core.io import write_json, write_text
from pickplan.omg.perceived_world import PerceivedPlanner, PerceivedWorld
from pickplan.omg.planner import OMGSettings
from pickplan.perception.field import backproject
from pickplan.ros.extra import Transport, configure_transport
from pickplan.ros.pipeline import CameraView, PickPipeline, PickRequest, PickSettings
from pickplan.sim.observe import render_observation
from pickplan.sim.scenes import generate_scene


def _rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


def _target_point(obs) -> np.ndarray:
    """A pixel at the middle of the target in view 0, back-projected (where a user would click)."""
    rows, cols = np.nonzero(obs.target_mask[0] & (obs.depth[0] > 0))
    k = int(np.argmin((rows - rows.mean()) ** 2 + (cols - cols.mean()) ** 2))
    return backproject(obs.depth[0], obs.K[0], obs.camera_pose[0])[rows[k], cols[k]]


def _library_seconds(pipeline: PickPipeline, request: PickRequest, start) -> float:
    obs, world_settings = pipeline.observation(request)  # the same observation the node builds
    t0 = time.perf_counter()
    world = PerceivedWorld(obs, pipeline.robot, pipeline.settings.world, cache=pipeline.cache)  # finds the plane
    result = PerceivedPlanner(world, pipeline.settings.planner).plan(start=start)
    if not result.success:
        raise RuntimeError(f"the library did not plan the bench observation: {result.status}")
    result.timed(pipeline.settings.rate, pipeline.limits)
    return time.perf_counter() - t0


def _stats(xs) -> dict:
    xs = sorted(xs)
    return {
        "n": len(xs),
        "median_ms": 1000 * statistics.median(xs),
        "p90_ms": 1000 * xs[int(0.9 * (len(xs) - 1))],
        "max_ms": 1000 * xs[-1],
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--requests", type=int, default=500)
    ap.add_argument("--library-every", type=int, default=5)
    ap.add_argument("--scene-seed", type=int, default=3)
    ap.add_argument("--out", default="out/bench/ros")
    args = ap.parse_args(argv)
    os.environ["ROS_DOMAIN_ID"] = str(10 + os.getpid() % 90)
    configure_transport(Transport.shm, os.environ)
    from pickplan.ros.client import PickClient
    from pickplan.ros.replay import ObservationReplay

    scene = generate_scene(seed=args.scene_seed)
    obs = render_observation(scene, views=1)
    robot = robots.load_robot("panda")
    start = robot.ready_configuration
    point = _target_point(obs)
    pipeline = PickPipeline(PickSettings(planner=OMGSettings(seed=0)))
    request = PickRequest(
        [CameraView(np.where(obs.depth[0] > 0, obs.depth[0], np.nan), obs.K[0], obs.camera_pose[0])], start, point
    )
    os.makedirs(args.out, exist_ok=True)
    client = PickClient()
    replay = ObservationReplay(client.node, obs, robot, start)
    client.node.create_timer(0.2, replay.publish)
    log = open(os.path.join(args.out, "node.log"), "w")
    node = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pickplan",
            "ros",
            "serve",
            "--transport",
            "shm",
            "--ros-args",
            *replay.node_arguments(),
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
    )
    node_s, library_s, rss = [], [], []
    try:
        if not client.wait_for_server(120):
            raise RuntimeError("the node did not come up")
        client.spin(1.0)
        for k in range(args.requests + 1):
            reply = client.plan(point=point)
            if not reply.success or reply.trajectory is None:
                raise RuntimeError(f"request {k}: {reply.message}")
            if k == 0:
                rss.append((0, _rss_mb(node.pid)))
                continue  # the first builds the robot's cached data (hand SDF): a start-up cost
            node_s.append(reply.seconds)
            if k % args.library_every == 0:
                library_s.append(_library_seconds(pipeline, request, start))
            if k % 25 == 0:
                rss.append((k, _rss_mb(node.pid)))
                print(
                    f"{k} requests: node {1000 * statistics.median(node_s):.0f} ms, library "
                    f"{1000 * statistics.median(library_s):.0f} ms (medians), node RSS {rss[-1][1]:.0f} MB",
                    flush=True,
                )
    finally:
        node.send_signal(2)
        node.wait(timeout=30)
        client.close()
        log.close()
    report = {
        "node": _stats(node_s),
        "library": _stats(library_s),
        "rss_mb": rss,
        "load_average": os.getloadavg(),
        "scene_seed": args.scene_seed,
        "views": 1,
        "image": f"{obs.depth.shape[2]} x {obs.depth.shape[1]}",
    }
    n, lib = report["node"], report["library"]
    text = (
        f"| | requests | median ms | p90 ms | max ms |\n|---|---|---|---|---|\n"
        f"| node: request to trajectory | {n['n']} | {n['median_ms']:.0f} | {n['p90_ms']:.0f} | {n['max_ms']:.0f} |\n"
        f"| library, same observation | {lib['n']} | {lib['median_ms']:.0f} | {lib['p90_ms']:.0f} | "
        f"{lib['max_ms']:.0f} |\n\nDifference of the medians: {n['median_ms'] - lib['median_ms']:.1f} ms. "
        f"Node RSS (MB) after request k: {', '.join(f'{k}: {m:.0f}' for k, m in rss)}. "
        f"Load average {report['load_average'][0]:.1f}.\n"
    )
    print(text)
    write_text(os.path.join(args.out, "report.md"), text)
    write_json(os.path.join(args.out, "report.json"), json.loads(json.dumps(report)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
