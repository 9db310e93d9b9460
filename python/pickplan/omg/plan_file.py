"""What ``plan.json`` holds (``pickplan demo`` and ``pickplan plan --out``): the trajectory and the
paper's metrics, plus what a 3D view of the plan needs: the goal set, the grasp the planner chose,
the refined grasp and the robot's body points that penetrate an obstacle."""

from __future__ import annotations

from typing import Optional

import numpy as np

from pickplan.omg.planner import PlanResult
from pickplan.omg.world import World

PLAN_FILE_VERSION = 2  # 1: no goal set, grasps or collision points


def collision_points(world: World, trajectory: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """World positions of the robot's body points that lie inside an obstacle (signed distance below
    ``margin``) at any waypoint, as (K, 4) rows of x, y, z and the waypoint index. The target does not
    count: the fingers close around it. Links that never move do not count: the base stands on the table."""
    Q = np.asarray(trajectory, dtype=float)
    if Q.ndim != 2 or Q.shape[1] != world.robot.dof:
        raise ValueError(f"trajectory: expected shape (T, {world.robot.dof}), got {Q.shape}")
    X = world.robot.transform_points(Q, world.body)  # (T, N, 3)
    distance, _ = world.sdf.distance(X.reshape(-1, 3), exclude=(world.target,))
    inside = np.asarray(distance).reshape(X.shape[:2]) < margin
    steps, points = np.nonzero(inside)
    return np.column_stack([X[steps, points], steps.astype(float)]) if len(steps) else np.zeros((0, 4))


def plan_record(result: PlanResult, world: Optional[World] = None, execution: Optional[dict] = None) -> dict:
    """The JSON-ready content of ``plan.json``. ``world`` (the planner's) adds the collision points."""
    record = {
        "version": PLAN_FILE_VERSION,
        "robot": world.robot.info.name if world is not None else "panda",  # the viewer loads this robot
        "status": result.status,
        "trajectory": result.trajectory.tolist(),
        "metrics": {} if result.metrics is None else result.metrics.to_dict(),
        "grasp_cost": result.grasp_cost,
        "timings": result.timings,
        "iterations": result.iterations,
        "execution": execution,
        "goal_set": np.asarray(result.goal_set).tolist(),
        "chosen_goal": None,
        "refined_goal": None,
    }
    if result.goal_source >= 0:
        record["chosen_goal"] = np.asarray(result.goal_set[result.goal_source]).tolist()
        if result.refined:
            record["refined_goal"] = np.asarray(result.goal).tolist()
    if world is not None:
        record["collision_points"] = collision_points(world, result.trajectory).tolist()
    return record
