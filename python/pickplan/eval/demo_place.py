"""``pickplan demo --place``: the demo's scene, its target picked and put down in a free region of the
table beside the clutter (``place_regions``), executed in PyBullet; a picture of the execution, the
plan with both segments timed, a metrics table and the 3D view of the object carried and placed."""

from __future__ import annotations

import logging
import os
import time

import numpy as np

from pickplan.core.io import write_json, write_text
from pickplan.eval.demo import DemoRun, DemoSettings
from pickplan.eval.pickplace import execute_in_sim
from pickplan.eval.place_regions import RegionKind, place_task
from pickplan.omg.pickplace import PickPlacePlan, PickPlacePlanner, PickPlaceSettings
from pickplan.omg.pickplace_file import pickplace_record, view_record
from pickplan.omg.planner import OMGPlanner
from pickplan.sim import execution, scenes
from pickplan.sim.view import view_folder
from pickplan.sim.view_page import write_html

log = logging.getLogger(__name__)


def metrics_table(plan: PickPlacePlan, executed) -> str:
    rows = [
        ("Pick", plan.pick.status.value),
        ("Place (transfer)", plan.place.status.value if plan.place else "-"),
        ("Pick and place", plan.status.value + (f" ({plan.reason})" if plan.reason else "")),
    ]
    if plan.place_goals is not None:
        rows.append(("Place goals (of candidates)", f"{len(plan.place_goals)} of {len(plan.place_goals.object_poses)}"))
    for key, label in (("pick", "Pick planning (ms)"), ("place", "Place planning: goal set + transfer (ms)")):
        if key in plan.timings:
            rows.append((label, f"{1000 * plan.timings[key]:.1f}"))
    if plan.success:
        rows.append(
            (
                "Duration (s, every segment timed within the limits)",
                f"{sum(t.duration for _, t in plan.timed(250.0)):.2f}",
            )
        )
    if executed is not None:
        rows += [
            ("Executed in PyBullet", executed.status.value + (f" ({executed.message})" if executed.message else "")),
            ("Placed object's tilt (deg)", f"{executed.tilt_deg:.1f}"),
            ("Other objects moved at most (cm)", f"{100 * max(executed.object_displacements.values(), default=0):.1f}"),
        ]
    return "\n".join(["| | this run |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]) + "\n"


def run_demo_place(out: str, settings: DemoSettings = DemoSettings()) -> DemoRun:
    """The pick-and-place demo into folder ``out`` (``DemoRun.lifted``: placed as asked); progress goes
    to the ``pickplan.eval.demo_place`` logger."""
    t0 = time.perf_counter()
    os.makedirs(out, exist_ok=True)
    log.info(f"[1/4] generating a cluttered scene (seed {settings.seed}) and a free place region beside it")
    scene = scenes.generate_scene(settings.seed, settings=scenes.SceneSettings(robot=settings.robot))
    scene, request = place_task(scene, RegionKind.free, settings.seed)
    log.info(
        f"      target: {scene.target}; region x {request.region_min[0]:.2f}-{request.region_max[0]:.2f}, "
        f"y {request.region_min[1]:.2f}-{request.region_max[1]:.2f} m"
    )
    log.info(f"[2/4] planning the pick and the place for {settings.robot} (OMG: MD selection over grasps, then places)")
    planner = PickPlacePlanner(
        OMGPlanner(settings.robot, scene, settings.planner), request, PickPlaceSettings(pick=settings.planner)
    )
    plan = planner.plan()
    log.info(f"      {plan.status.value} {plan.reason}")
    executed = None
    if plan.success:
        log.info("[3/4] executing in PyBullet: approach, close, lift, transfer, set down, release, retract")
        executed = execute_in_sim(
            scene,
            planner,
            plan,
            request,
            planner.world.robot.info.name,
            record=execution.RecordSettings(every=settings.record_every),
        )
        log.info(f"      {executed.status.value} {executed.message}")
        frames = executed.frames
        if frames:
            pick = np.linspace(0, len(frames) - 1, min(settings.frames_in_sheet, len(frames))).round().astype(int)
            execution.save_frames([frames[i] for i in pick], os.path.join(out, "demo.png"), columns=4)
    log.info("[4/4] writing the plan, the 3D view and the metrics table")
    robot = planner.world.robot.info.name
    timed = plan.timed(settings.timed_rate) if plan.success else None
    write_json(
        os.path.join(out, "pickplace.json"),
        pickplace_record(plan, request, robot, timed, executed.to_dict() if executed else None),
    )
    write_json(os.path.join(out, "region.json"), request.to_dict())
    scene.save(os.path.join(out, "scene.json"))
    write_json(os.path.join(out, "plan.json"), view_record(plan, robot))
    write_html(view_folder(out), os.path.join(out, "view.html"))
    table = metrics_table(plan, executed)
    write_text(os.path.join(out, "metrics.md"), table)
    files = ["demo.png"] * bool(executed is not None and executed.frames) + [
        "view.html",
        "metrics.md",
        "pickplace.json",
        "plan.json",
        "scene.json",
        "region.json",
    ]
    return DemoRun(table, files, executed is not None and executed.success, time.perf_counter() - t0)
