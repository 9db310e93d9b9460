"""What a pick-and-place plan file holds (``pickplace.json``, written by ``pickplan pickplace`` and
``pickplan demo --place``): every segment's waypoints and its timed samples (within the robot's
limits), the grasp in hand, the planned place; plus what ``plan.json`` holds for the 3D view (the
whole trajectory, the held object's interval, the place goal set)."""

from __future__ import annotations

from typing import List, Optional, Tuple

import numpy as np

from pickplan.core.timing import TimedTrajectory
from pickplan.omg.pickplace import PickPlacePlan
from pickplan.omg.place import PlaceRequest

PICKPLACE_FORMAT = "pickplan.pickplace/1"


def pickplace_record(
    plan: PickPlacePlan,
    request: PlaceRequest,
    robot: str,
    timed: Optional[List[Tuple[str, TimedTrajectory]]] = None,
    execution: Optional[dict] = None,
) -> dict:
    """``pickplace.json``: the plan's dict (``PickPlacePlan.to_dict``), the request, the robot, the timed
    segments (t, q, qd, qdd at their rate) and the execution's outcome when it ran."""
    d = {
        "format": PICKPLACE_FORMAT,
        "robot": robot,
        "request": request.to_dict(),
        **plan.to_dict(),
        "execution": execution,
    }
    if timed is not None:
        d["timed"] = [{"name": name, **t.to_dict()} for name, t in timed]
        d["duration"] = float(sum(t.duration for _, t in timed))
    return d


def view_record(
    plan: PickPlacePlan, robot: str, target: Optional[str] = None, frame: Optional[np.ndarray] = None
) -> dict:
    """``plan.json`` for ``pickplan view``: the segments as one trajectory and the held object's
    interval (from the grasp to the release), its grasp and its place; the place goal set as hands.
    A plan from depth names the scene's ``target`` and its true pose ``frame`` (its object frame in
    the observed object's: the view draws the true mesh)."""
    frame = np.eye(4) if frame is None else np.asarray(frame, dtype=float)
    segments = plan.segments()
    lengths = [len(Q) - 1 for _, Q in segments]
    record = {
        "version": 2,
        "robot": robot,
        "status": plan.status.value,
        "trajectory": plan.trajectory.tolist(),
        "goal_set": [],
        "chosen_goal": None,
        "refined_goal": None,
    }
    if plan.held is not None:
        first = lengths[0]
        carried = sum(n for (name, _), n in zip(segments, lengths) if name in ("lift", "transfer"))
        record["held"] = {
            "name": target or plan.held.name,
            "hand_T_object": (plan.held.hand_T_object @ frame).tolist(),
            "from": first,
            "to": first + carried,
        }
        if plan.place_pose is not None:
            record["held"]["place_pose"] = (np.asarray(plan.place_pose) @ frame).tolist()
    if plan.place_goals is not None and len(plan.place_goals):
        record["goal_set"] = np.asarray(plan.place_goals.goal_set.goals).tolist()
        if plan.place is not None and plan.place.goal_source >= 0:
            record["chosen_goal"] = np.asarray(plan.place.goal).tolist()
    return record
