"""What a request planned, for RViz: a ``visualization_msgs/MarkerArray`` in the planning frame.

Namespaces (colours as in ``pickplan view``): ``field`` the fused depth field's surface (grey
cubes), ``target`` the observed target points (yellow), ``goal_set`` the open hand at every goal
(blue points, thinned to ``max_goal_hands``), ``chosen_grasp`` the hand at the goal the planner
chose (orange), ``refined_grasp`` where C-Space ISF moved it (green); for a pick and place also
``place_region`` (the box's edges, purple) and ``place`` (the hand at the set-down, purple). The array starts with a
DELETEALL, so each request's markers replace the last's.
"""

from __future__ import annotations

from typing import Optional, Sequence

import numpy as np
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from pickplan.ros.pipeline import PickOutcome

FIELD_COLOR = (0.6, 0.6, 0.6, 0.6)
TARGET_COLOR = (1.0, 0.85, 0.1, 1.0)
GOAL_COLOR = (0.3, 0.5, 1.0, 0.5)
CHOSEN_COLOR = (1.0, 0.5, 0.0, 1.0)
REFINED_COLOR = (0.1, 0.8, 0.2, 1.0)
PLACE_COLOR = (0.7, 0.2, 0.9, 1.0)


def box_edges(lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
    """The 12 edges of the box [lo, hi] as 24 points (a LINE_LIST)."""
    corners = np.array(
        [[(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2]] for i in (0, 1) for j in (0, 1) for k in (0, 1)]
    )
    pairs = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
    return corners[np.array(pairs).ravel()]


def field_surface(grid, max_points: int = 20000) -> np.ndarray:
    """(N, 3) world centres of the occupied nodes of an ``SdfGrid`` (values <= 0) with a free
    6-neighbour, evenly thinned to at most ``max_points``."""
    v = np.asarray(grid.values)  # (z, y, x)
    occupied = v <= 0
    padded = np.pad(occupied, 1, constant_values=True)
    inner = np.ones_like(occupied)
    Z, Y, X = occupied.shape
    for dz, dy, dx in ((0, 1, 1), (2, 1, 1), (1, 0, 1), (1, 2, 1), (1, 1, 0), (1, 1, 2)):
        inner &= padded[dz : dz + Z, dy : dy + Y, dx : dx + X]
    z, y, x = np.nonzero(occupied & ~inner)
    points = np.asarray(grid.origin, float) + grid.resolution * np.column_stack([x, y, z])
    if len(points) > max_points:
        points = points[np.linspace(0, len(points) - 1, max_points).astype(int)]
    return points


def hand_points(robot, hand_samples: np.ndarray, configurations: np.ndarray) -> np.ndarray:
    """World points of the open hand's samples (hand frame) at each configuration."""
    Q = np.atleast_2d(configurations)
    if len(Q) == 0:
        return np.zeros((0, 3))
    hand = robot.link_index(robot.hand_link)
    H = np.stack([robot.fk(q)[hand] for q in Q])
    return (np.einsum("kij,mj->kmi", H[:, :3, :3], hand_samples) + H[:, None, :3, 3]).reshape(-1, 3)


def _marker(ns: str, kind: int, points: np.ndarray, color: Sequence[float], scale: float, frame: str, stamp) -> Marker:
    m = Marker()
    m.header.frame_id, m.header.stamp = frame, stamp
    m.ns, m.id, m.type, m.action = ns, 0, kind, Marker.ADD
    m.pose.orientation.w = 1.0
    m.scale.x = m.scale.y = m.scale.z = float(scale)
    m.color = ColorRGBA(r=float(color[0]), g=float(color[1]), b=float(color[2]), a=float(color[3]))
    m.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in np.asarray(points, float)]
    return m


def pick_markers(outcome: PickOutcome, frame: str, stamp, max_goal_hands: int = 40) -> MarkerArray:
    """The markers of one request's outcome (see the module doc); only DELETEALL without a world."""
    clear = Marker()
    clear.header.frame_id, clear.header.stamp, clear.action = frame, stamp, Marker.DELETEALL
    out = MarkerArray(markers=[clear])
    world = outcome.world
    if world is None:
        return out
    grid = world.perceived.obstacles
    if grid is not None:
        out.markers.append(
            _marker("field", Marker.CUBE_LIST, field_surface(grid), FIELD_COLOR, grid.resolution, frame, stamp)
        )
    out.markers.append(
        _marker("target", Marker.POINTS, world.perceived.target_points[::4], TARGET_COLOR, 0.004, frame, stamp)
    )
    result = outcome.result
    if result is None or len(result.goal_set) == 0:
        return out
    samples = world.hand_points[0][::3]
    goals = np.asarray(result.goal_set)
    shown = goals[np.unique(np.linspace(0, len(goals) - 1, min(max_goal_hands, len(goals))).astype(int))]
    robot = world.robot
    out.markers.append(
        _marker("goal_set", Marker.POINTS, hand_points(robot, samples, shown), GOAL_COLOR, 0.003, frame, stamp)
    )
    chosen: Optional[np.ndarray] = goals[result.goal_source] if result.goal_source >= 0 else None
    if chosen is not None:
        out.markers.append(
            _marker(
                "chosen_grasp", Marker.POINTS, hand_points(robot, samples, chosen), CHOSEN_COLOR, 0.005, frame, stamp
            )
        )
    if result.refined:
        out.markers.append(
            _marker(
                "refined_grasp",
                Marker.POINTS,
                hand_points(robot, samples, result.goal),
                REFINED_COLOR,
                0.005,
                frame,
                stamp,
            )
        )
    task = outcome.task
    if task is not None and outcome.place is not None:
        out.markers.append(
            _marker(
                "place_region",
                Marker.LINE_LIST,
                box_edges(outcome.place.region_min, outcome.place.region_max),
                PLACE_COLOR,
                0.004,
                frame,
                stamp,
            )
        )
        if task.place is not None and task.place.success:
            out.markers.append(
                _marker(
                    "place",
                    Marker.POINTS,
                    hand_points(robot, samples, task.place.goal),
                    PLACE_COLOR,
                    0.005,
                    frame,
                    stamp,
                )
            )
    return out
