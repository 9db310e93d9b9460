"""MoveIt's scene files into pickplan's scene model: a PlanningScene as YAML (``sceneNNNN.yaml`` of
MotionBenchMaker, ``rostopic echo`` dumps), the ``.scene`` text RViz's MotionPlanning panel exports,
and a MotionPlanRequest's start state and joint goal (``requestNNNN.yaml``).

Collision objects become ``shapes.Obstacle``s in the planning frame: a box, cylinder or sphere
primitive each (an object of several primitives gives ``id/0``, ``id/1``, ...), and meshes. MoveIt's
conventions: cylinder ``dimensions`` are [height, radius]; a primitive's pose is relative to the
object's ``pose`` when the object has one (MoveIt >= 1.1), else to the planning frame. Cones and
planes have no pickplan shape and are refused by name, as is anything malformed
(``InputError``: the file and the field, e.g. ``scene0001.yaml: world.collision_objects[2].primitives[0].dimensions``).

>>> ms = read_moveit_scene("scene0001.yaml")          # or "kitchen.scene"
>>> scene = ms.to_scene()                             # a Scene with obstacles, no table, no target
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from pickplan.core.errors import InputError
from pickplan.core.fields import FieldReader, shown
from pickplan.core.shapes import Obstacle, Shape, check_unique
from pickplan.sim.scenes import Scene

# moveit_msgs/SolidPrimitive's type constants, and the dimensions each reads (MoveIt's order).
_PRIMITIVE_TYPES = {1: "box", 2: "sphere", 3: "cylinder", 4: "cone"}
_DIMENSIONS = {"box": 3, "sphere": 1, "cylinder": 2}


@dataclass
class MoveItScene:
    """What a MoveIt scene file says: its name, the obstacles, the robot's joint state (name ->
    value), and the pairs the allowed-collision matrix lets touch."""

    name: str
    obstacles: List[Obstacle]
    joint_state: Dict[str, float] = field(default_factory=dict)
    allowed_collisions: Tuple[Tuple[str, str], ...] = ()

    def to_scene(self, robot: str = "panda", joints: Optional[List[str]] = None) -> Scene:
        """A pickplan ``Scene``: these obstacles, no table, no target, the robot at the planning
        frame's origin; its start from the joint state when ``joints`` (the robot's joint names in
        order) are all in it."""
        q = [self.joint_state[j] for j in joints] if joints and all(j in self.joint_state for j in joints) else []
        return Scene(
            robot_base=np.eye(4),
            table=None,
            objects=[],
            target=None,
            robot_configuration=q,
            robot=robot,
            obstacles=list(self.obstacles),
        )


@dataclass(frozen=True)
class MotionRequest:
    """A MotionPlanRequest's start (joint name -> value), joint goal (name -> value) and group."""

    start: Dict[str, float]
    goal: Dict[str, float]
    group: str = ""


def read_moveit_scene(path: str, text: Optional[str] = None) -> MoveItScene:
    """A ``.scene`` text file or a PlanningScene YAML file (by extension); ``text``: its contents
    when they do not come from disk (an archive member), ``path`` then only names it."""
    path = os.fspath(path)
    text = _read(path) if text is None else text
    if path.endswith(".scene"):
        return parse_scene_text(text, path)
    return parse_planning_scene(_yaml(text, path), path)


def read_motion_request(path: str, text: Optional[str] = None) -> MotionRequest:
    path = os.fspath(path)
    data = _yaml(_read(path) if text is None else text, path)
    r = _Fields(path)
    start = r.joint_state(
        r.mapping(r.mapping(data, "start_state", ""), "joint_state", "start_state."), "start_state.joint_state"
    )
    goals = r.listed(data, "goal_constraints", "")
    if not goals:
        raise InputError("no goal constraints", path=path, field="goal_constraints")
    goal = {}
    for k, c in enumerate(r.listed(goals[0], "joint_constraints", "goal_constraints[0].")):
        where = f"goal_constraints[0].joint_constraints[{k}]"
        goal[r.name(c, "joint_name", where + ".")] = r.number_at(c, "position", where + ".")
    if not goal:
        raise InputError(
            "only joint constraints are read, and there are none",
            path=path,
            field="goal_constraints[0].joint_constraints",
        )
    group = data.get("group_name", "") if isinstance(data, dict) else ""
    return MotionRequest(start, goal, str(group or ""))


# --- PlanningScene YAML ------------------------------------------------------------------------------
def parse_planning_scene(data, path: str = "scene.yaml") -> MoveItScene:
    r = _Fields(path)
    if not isinstance(data, dict):
        raise InputError(f"expected a PlanningScene mapping, got {type(data).__name__}", path=path)
    world = r.mapping(data, "world", "", required=False)
    obstacles: List[Obstacle] = []
    for i, obj in enumerate(r.listed(world, "collision_objects", "world.", required=False)):
        obstacles.extend(_collision_object(r, obj, f"world.collision_objects[{i}]"))
    _unique(obstacles, path)
    state = r.mapping(data, "robot_state", "", required=False)
    joints = (
        r.joint_state(r.mapping(state, "joint_state", "robot_state.", required=False), "robot_state.joint_state")
        if state
        else {}
    )
    acm = r.mapping(data, "allowed_collision_matrix", "", required=False)
    return MoveItScene(str(data.get("name") or ""), obstacles, joints, _allowed(r, acm) if acm else ())


def _collision_object(r: "_Fields", obj, where: str) -> List[Obstacle]:
    if not isinstance(obj, dict):
        raise InputError(f"expected a collision object mapping, got {type(obj).__name__}", path=r.path, field=where)
    name = r.name(obj, "id", where + ".")
    operation = obj.get("operation", 0)
    if operation not in (0, "0", "add", "ADD", b"\x00"):
        raise InputError(f"only ADD (0) objects are read, got {operation!r}", path=r.path, field=where + ".operation")
    base = r.pose(obj["pose"], where + ".pose") if "pose" in obj else np.eye(4)
    parts = _posed(r, obj, where, base, "primitives", "primitive_poses", _primitive) + _posed(
        r, obj, where, base, "meshes", "mesh_poses", _mesh_msg
    )
    if r.listed(obj, "planes", where + ".", required=False):
        raise InputError("planes (infinite) have no pickplan shape", path=r.path, field=where + ".planes")
    if not parts:
        raise InputError("a collision object without primitives or meshes", path=r.path, field=where)
    return [Obstacle(name if len(parts) == 1 else f"{name}/{k}", shape, T) for k, (shape, T) in enumerate(parts)]


def _posed(r: "_Fields", obj: dict, where: str, base: np.ndarray, key: str, poses_key: str, make) -> list:
    """(shape, world pose) of each of an object's ``key`` items (primitives, meshes) and their poses."""
    items = r.listed(obj, key, where + ".", required=False)
    poses = r.listed(obj, poses_key, where + ".", required=bool(items))
    if len(poses) != len(items):
        raise InputError(f"{len(items)} {key} but {len(poses)} {poses_key}", path=r.path, field=f"{where}.{poses_key}")
    return [
        (make(r, item, f"{where}.{key}[{k}]"), base @ r.pose(T, f"{where}.{poses_key}[{k}]"))
        for k, (item, T) in enumerate(zip(items, poses))
    ]


def _primitive(r: "_Fields", p, where: str) -> Shape:
    if not isinstance(p, dict):
        raise InputError(f"expected a primitive mapping, got {type(p).__name__}", path=r.path, field=where)
    kind = p.get("type")
    kind = _PRIMITIVE_TYPES.get(kind, kind) if isinstance(kind, int) and not isinstance(kind, bool) else kind
    kind = kind.lower() if isinstance(kind, str) else kind
    if kind not in _DIMENSIONS:
        raise InputError(f"expected box, sphere or cylinder, got {p.get('type')!r}", path=r.path, field=where + ".type")
    dims = r.numbers(p, "dimensions", where + ".", _DIMENSIONS[kind])
    return _shape(kind, dims, r.path, where + ".dimensions")


def _shape(kind: str, dims, path: str, where: str) -> Shape:
    """A Shape from MoveIt's dimensions (a cylinder's are [height, radius] in messages)."""
    try:
        if kind == "cylinder":
            return Shape.cylinder(dims[1], dims[0])
        return Shape.box(*dims) if kind == "box" else Shape.sphere(dims[0])
    except InputError as exc:
        raise InputError(exc.detail, path=path, field=where) from None


def _mesh_msg(r: "_Fields", m, where: str) -> Shape:
    vertices = [
        [r.number_at(v, a, f"{where}.vertices[{i}].") for a in "xyz"]
        if isinstance(v, dict)
        else r.numbers_of(v, 3, f"{where}.vertices[{i}]")
        for i, v in enumerate(r.listed(m, "vertices", where + "."))
    ]
    faces = [
        r.numbers_of(t.get("vertex_indices") if isinstance(t, dict) else t, 3, f"{where}.triangles[{i}]")
        for i, t in enumerate(r.listed(m, "triangles", where + "."))
    ]
    return _inline_mesh(vertices, faces, r.path, where)


def _inline_mesh(vertices, faces, path: str, where: str) -> Shape:
    V, F = np.asarray(vertices, dtype=float).reshape(-1, 3), np.asarray(faces, dtype=float).reshape(-1, 3)
    if len(F) == 0 or np.any(F != np.round(F)) or F.min() < 0 or F.max() >= len(V):
        raise InputError(f"triangles must index the {len(V)} vertices", path=path, field=where + ".triangles")
    try:
        return Shape.inline_mesh(V, F.astype(int))
    except InputError as exc:
        raise InputError(exc.detail, path=path, field=where) from None


def _allowed(r: "_Fields", acm, where: str = "allowed_collision_matrix") -> Tuple[Tuple[str, str], ...]:
    names = [str(n) for n in r.listed(acm, "entry_names", where + ".")]
    rows = r.listed(acm, "entry_values", where + ".")
    if len(rows) != len(names):
        raise InputError(f"{len(names)} entry_names but {len(rows)} rows", path=r.path, field=where + ".entry_values")
    out = []
    for i, row in enumerate(rows):
        values = row.get("enabled") if isinstance(row, dict) else row  # ROS message dumps nest it
        if not isinstance(values, list) or len(values) != len(names) or not all(isinstance(v, bool) for v in values):
            raise InputError(
                f"expected {len(names)} true/false values", path=r.path, field=f"{where}.entry_values[{i}]"
            )
        out.extend((names[i], names[j]) for j in range(i + 1, len(names)) if values[j])
    return tuple(out)


def _unique(obstacles: List[Obstacle], path: str) -> None:
    try:
        check_unique([o.name for o in obstacles], "collision object ids")
    except InputError as exc:
        raise InputError(exc.detail, path=path, field=exc.field) from None


# --- .scene text (RViz export) -----------------------------------------------------------------------
def parse_scene_text(text: str, path: str = "scene.scene") -> MoveItScene:
    """The text of ``PlanningScene::saveGeometryToStream``: a name line, then per object ``* id``,
    [its pose: "x y z" and "qx qy qz qw" lines (the newer format)], a shape count, per shape its type,
    dimensions, pose and colour, [subframes (newer format)]; a line "." ends the scene."""
    lines = text.splitlines()
    if not lines:
        raise InputError("empty file", path=path)
    tokens = _Tokens(lines[1:], path, first_line=2)
    # The newer format puts the object's position ("x y z") right after "* id"; the older its shape count.
    new_format = _newer_format(lines)
    obstacles: List[Obstacle] = []
    while True:
        marker = tokens.word("'*' (an object) or '.' (the end)")
        if marker == ".":
            break
        if marker != "*":
            raise InputError(f"expected '*' or '.', got {marker!r}", path=path, field=f"line {tokens.line}")
        name = tokens.rest_of_line("object id")
        base = tokens.pose(f"object {name!r} pose") if new_format else np.eye(4)
        count = tokens.count(f"object {name!r} shape count")
        parts = []
        for k in range(count):
            where = f"object {name!r} shape {k}"
            shape = _text_shape(tokens, where)
            parts.append((shape, base @ tokens.pose(where + " pose")))
            tokens.numbers(4, where + " colour")
        if new_format:
            for k in range(tokens.count(f"object {name!r} subframe count")):
                tokens.word(f"object {name!r} subframe {k} name")
                tokens.pose(f"object {name!r} subframe {k} pose")
        obstacles += [Obstacle(name if len(parts) == 1 else f"{name}/{k}", s, T) for k, (s, T) in enumerate(parts)]
    _unique(obstacles, path)
    return MoveItScene(lines[0].strip(), obstacles)


def _newer_format(lines: List[str]) -> bool:
    """MoveIt's own test: the line after the first "* id" holds spaces (a position) in the newer format."""
    for i, line in enumerate(lines[1:], start=1):
        if line.strip().startswith("*"):
            return i + 1 < len(lines) and " " in lines[i + 1].strip()
    return False


def _text_shape(tokens: "_Tokens", where: str) -> Shape:
    kind = tokens.word(where + " type")
    if kind in ("box", "sphere", "cylinder"):
        dims = tokens.numbers({"box": 3, "sphere": 1, "cylinder": 2}[kind], where + " dimensions")
        try:  # the text gives a cylinder's radius, then its length
            return (
                Shape.cylinder(*dims)
                if kind == "cylinder"
                else Shape.box(*dims)
                if kind == "box"
                else Shape.sphere(*dims)
            )
        except InputError as exc:
            raise InputError(exc.detail, path=tokens.path, field=f"{where} dimensions (line {tokens.line})") from None
    if kind == "mesh":
        nv, nt = tokens.count(where + " vertex count"), tokens.count(where + " triangle count")
        V = [tokens.numbers(3, f"{where} vertex {i}") for i in range(nv)]
        F = [tokens.numbers(3, f"{where} triangle {i}") for i in range(nt)]
        return _inline_mesh(V, F, tokens.path, f"{where} (line {tokens.line})")
    raise InputError(
        f"shape type {kind!r}: expected box, sphere, cylinder or mesh (cones and planes have no pickplan shape)",
        path=tokens.path,
        field=f"{where} (line {tokens.line})",
    )


class _Tokens:
    """Whitespace-separated tokens with the line each came from (for messages)."""

    def __init__(self, lines: List[str], path: str, first_line: int):
        self.path, self.line = path, first_line
        self._items = [(n, w) for n, l in enumerate(lines, start=first_line) for w in l.split()]
        self._lines = {n: l for n, l in enumerate(lines, start=first_line)}
        self._i = 0

    def word(self, what: str) -> str:
        if self._i >= len(self._items):
            raise InputError(
                f"file ends where {what} should be (a '.' line ends a scene)", path=self.path, field=f"line {self.line}"
            )
        self.line, w = self._items[self._i]
        self._i += 1
        return w

    def rest_of_line(self, what: str) -> str:
        line = self.line if self._i >= len(self._items) else self._items[self._i][0]
        words = []
        while self._i < len(self._items) and self._items[self._i][0] == line:
            words.append(self.word(what))
        if not words:
            raise InputError(f"missing {what}", path=self.path, field=f"line {line}")
        return " ".join(words)

    def numbers(self, n: int, what: str) -> List[float]:
        out = []
        for _ in range(n):
            w = self.word(what)
            try:
                v = float(w)
            except ValueError:
                raise InputError(
                    f"{what}: expected a number, got {w!r}", path=self.path, field=f"line {self.line}"
                ) from None
            if not np.isfinite(v):
                raise InputError(f"{what}: not finite ({w})", path=self.path, field=f"line {self.line}")
            out.append(v)
        return out

    def count(self, what: str) -> int:
        w = self.word(what)
        if not w.isdigit():
            raise InputError(f"{what}: expected a count, got {w!r}", path=self.path, field=f"line {self.line}")
        return int(w)

    def pose(self, what: str) -> np.ndarray:
        p, q = self.numbers(3, what + " position"), self.numbers(4, what + " orientation")
        return _pose_from(p, q, self.path, f"{what} (line {self.line})")


# --- small readers ------------------------------------------------------------------------------------
def _pose_from(position, quaternion, path: str, where: str) -> np.ndarray:
    """A 4x4 from a position and an (x, y, z, w) quaternion, normalized when within 1e-3 of unit."""
    q = np.asarray(quaternion, dtype=float)
    norm = np.linalg.norm(q)
    if not abs(norm - 1.0) <= 1e-3:
        raise InputError(f"orientation {q.tolist()} is not a unit quaternion (norm {norm:.4g})", path=path, field=where)
    x, y, z, w = q / norm
    T = np.eye(4)
    T[:3, :3] = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    T[:3, 3] = position
    return T


class _Fields(FieldReader):
    """``core.fields``' checks over MoveIt's YAML (keyed reads), failing at the first problem: an
    InputError naming the file and the field."""

    def note(self, field: str, message: str) -> None:
        raise InputError(message, path=self.path, field=field)

    def mapping(self, d, key: str, where: str, required: bool = True) -> dict:
        v = d.get(key) if isinstance(d, dict) else None
        if v is None:
            if required:
                self.note(where + key, "missing")
            return {}
        return self.table(v, where + key)

    def listed(self, d, key: str, where: str, required: bool = True) -> list:
        v = d.get(key) if isinstance(d, dict) else None
        if v is None:
            if required:
                self.note(where + key, "missing")
            return []
        return [item for _, item in self.items(v, where + key)]

    def name(self, d, key: str, where: str) -> str:
        return self.text(d.get(key) if isinstance(d, dict) else None, where + key)

    def number_at(self, d, key: str, where: str) -> float:
        return self.number(d.get(key) if isinstance(d, dict) else None, where + key)

    def numbers_of(self, v, n: int, where: str) -> List[float]:
        return list(self.vector(v, where, n))

    def numbers(self, d, key: str, where: str, n: int) -> List[float]:
        if not isinstance(d, dict) or key not in d:
            self.note(where + key, "missing")
        return self.numbers_of(d[key], n, where + key)

    def pose(self, p, where: str) -> np.ndarray:
        """A geometry_msgs/Pose: position and orientation as lists ([x, y, z], [x, y, z, w]) or mappings."""
        if not isinstance(p, dict):
            self.note(where, f"expected a pose with position and orientation, got {shown(p)}")
        out = []
        for key, axes in (("position", "xyz"), ("orientation", "xyzw")):
            v = p.get(key)
            out.append(
                [self.number_at(v, a, f"{where}.{key}.") for a in axes]
                if isinstance(v, dict)
                else self.numbers_of(v, len(axes), f"{where}.{key}")
            )
        return _pose_from(out[0], out[1], self.path, where + ".orientation")

    def joint_state(self, js, where: str) -> Dict[str, float]:
        names, values = self.listed(js, "name", where + "."), self.listed(js, "position", where + ".")
        if len(names) != len(values):
            self.note(where + ".position", f"{len(names)} names but {len(values)} positions")
        self.numbers_of(values, len(values), where + ".position")
        return {str(n): float(v) for n, v in zip(names, values)}


def _read(path: str) -> str:
    if not os.path.isfile(path):
        raise FileNotFoundError(f"MoveIt file not found: {path}")
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except UnicodeDecodeError as exc:
        raise InputError(f"not a text file ({exc})", path=path) from None


def _yaml(text: str, path: str):
    import yaml

    try:
        return yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        raise InputError(f"malformed YAML: {exc}", path=path) from None


def read_srdf_disabled(path: str) -> Tuple[Tuple[str, str], ...]:
    """The link pairs an SRDF's ``disable_collisions`` elements exempt from self-collision checks."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(_read(os.fspath(path)))
    except ET.ParseError as exc:
        raise InputError(f"malformed SRDF: {exc}", path=os.fspath(path)) from None
    out = []
    for k, el in enumerate(root.iter("disable_collisions")):
        a, b = el.get("link1"), el.get("link2")
        if not a or not b:
            raise InputError("needs link1 and link2", path=os.fspath(path), field=f"disable_collisions[{k}]")
        out.append((a, b))
    return tuple(out)
