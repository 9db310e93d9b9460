"""Cluttered tabletop scenes: seeded generation in PyBullet, a JSON record, and reloading.

Conventions (other modules rely on them):

* world frame = the scene's robot base frame (``robot_base`` = identity); the robot (``Scene.robot``:
  a description's name, the Panda by default) stands at its description's base pose in it;
* the table is a box whose top surface is the plane z = 0, spanning x in [-0.2, 1.1], y in
  [-0.8, 0.8], 0.05 m thick (``Table.pose`` is the pose of the box centre);
* objects are dropped in the reachable area x in [0.35, 0.75], y in [-0.35, 0.35];
* ``SceneObject.pose`` maps the object (mesh) frame into the world, like ``ObjectModel.resting_poses``.

>>> scene = generate_scene(seed=3)
>>> scene.save("out/scene_3.json"); Scene.load("out/scene_3.json").target
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.graspability import graspability
from pickplan.core.description import RobotInfo, load_description
from pickplan.core.panda import PANDA
from pickplan.core.errors import InputError
from pickplan.core.io import atomic_open
from pickplan.core.settings import Option
from pickplan.core.shapes import Obstacle
from pickplan.sim.bodies import _inertial_frame, _mat_to_quat, _panda_defaults, _quat_to_mat  # noqa: F401 (re-exported)
from pickplan.sim.bodies import add_object_body, add_obstacle_body, add_robot, add_table, object_pose  # noqa: F401
from pickplan.sim.scene_checks import SCENE_FORMAT, SCENE_VERSION, check_placement, read_scene  # noqa: F401


class Orientation(Option):
    """How generated scenes pose their objects (``SceneSettings.orientation``)."""

    upright = "upright"  # the paper's "random upright poses": the resting pose with model +z closest to up
    stable = "stable"  # a resting pose drawn with the probability a random drop ends on it
    resting = "resting"  # any sufficiently stable resting pose, drawn uniformly


ORIENTATIONS = tuple(o.value for o in Orientation)


@dataclass(frozen=True)
class SceneSettings:
    """How scenes are generated; every field has the default used for the benchmark sets."""

    min_objects: int = 3
    max_objects: int = 7
    region_x: Tuple[float, float] = (0.35, 0.75)  # where object centres are dropped
    region_y: Tuple[float, float] = (-0.35, 0.35)
    table_x: Tuple[float, float] = (-0.2, 1.1)
    table_y: Tuple[float, float] = (-0.8, 0.8)
    table_thickness: float = 0.05
    drop_height: float = 0.005  # gap between the object's lowest point and the table at release
    spawn_gap: float = 0.005  # minimum gap between footprint circles at release
    # "upright" (the paper: "random upright poses"): every object stands on the resting pose that keeps
    # its model +z closest to up; "stable": a resting pose drawn with the probability that a random
    # drop ends on it (core.stability), among those that tip with at least min_barrier of COM rise;
    # "resting": any sufficiently stable resting pose (lying boxes, upside-down bowls), drawn uniformly
    # among those passing both settings below.
    orientation: Orientation = Orientation.upright
    min_barrier: float = 0.002  # resting poses that tip with less COM rise (m) are not sampled
    barrier_fraction: float = 0.1  # ... nor those below this fraction of the most stable one's
    time_step: float = 1.0 / 240.0
    max_settle_time: float = 2.0  # seconds of simulation per settling round
    settle_speed: float = 0.005  # m/s; below this (and settle_spin) an object counts as at rest
    settle_spin: float = 0.05  # rad/s
    max_tilt_deg: float = 15.0  # more than this away from the sampled upright = tipped over
    max_lift: float = 0.005  # lowest point higher than this above the table = not resting on it
    robot_clearance: float = 0.01  # objects closer than this to the robot are discarded
    friction: float = 0.8
    max_attempts: int = 20
    # The robot the scene is made for (a shipped description's name, a short name or a .toml file):
    # it stands at its start while objects settle (objects touching it are discarded) and its gripper's
    # opening decides which objects can be the target.
    robot: str = "panda"
    robot_configuration: Optional[Tuple[float, ...]] = None  # None: the robot's start (description)
    # The target is drawn among the objects its gripper can grasp as they lie (core.graspability),
    # of this opening (None: the scene robot's, its description's max_opening); when none can be, among all.
    gripper_opening: Optional[float] = None

    def __post_init__(self):
        if self.orientation not in ORIENTATIONS:  # a spelling converts; the message keeps its old words
            raise ValueError(f"orientation: expected one of {list(ORIENTATIONS)}, got {self.orientation!r}")
        object.__setattr__(self, "orientation", Orientation(self.orientation))
        if not 1 <= self.min_objects <= self.max_objects:
            raise ValueError(f"need 1 <= min_objects <= max_objects, got {self.min_objects}, {self.max_objects}")
        for name in ("region_x", "region_y", "table_x", "table_y"):
            lo, hi = getattr(self, name)
            if not lo < hi:
                raise ValueError(f"{name}: expected (low, high) with low < high, got {(lo, hi)}")


@dataclass(eq=False)
class Table:
    size: np.ndarray  # (3,) box extents
    pose: np.ndarray  # (4, 4) pose of the box centre; the top face is at z = 0 by convention


@dataclass(eq=False)
class SceneObject:
    name: str
    source: str  # "builtin:NAME" or the object's folder
    pose: np.ndarray  # (4, 4) object frame -> world


@dataclass(eq=False)
class Scene:
    robot_base: np.ndarray
    table: Optional[Table]  # None: no table (a MoveIt scene of obstacles only)
    objects: List[SceneObject]
    target: Optional[str]  # None: no target (nothing to grasp, e.g. a motion problem)
    seed: Optional[int] = None
    robot_configuration: List[float] = field(default_factory=list)  # the start configuration (of ``robot``)
    robot: str = PANDA.name  # the description the scene was made for (its robot_configuration's robot)
    obstacles: List[Obstacle] = field(default_factory=list)  # static shapes: shelves, bins, MoveIt's objects

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"no object {name!r} in scene; objects: {[o.name for o in self.objects]}")

    # --- JSON ---------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        return {
            "format": SCENE_FORMAT,
            "version": SCENE_VERSION,
            "seed": self.seed,
            "robot_base": np.asarray(self.robot_base, dtype=float).tolist(),
            "robot_configuration": [float(x) for x in self.robot_configuration],
            "table": None
            if self.table is None
            else {
                "size": np.asarray(self.table.size, dtype=float).tolist(),
                "pose": np.asarray(self.table.pose, dtype=float).tolist(),
            },
            "objects": [
                {"name": o.name, "source": o.source, "pose": np.asarray(o.pose, dtype=float).tolist()}
                for o in self.objects
            ],
            "target": self.target,
            **({} if self.robot == PANDA.name else {"robot": self.robot}),  # the Panda's files: as before
            **({"obstacles": [o.to_dict() for o in self.obstacles]} if self.obstacles else {}),
        }

    def to_json(self) -> str:
        # Python writes the shortest repr that round-trips, so floats come back bit-identical.
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d, path: Optional[str] = None) -> "Scene":
        """The scene of a parsed scene file; InputError naming ``path`` and every field at fault."""
        v = read_scene(d, path)
        table = None if v["size"] is None else Table(size=v["size"], pose=v["table_pose"])
        scene = cls(
            robot_base=v["robot_base"],
            table=table,
            objects=[SceneObject(*o) for o in v["objects"]],
            target=v["target"],
            seed=v["seed"],
            robot_configuration=v["robot_configuration"],
            robot=v["robot"],
            obstacles=v["obstacles"],
        )
        check_placement(scene, path=path)
        return scene

    @classmethod
    def from_json(cls, text: str, path: Optional[str] = None) -> "Scene":
        try:
            data = json.loads(text)
        except ValueError as exc:  # JSONDecodeError, or an integer of more digits than Python converts
            raise InputError(f"malformed scene JSON: {exc}", path=path) from None
        except RecursionError:  # the decoder recurses once per level of nesting
            raise InputError("malformed scene JSON: nested too deeply", path=path) from None
        return cls.from_dict(data, path)

    def save(self, path: str) -> None:
        with atomic_open(path, "w") as f:
            f.write(self.to_json())

    @classmethod
    def load(cls, path: str) -> "Scene":
        path = os.fspath(path)
        if not os.path.isfile(path):
            raise FileNotFoundError(f"scene file not found: {path}")
        try:
            with open(path, "r", encoding="utf-8") as f:
                text = f.read()
        except UnicodeDecodeError as exc:
            raise InputError(f"not UTF-8 text ({exc.reason} at byte {exc.start})", path=path) from None
        return cls.from_json(text, path)


def load_into_pybullet(
    scene: Scene, client: int, library: Optional[objects_mod.ObjectLibrary] = None, with_robot: bool = True
) -> Dict[str, int]:
    """Recreate ``scene`` in ``client``: body ids by object name, plus "table" and "robot"."""
    ids = {} if scene.table is None else {"table": add_table(client, scene.table)}
    for o in scene.obstacles:
        ids[o.name] = add_obstacle_body(client, o)
    if with_robot:
        if scene.robot == PANDA.name:
            ids["robot"] = add_robot(client, scene.robot_base, scene.robot_configuration)
        else:
            desc = load_description(scene.robot)
            ids["robot"] = add_robot(
                client,
                np.asarray(scene.robot_base, dtype=float) @ desc.base_pose,
                scene.robot_configuration or RobotInfo.from_description(desc).ready,
                desc.urdf,
            )
    for o in scene.objects:
        model = library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)
        ids[o.name] = add_object_body(client, model, o.pose)
    return ids


# --- generation ----------------------------------------------------------------------------------
def default_table(settings: SceneSettings = SceneSettings()) -> Table:
    """The table box: top face at z = 0 spanning ``table_x`` x ``table_y``."""
    (x0, x1), (y0, y1), t = settings.table_x, settings.table_y, settings.table_thickness
    pose = np.eye(4)
    pose[:3, 3] = [(x0 + x1) / 2, (y0 + y1) / 2, -t / 2]
    return Table(size=np.array([x1 - x0, y1 - y0, t]), pose=pose)


def _allowed_poses(model: objects_mod.ObjectModel, settings: SceneSettings) -> List[int]:
    """Indices of the resting poses to sample from. "upright": the one whose model +z points most
    nearly up; "stable" and "resting": those stable enough (the most stable one always qualifies)."""
    if settings.orientation is Orientation.upright:
        return [int(np.argmax([pose[2, 2] for pose in model.resting_poses]))]
    if settings.orientation is Orientation.stable:
        b = model.resting_barriers or [1.0]
        return [i for i in range(min(len(b), len(model.resting_poses))) if i == 0 or b[i] >= settings.min_barrier]
    b = np.asarray(model.resting_barriers if model.resting_barriers else [1.0], dtype=float)
    floor = max(settings.min_barrier, settings.barrier_fraction * b[0])
    return [i for i in range(min(len(b), len(model.resting_poses))) if i == 0 or b[i] >= floor]


def _sample_pose(rng: np.random.Generator, model: objects_mod.ObjectModel, settings: SceneSettings) -> int:
    """One resting pose index: uniform over the allowed ones, or by drop probability for "stable"."""
    allowed = _allowed_poses(model, settings)
    probabilities = model.resting_probabilities
    if settings.orientation is not Orientation.stable or len(probabilities) < len(model.resting_poses):
        return allowed[int(rng.integers(len(allowed)))]
    p = np.asarray([probabilities[i] for i in allowed], dtype=float)
    if p.sum() <= 0:
        return allowed[int(rng.integers(len(allowed)))]
    return allowed[int(rng.choice(len(allowed), p=p / p.sum()))]


def _hull_points(model: objects_mod.ObjectModel) -> np.ndarray:
    return np.asarray(model.mesh.convex_hull.vertices, dtype=float)  # trimesh caches the hull


@dataclass
class _Placed:
    name: str
    model: objects_mod.ObjectModel
    body: int
    up: np.ndarray  # the world's up direction in the object frame when it was dropped


def _settle(client: int, bodies: Sequence[int], settings: SceneSettings) -> None:
    from pickplan.sim.bullet import pb

    chunk = max(1, int(round(0.1 / settings.time_step)))
    for i in range(max(2, int(math.ceil(settings.max_settle_time / 0.1)))):
        for _ in range(chunk):
            pb.stepSimulation(physicsClientId=client)
        if i == 0:
            continue  # give every object at least 0.2 s to land
        still = True
        for b in bodies:
            v, w = pb.getBaseVelocity(b, physicsClientId=client)
            if np.linalg.norm(v) > settings.settle_speed or np.linalg.norm(w) > settings.settle_spin:
                still = False
                break
        if still:
            return


def _resting_ok(client: int, p: _Placed, robot: int, table: Table, settings: SceneSettings) -> bool:
    """On the table, upright as dropped, touching the table and clear of the robot."""
    from pickplan.sim.bullet import pb

    T = object_pose(client, p.body, p.model)
    up_now = T[:3, :3] @ p.up
    if up_now[2] < math.cos(math.radians(settings.max_tilt_deg)):
        return False
    lo = table.pose[:3, 3] - np.asarray(table.size) / 2
    hi = table.pose[:3, 3] + np.asarray(table.size) / 2
    com = T[:3, :3] @ p.model.com + T[:3, 3]
    if not (lo[0] <= com[0] <= hi[0] and lo[1] <= com[1] <= hi[1]):
        return False
    lowest = float(np.min(_hull_points(p.model) @ T[:3, :3].T[:, 2] + T[2, 3]))
    if not -settings.max_lift <= lowest - hi[2] <= settings.max_lift:
        return False
    if robot >= 0 and pb.getClosestPoints(p.body, robot, settings.robot_clearance, physicsClientId=client):
        return False
    return True


def generate_scene(seed: int, library=None, settings: SceneSettings = SceneSettings()) -> Scene:
    """Drop 3-7 sampled objects in front of ``settings.robot`` (the Panda by default), let them settle,
    keep those resting upright; the target is one its gripper can grasp.

    ``library``: an ``ObjectLibrary``, a YCB-layout folder, or None (``objects.library()``: the
    built-ins or $PICKPLAN_YCB_DIR). Same seed, library and settings -> the identical scene: every
    random draw comes from one ``default_rng(seed)`` and PyBullet runs in a fresh DIRECT client.
    """
    from pickplan.sim.bullet import connect, pb

    lib = library if isinstance(library, objects_mod.ObjectLibrary) else objects_mod.library(library)
    if len(lib) < settings.min_objects:
        raise ValueError(f"library {lib.source} has {len(lib)} objects, fewer than min_objects={settings.min_objects}")
    rng = np.random.default_rng(seed)
    table = default_table(settings)
    desc = load_description(settings.robot)
    info = RobotInfo.from_description(desc)
    q = settings.robot_configuration or info.ready
    if len(q) != len(info.ready):
        raise ValueError(f"robot_configuration: expected {len(info.ready)} joint values ({info.name}), got {len(q)}")
    (x0, x1), (y0, y1) = settings.region_x, settings.region_y
    client = connect()
    try:
        pb.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=client)
        pb.setGravity(0, 0, -9.81, physicsClientId=client)
        pb.setTimeStep(settings.time_step, physicsClientId=client)
        add_table(client, table, settings.friction)
        robot = add_robot(client, desc.base_pose, q, None if info.name == PANDA.name else desc.urdf)
        kept: List[_Placed] = []
        for _attempt in range(settings.max_attempts):
            n = min(int(rng.integers(settings.min_objects, settings.max_objects + 1)), len(lib))
            names = [lib.names[i] for i in rng.choice(len(lib), size=n, replace=False)]
            placed, circles = [], []
            for name in names:
                model = lib.get(name)
                rest = model.resting_poses[_sample_pose(rng, model, settings)]
                yaw = rng.uniform(-math.pi, math.pi)
                radius = float(
                    np.max(np.linalg.norm((_hull_points(model) @ rest[:3, :3].T)[:, :2] + rest[:2, 3], axis=1))
                )
                for _ in range(50):  # rejection sampling of a free spot; the object is skipped if none
                    xy = rng.uniform([x0, y0], [x1, y1])
                    if all(np.linalg.norm(xy - c) >= radius + r + settings.spawn_gap for c, r in circles):
                        break
                else:
                    continue
                circles.append((xy, radius))
                Rz = np.eye(4)
                Rz[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
                T = Rz @ rest
                T[:3, 3] += [xy[0], xy[1], settings.drop_height]
                body = add_object_body(client, model, T, settings.friction)
                placed.append(_Placed(name, model, body, rest[2, :3].copy()))
            kept = _settle_and_filter(client, placed, robot, table, settings)
            if len(kept) >= settings.min_objects:
                break
            for p in kept:
                pb.removeBody(p.body, physicsClientId=client)
            kept = []
        else:
            raise RuntimeError(
                f"seed {seed}: fewer than {settings.min_objects} objects came to rest in "
                f"{settings.max_attempts} attempts"
            )
        objs = [SceneObject(p.name, p.model.source, object_pose(client, p.body, p.model)) for p in kept]
        opening = settings.gripper_opening or info.max_opening
        candidates = [o for o, p in zip(objs, kept) if graspability(p.model, o.pose, opening).graspable] or objs
        target = candidates[int(rng.integers(len(candidates)))].name
    finally:
        pb.disconnect(client)
    return Scene(
        robot_base=np.eye(4),
        table=table,
        objects=objs,
        target=target,
        seed=None if seed is None else int(seed),
        robot_configuration=[float(v) for v in q],
        robot=info.name,
    )


def _settle_and_filter(
    client: int, placed: List[_Placed], robot: int, table: Table, settings: SceneSettings
) -> List[_Placed]:
    """Settle, drop the objects that fell, tipped or touch the robot, and settle again until none go.

    Returns [] when the survivors still do not come to rest (the caller then re-samples).
    """
    from pickplan.sim.bullet import pb

    kept = list(placed)
    for _round in range(3):
        _settle(client, [p.body for p in kept], settings)
        bad = [p for p in kept if not _resting_ok(client, p, robot, table, settings)]
        if not bad:
            return kept
        for p in bad:
            pb.removeBody(p.body, physicsClientId=client)
        kept = [p for p in kept if p not in bad]
    for p in kept:
        pb.removeBody(p.body, physicsClientId=client)
    return []
