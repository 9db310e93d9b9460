"""Scene families beyond the tabletop, seeded: a shelf (boards at several heights, objects on them,
reached from the front), a bin (walls on the table, objects inside, reached from above) and a cabinet
(an open door, a pulled-out drawer, objects on its inner board, as in the OMG authors' kitchen demo).

The furniture is ``shapes.Obstacle`` boxes. The board or floor the target stands on is the scene's
``table`` (the support surface the planner lets the fingers rest on and the success test measures);
the other boards are obstacles marked ``support``. Objects stand on their resting poses (exact:
their lowest point on the board), spaced apart; the target is one the gripper can grasp as it stands
and the robot can reach there, clear of everything, with room to back off and lift
(``sim.target_access``; as MotionBenchMaker keeps only problems with a valid goal).

>>> scene = generate_layout(Layout.shelf, seed=3)
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Optional, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.description import RobotInfo, load_description
from pickplan.core.graspability import graspability
from pickplan.core.settings import Option
from pickplan.core.shapes import Obstacle, Shape
from pickplan.sim.execution import ExecutionSettings
from pickplan.sim.scenes import Scene, SceneObject, Table, default_table
from pickplan.sim.target_access import AccessSettings, target_access

THICKNESS = 0.02  # m: boards, walls, doors
# m under the board above an object: execution's shortest lift, its clearance, and 1 cm between
LIFT_ROOM = ExecutionSettings.min_lift + ExecutionSettings.lift_clearance + 0.01


class Layout(Option):
    table = "table"  # today's tabletop (sim.scenes.generate_scene)
    shelf = "shelf"
    bin = "bin"
    cabinet = "cabinet"


@dataclass(frozen=True)
class LayoutSettings:
    min_objects: int = 2  # on the target's support
    max_objects: int = 4
    other_objects: int = 2  # at most this many on the other boards (shelf)
    gap: float = 0.03  # m between objects' footprint circles
    robot: str = "panda"
    # the target must pass ``sim.target_access`` (a grasp the robot reaches clear of everything, with room to
    # back off and lift); None: any object the gripper can grasp as it stands (``core.graspability``)
    access: Optional[AccessSettings] = AccessSettings()


def _pose(R: np.ndarray, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


class _Furniture:
    """Boxes in a frame F (x away from the robot, y across, z up; origin on the floor at the front
    centre), placed in the world by F."""

    def __init__(self, F: np.ndarray, prefix: str):
        self.F, self.prefix, self.boxes = F, prefix, []

    def box(self, name: str, size, centre, R: np.ndarray = np.eye(3), support: bool = False) -> Obstacle:
        o = Obstacle(f"{self.prefix}{name}", Shape.box(*size), self.F @ _pose(R, centre), support)
        self.boxes.append(o)
        return o


def _table_of(board: Obstacle) -> Table:
    return Table(size=np.array(board.shape.size), pose=np.array(board.pose))


def _shelf(rng, F) -> Tuple[_Furniture, List[Obstacle], List[float]]:
    depth, width = rng.uniform(0.3, 0.4), rng.uniform(0.7, 0.9)
    low, gap = rng.uniform(0.05, 0.2), rng.uniform(0.3, 0.38)
    tops = [low + k * gap for k in range(3)]
    top = tops[-1] + gap
    f = _Furniture(F, "shelf_")
    boards = [
        f.box(f"board{k}", (depth, width, THICKNESS), (depth / 2, 0, h - THICKNESS / 2), support=True)
        for k, h in enumerate(tops + [top])
    ]
    for side, y in (("left", 1), ("right", -1)):
        f.box(side, (depth, THICKNESS, top), (depth / 2, y * (width + THICKNESS) / 2, top / 2))
    f.box("back", (THICKNESS, width + 2 * THICKNESS, top), (depth + THICKNESS / 2, 0, top / 2))
    return f, boards[:-1], [gap - THICKNESS] * len(tops)


def _cabinet(rng, F) -> Tuple[_Furniture, List[Obstacle], List[float]]:
    depth, width, height = rng.uniform(0.35, 0.42), rng.uniform(0.5, 0.6), rng.uniform(0.75, 0.85)
    shelf_z = rng.uniform(0.35, 0.42)
    f = _Furniture(F, "cabinet_")
    board = f.box("board", (depth, width, THICKNESS), (depth / 2, 0, shelf_z - THICKNESS / 2), support=True)
    f.box("top", (depth, width + 2 * THICKNESS, THICKNESS), (depth / 2, 0, height - THICKNESS / 2))
    for side, y in (("left", 1), ("right", -1)):
        f.box(side, (depth, THICKNESS, height), (depth / 2, y * (width + THICKNESS) / 2, height / 2))
    f.box("back", (THICKNESS, width + 2 * THICKNESS, height), (depth + THICKNESS / 2, 0, height / 2))
    # The door hangs on the left side's front edge, opened by 100-130 degrees towards the robot's left.
    open_angle = math.radians(rng.uniform(100, 130))
    hinge = np.array([0.0, width / 2 + THICKNESS, 0.0])
    R = _rz(open_angle)
    f.box(
        "door",
        (THICKNESS, width + 2 * THICKNESS, height - shelf_z + 0.05),
        hinge
        + R @ np.array([-THICKNESS / 2, -(width + 2 * THICKNESS) / 2, 0.0])
        + [0, 0, (height + shelf_z - 0.05) / 2],
        R,
    )
    # The drawer below the board, pulled out towards the robot: a front, a floor and two sides.
    out, drawer_h = rng.uniform(0.12, 0.22), shelf_z - 0.12
    f.box("drawer_front", (THICKNESS, width, drawer_h), (-out, 0, 0.05 + drawer_h / 2))
    f.box("drawer_floor", (depth, width - 0.02, THICKNESS), (depth / 2 - out, 0, 0.06))
    for side, y in (("drawer_left", 1), ("drawer_right", -1)):
        f.box(
            side, (depth, THICKNESS, drawer_h * 0.6), (depth / 2 - out, y * (width / 2 - 0.02), 0.05 + drawer_h * 0.3)
        )
    return f, [board], [height - THICKNESS - shelf_z]


def _bin(rng) -> Tuple[_Furniture, Table, np.ndarray]:
    table = default_table()
    centre = np.array([rng.uniform(0.5, 0.6), rng.uniform(-0.1, 0.1), 0.0])
    F = _pose(_rz(rng.uniform(-0.4, 0.4)), centre)
    inner = (rng.uniform(0.28, 0.34), rng.uniform(0.36, 0.44))
    wall = rng.uniform(0.1, 0.16)
    f = _Furniture(F, "bin_")
    for name, size, c in (
        ("front", (THICKNESS, inner[1] + 2 * THICKNESS, wall), (-(inner[0] + THICKNESS) / 2, 0)),
        ("back", (THICKNESS, inner[1] + 2 * THICKNESS, wall), ((inner[0] + THICKNESS) / 2, 0)),
        ("left", (inner[0], THICKNESS, wall), (0, (inner[1] + THICKNESS) / 2)),
        ("right", (inner[0], THICKNESS, wall), (0, -(inner[1] + THICKNESS) / 2)),
    ):
        f.box(name, size, (c[0], c[1], wall / 2))
    return f, table, F @ _pose(np.eye(3), (0, 0, 0))


def _place(
    rng,
    lib,
    n: int,
    surface: np.ndarray,
    half: Tuple[float, float],
    clearance: float,
    taken: List[Tuple[np.ndarray, float]],
    gap: float,
    used: set,
) -> List[SceneObject]:
    """Up to ``n`` objects on resting poses within the surface's rectangle (its frame: z up from the top
    face; x in [-half[0], half[0]], y likewise), no taller than ``clearance``, apart from ``taken``; none
    of the models in ``used`` (a scene names each object once), which gains those placed."""
    out = []
    for _ in range(n):
        name = lib.names[int(rng.integers(len(lib)))]
        if name in used:
            continue
        model = lib.get(name)
        rest = model.resting_poses[int(np.argmax([p[2, 2] for p in model.resting_poses]))]  # upright
        T = _pose(_rz(rng.uniform(-math.pi, math.pi)), (0, 0, 0)) @ rest
        hull = np.asarray(model.mesh.convex_hull.vertices) @ T[:3, :3].T + T[:3, 3]
        radius = float(np.max(np.linalg.norm(hull[:, :2], axis=1)))
        if hull[:, 2].max() > clearance or radius > min(half):
            continue
        for _try in range(40):
            xy = rng.uniform(-np.asarray(half) + radius, np.asarray(half) - radius)
            if all(np.linalg.norm(xy - c) >= radius + r + gap for c, r in taken):
                break
        else:
            continue
        taken.append((xy, radius))
        used.add(name)
        T[:2, 3] += xy
        out.append(SceneObject(name, model.source, surface @ T))
    return out


def generate_layout(kind, seed: int, library=None, settings: LayoutSettings = LayoutSettings()) -> Scene:
    """A seeded scene of ``kind`` (a ``Layout``; "table" is ``scenes.generate_scene``'s)."""
    kind = Layout.parse(kind, "layout")
    if kind is Layout.table:
        from pickplan.sim.scenes import generate_scene  # the tabletop family lives there

        return generate_scene(seed, library)
    lib = library if isinstance(library, objects_mod.ObjectLibrary) else objects_mod.library(library)
    rng = np.random.default_rng(seed)
    info = RobotInfo.from_description(load_description(settings.robot))
    for _attempt in range(20):
        scene = _attempt_layout(kind, rng, lib, settings, info)
        if scene is not None:
            scene.seed = int(seed)
            return scene
    raise RuntimeError(f"seed {seed}: no {kind.value} layout with a reachable graspable target in 20 attempts")


def _attempt_layout(kind: Layout, rng, lib, settings: LayoutSettings, info: RobotInfo) -> Optional[Scene]:
    if kind is Layout.bin:
        furniture, table, surface = _bin(rng)
        sx, sy = (furniture.boxes[2].shape.size[0], furniture.boxes[0].shape.size[1] - 2 * THICKNESS)
        supports, clearance = [(surface, (sx / 2 - 0.01, sy / 2 - 0.01), 0.3, True)], 0.3
        obstacles = furniture.boxes
    else:
        dist, yaw = rng.uniform(0.5, 0.62), rng.uniform(-0.35, 0.35)
        F = _pose(_rz(yaw), (dist * math.cos(yaw), dist * math.sin(yaw), 0.0))
        furniture, boards, free = (_shelf if kind is Layout.shelf else _cabinet)(rng, F)
        reachable = [b for b in boards if 0.15 <= b.top_plane()[1] <= 0.75]
        target_board = reachable[int(rng.integers(len(reachable)))]
        table = _table_of(target_board)
        obstacles = [o for o in furniture.boxes if o is not target_board]
        supports = []
        for b, height in zip(boards, free):
            d, w, _ = b.shape.size
            top = b.pose @ _pose(np.eye(3), (0, 0, THICKNESS / 2))
            room = height - LIFT_ROOM  # an object the board above leaves room to lift
            # objects stand in the front part of a board (reached from the front)
            top = top @ _pose(np.eye(3), (-d / 2 + 0.3 * d, 0, 0))
            supports.append((top, (0.28 * d, w / 2 - 0.02), room, b is target_board))
    objs, taken, used = [], [], set()
    for surface, half, clearance, main in supports:
        n = (
            int(rng.integers(settings.min_objects, settings.max_objects + 1))
            if main
            else int(rng.integers(0, settings.other_objects + 1))
        )
        placed = _place(rng, lib, n, surface, half, clearance, [] if not main else taken, settings.gap, used)
        objs += placed
        if main:
            main_objs = placed
    candidates = [
        o
        for o in main_objs
        if graspability(lib.get(o.name), o.pose, info.max_opening, np.asarray(table.pose)[:3, 2]).graspable
    ]
    if len(main_objs) < settings.min_objects or not candidates:
        return None
    scene = Scene(
        robot_base=np.eye(4),
        table=table,
        objects=objs,
        target=None,
        robot_configuration=[float(v) for v in info.ready],
        robot=info.name,
        obstacles=obstacles,
    )
    # the graspable object drawn first, else the others in a seeded order: the first the robot can reach
    first = int(rng.integers(len(candidates)))
    models = {o.name: lib.get(o.name) for o in objs}
    for k in [first] + [int(k) for k in rng.permutation(len(candidates)) if k != first]:
        scene.target = candidates[k].name
        if settings.access is None or target_access(scene, models, settings.access).reachable:
            return scene
    return None
