"""A 3D view of a plan with meshcat (three.js in the browser): the table and the objects of the scene,
the robot moving along the trajectory (a time slider: Animations > default > time), the goal set
as hand poses, the chosen and the refined grasp, and the body points that penetrate an obstacle.

``build_view`` turns a scene and a ``plan.json`` record into meshcat commands; ``sim.view_page``
writes them as a self-contained page or serves them live.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import List

import meshcat
import meshcat.geometry as mg
import numpy as np
import trimesh
from meshcat.animation import Animation

from pickplan.core import objects
from pickplan.core.robots import DescribedRobot, load_robot
from pickplan.sim.scenes import Scene

# Colours (0xRRGGBB): what a person tells apart at a glance.
TABLE_COLOR = 0x9C7A54
TARGET_COLOR = 0xF2C230
OBJECT_COLORS = (0x4C78A8, 0xB279A2, 0x72B7B2, 0x7F7F7F, 0xD37295, 0x3B4CC0, 0x6B4C9A)  # none like a marker colour
ROBOT_COLOR, HAND_COLOR = 0xE8E8E8, 0x505050
GOAL_COLOR, CHOSEN_COLOR, REFINED_COLOR = 0x6FA8DC, 0xFF7F0E, 0x2CA02C
COLLISION_COLOR = (1.0, 0.0, 0.0)

LEGEND = (
    ("target object", TARGET_COLOR),
    ("goal set (hand poses)", GOAL_COLOR),
    ("chosen grasp", CHOSEN_COLOR),
    ("refined grasp", REFINED_COLOR),
    ("collision points", 0xFF0000),
)


@dataclass(frozen=True)
class ViewSettings:
    seconds_per_waypoint: float = 0.15  # plan.json has no timing: a steady pace through the waypoints
    substeps: int = 4  # joint-space samples per waypoint (three.js interpolates poses linearly)
    max_goal_hands: int = 40  # goal-set hands drawn; larger sets are thinned evenly
    goal_opacity: float = 0.25
    collision_point_size: float = 0.012  # m


@dataclass
class PlanView:
    """The meshcat commands that draw one plan, in the order a viewer must apply them."""

    commands: list
    duration: float  # seconds of robot motion
    title: str


class _Recorder:
    """A meshcat window that keeps the commands instead of sending them to a server."""

    def __init__(self):
        self.commands: list = []

    def send(self, command) -> None:
        self.commands.append(command)


def read_plan(folder: str) -> tuple:
    """The scene and the plan record in ``folder`` (``scene.json``, ``plan.json``), checked."""
    scene_path, plan_path = os.path.join(folder, "scene.json"), os.path.join(folder, "plan.json")
    if not os.path.isdir(folder):
        raise FileNotFoundError(f"plan folder not found: {folder}")
    if not os.path.isfile(plan_path):
        raise FileNotFoundError(f"plan file not found: {plan_path} (write one with `pickplan plan --out` or `demo`)")
    scene = Scene.load(scene_path)
    with open(plan_path, "r", encoding="utf-8") as f:
        try:
            plan = json.load(f)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{plan_path}: malformed JSON: {exc}") from exc
    if not isinstance(plan, dict) or "trajectory" not in plan:
        raise ValueError(f"{plan_path}: not a plan record (no 'trajectory')")
    return scene, plan


def _configurations(value, dof: int, what: str) -> np.ndarray:
    Q = np.asarray(value if value is not None else [], dtype=float)
    if Q.size == 0:
        return np.zeros((0, dof))
    Q = Q.reshape(1, -1) if Q.ndim == 1 else Q
    if Q.ndim != 2 or Q.shape[1] != dof or not np.all(np.isfinite(Q)):
        raise ValueError(f"{what}: expected finite configurations of {dof} joint values, got shape {Q.shape}")
    return Q


def _mesh_geometry(mesh: trimesh.Trimesh) -> mg.TriangularMeshGeometry:
    return mg.TriangularMeshGeometry(np.asarray(mesh.vertices), np.asarray(mesh.faces))


def _material(color: int, opacity: float = 1.0) -> mg.MeshLambertMaterial:
    return mg.MeshLambertMaterial(color=color, opacity=opacity, transparent=opacity < 1.0)


class _RobotDrawing:
    """The robot's collision meshes per link (what the planner checks), posed by FK."""

    def __init__(self, robot: DescribedRobot):
        self.robot = robot
        self.meshes = {i: robot.collision_meshes(i) for i in range(len(robot.link_names))}
        self.meshes = {i: m for i, m in self.meshes.items() if m is not None}
        hand = [robot.link_index(robot.hand_link)] + [robot.link_index(f) for f in robot.finger_links]
        self.hand_links = [i for i in hand if i in self.meshes]

    def hand_mesh(self, q: np.ndarray) -> trimesh.Trimesh:
        """Hand and fingers at configuration ``q``, in world coordinates, as one mesh."""
        poses = self.robot.fk(q)
        return trimesh.util.concatenate([self.meshes[i].copy().apply_transform(poses[i]) for i in self.hand_links])


def _thin(Q: np.ndarray, limit: int) -> np.ndarray:
    if len(Q) <= limit:
        return Q
    return Q[np.linspace(0, len(Q) - 1, limit).round().astype(int)]


def _densify(Q: np.ndarray, substeps: int) -> np.ndarray:
    """Joint-space linear interpolation: ``substeps`` samples per waypoint interval."""
    if len(Q) < 2 or substeps <= 1:
        return Q
    s = np.linspace(0.0, len(Q) - 1, (len(Q) - 1) * substeps + 1)
    i = np.minimum(np.floor(s).astype(int), len(Q) - 2)
    w = (s - i)[:, None]
    return (1 - w) * Q[i] + w * Q[i + 1]


def _draw_scene(vis: meshcat.Visualizer, scene: Scene) -> None:
    if scene.table is not None:
        vis["table"].set_object(mg.Box(np.asarray(scene.table.size, dtype=float)), _material(TABLE_COLOR))
        vis["table"].set_transform(np.asarray(scene.table.pose, dtype=float))
    for o in scene.obstacles:  # shelves, bins, MoveIt's objects: the shape's own mesh
        vis["obstacles"][o.name].set_object(_mesh_geometry(o.shape.trimesh()), _material(TABLE_COLOR))
        vis["obstacles"][o.name].set_transform(np.asarray(o.pose, dtype=float))
    others = iter(OBJECT_COLORS * (1 + len(scene.objects) // len(OBJECT_COLORS)))
    for o in scene.objects:
        model = objects.model_from_source(o.name, o.source)
        color = TARGET_COLOR if o.name == scene.target else next(others)
        vis["objects"][o.name].set_object(_mesh_geometry(model.mesh), _material(color))
        vis["objects"][o.name].set_transform(np.asarray(o.pose, dtype=float))


def _draw_grasps(vis: meshcat.Visualizer, drawing: _RobotDrawing, plan: dict, settings: ViewSettings) -> None:
    dof = drawing.robot.dof
    goals = _configurations(plan.get("goal_set"), dof, "goal_set")
    chosen = _configurations(plan.get("chosen_goal"), dof, "chosen_goal")
    if len(chosen):  # drawn apart below, in its own colour
        goals = goals[~np.all(goals == chosen[0], axis=1)]
    goals = _thin(goals, settings.max_goal_hands)
    for i, q in enumerate(goals):
        vis["goal_set"][f"goal_{i:03d}"].set_object(
            _mesh_geometry(drawing.hand_mesh(q)), _material(GOAL_COLOR, settings.goal_opacity)
        )
    # The refined grasp lies within a centimetre of the chosen one: the chosen one is see-through.
    for key, color, opacity in (("chosen_goal", CHOSEN_COLOR, 0.5), ("refined_goal", REFINED_COLOR, 0.85)):
        q = _configurations(plan.get(key), dof, key)
        if len(q):
            vis[key.replace("_goal", "_grasp")].set_object(
                _mesh_geometry(drawing.hand_mesh(q[0])), _material(color, opacity)
            )
    points = np.asarray(plan.get("collision_points") or np.zeros((0, 4)), dtype=float)
    if points.size:
        if points.ndim != 2 or points.shape[1] < 3:
            raise ValueError(f"collision_points: expected rows of x, y, z(, waypoint), got shape {points.shape}")
        xyz = points[:, :3].T.astype(np.float32)
        colors = np.tile(np.asarray(COLLISION_COLOR, dtype=np.float32)[:, None], (1, xyz.shape[1]))
        vis["collision_points"].set_object(mg.PointCloud(xyz, colors, size=settings.collision_point_size))


def _draw_robot(
    vis: meshcat.Visualizer, drawing: _RobotDrawing, trajectory: np.ndarray, settings: ViewSettings
) -> tuple:
    robot = drawing.robot
    names = robot.link_names
    hand = set(drawing.hand_links)
    for i, mesh in drawing.meshes.items():
        vis["robot"][names[i]].set_object(_mesh_geometry(mesh), _material(HAND_COLOR if i in hand else ROBOT_COLOR))
    Q = _densify(trajectory, settings.substeps)
    poses = robot.fk_batch(Q)  # (T, links, 4, 4)
    for i in drawing.meshes:
        vis["robot"][names[i]].set_transform(poses[0, i])
    fps = settings.substeps / settings.seconds_per_waypoint
    animation = Animation(default_framerate=fps)
    for k in range(len(Q)):
        with animation.at_frame(vis, k) as frame:
            for i in drawing.meshes:
                frame["robot"][names[i]].set_transform(poses[k, i])
    return animation, (len(Q) - 1) / fps


def _animate_held(
    vis: meshcat.Visualizer,
    animation: Animation,
    robot: DescribedRobot,
    trajectory: np.ndarray,
    scene: Scene,
    held: dict,
    settings: ViewSettings,
) -> None:
    """The held object moves with the hand from waypoint ``held["from"]`` (the grasp) to ``held["to"]``
    (the release) and rests at ``held["place_pose"]`` after it (a pick-and-place plan's ``held``)."""
    name = str(held.get("name", scene.target))
    T = np.asarray(held.get("hand_T_object"), dtype=float)
    first, last = int(held.get("from", 0)), int(held.get("to", len(trajectory) - 1))
    if T.shape != (4, 4) or not 0 <= first <= last < len(trajectory):
        raise ValueError(f"held: expected hand_T_object (4, 4) and 0 <= from <= to < {len(trajectory)}")
    start = np.asarray(scene.object(name).pose, dtype=float)
    placed = np.asarray(held.get("place_pose", np.nan * np.eye(4)), dtype=float)
    Q = _densify(trajectory, settings.substeps)
    hands = robot.fk_batch(Q)[:, robot.link_index(robot.hand_link)]
    for k in range(len(Q)):
        waypoint = k / max(1, settings.substeps)
        pose = (
            start
            if waypoint < first
            else (hands[k] @ T if waypoint <= last or not np.all(np.isfinite(placed)) else placed)
        )
        with animation.at_frame(vis, k) as frame:
            frame["objects"][name].set_transform(pose)


def _set_camera(vis: meshcat.Visualizer, scene: Scene) -> None:
    """Look at the middle of the objects from the front right, above the table."""
    centres = np.array([np.asarray(o.pose, dtype=float)[:3, 3] for o in scene.objects])
    focus = centres.mean(axis=0) if len(centres) else np.asarray(scene.robot_base, dtype=float)[:3, 3]
    focus = focus + np.array([-0.1, 0.0, 0.1])
    vis["/Cameras/default"].set_transform(trimesh.transformations.translation_matrix(focus))
    offset = np.array([0.75, 0.65, 0.55])  # world (x, y, z) from the focus; meshcat's camera frame is y-up
    vis["/Cameras/default/rotated/<object>"].set_property("position", [offset[0], offset[2], -offset[1]])


def build_view(scene: Scene, plan: dict, settings: ViewSettings = ViewSettings(), title: str = "pickplan") -> PlanView:
    """The meshcat commands that draw ``scene`` and the plan record ``plan`` (``plan.json``'s content), for
    the robot the plan names (``plan["robot"]``; the Panda for plans written before robots were named)."""
    robot = load_robot(str(plan.get("robot", "panda")), np.asarray(scene.robot_base, dtype=float))
    trajectory = _configurations(plan.get("trajectory"), robot.dof, "trajectory")
    if len(trajectory) == 0:
        raise ValueError("trajectory: the plan has no waypoints")
    recorder = _Recorder()
    root = meshcat.Visualizer(window=recorder)
    root["/Grid"].set_property("visible", False)  # the table is the floor that matters
    root["/Axes"].set_property("visible", False)
    vis = root["pickplan"]
    _draw_scene(vis, scene)
    drawing = _RobotDrawing(robot)
    _draw_grasps(vis, drawing, plan, settings)
    animation, duration = _draw_robot(vis, drawing, trajectory, settings)
    if plan.get("held"):  # a pick and place: the object carried and put down
        _animate_held(vis, animation, robot, trajectory, scene, plan["held"], settings)
    _set_camera(root, scene)
    # Not played on opening: a playing animation redraws every frame, which a software renderer
    # (a headless browser, a remote desktop) cannot keep up with; play and the time slider are in view.
    root.set_animation(animation, play=False, repetitions=1)
    return PlanView(recorder.commands, duration, title)


def view_folder(folder: str, settings: ViewSettings = ViewSettings()) -> PlanView:
    """``build_view`` for a folder written by ``pickplan demo`` or ``pickplan plan --out``."""
    scene, plan = read_plan(folder)
    status = plan.get("status", "?")
    return build_view(scene, plan, settings, title=f"pickplan: {os.path.basename(os.path.abspath(folder))} ({status})")


def legend_entries() -> List[tuple]:
    """(label, '#rrggbb') pairs the page shows beside the view."""
    return [(label, f"#{color:06x}") for label, color in LEGEND]
