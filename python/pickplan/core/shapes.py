"""Obstacles of any shape at any pose: solid boxes, cylinders and spheres (closed-form SDFs and FCL's
exact primitives, native) and meshes (an SDF grid and an FCL BVH, like the objects). Shelves, bins,
cabinets and MoveIt's collision objects are made of them.

Conventions (MoveIt's and URDF's): a shape is centred at its frame's origin; a box's ``size`` is its
full extents (x, y, z); a cylinder's is (radius, length) with its axis along z; a sphere's (radius,).
A mesh shape reads ``file`` (anything trimesh loads) scaled by ``size`` (sx, sy, sz).

>>> shelf = Obstacle("board", Shape.box(0.8, 0.4, 0.02), pose, support=True)
>>> sdf.add_primitive(shelf.name, shelf.shape, shelf.pose)
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Optional, Sequence, Tuple

import numpy as np

from pickplan import _core
from pickplan.core import sdf as sdf_mod
from pickplan.core.caches import memo
from pickplan.core.errors import InputError
from pickplan.core.poses import clean_pose
from pickplan.core.settings import Option


class ShapeKind(Option):
    box = "box"
    cylinder = "cylinder"
    sphere = "sphere"
    mesh = "mesh"


_SIZES = {ShapeKind.box: 3, ShapeKind.cylinder: 2, ShapeKind.sphere: 1, ShapeKind.mesh: 3}


@dataclass(frozen=True)
class Shape:
    """A solid primitive or a mesh file, in its own frame (see the module doc for ``size``)."""

    kind: ShapeKind
    size: Tuple[float, ...]
    file: str = ""  # mesh shapes: the file, or ...
    vertices: Tuple[Tuple[float, float, float], ...] = ()  # ... the mesh itself (MoveIt messages carry it)
    faces: Tuple[Tuple[int, int, int], ...] = ()

    def __post_init__(self):
        kind = ShapeKind.parse(self.kind, "shape kind")
        object.__setattr__(self, "kind", kind)
        size = tuple(float(v) for v in np.atleast_1d(np.asarray(self.size, dtype=float)))
        object.__setattr__(self, "size", size)
        if len(size) != _SIZES[kind] or not all(np.isfinite(v) and v > 0 for v in size):
            raise InputError(
                f"a {kind.value} needs {_SIZES[kind]} finite positive dimensions, got {list(size)}", field="size"
            )
        if (kind is ShapeKind.mesh) != (bool(self.file) or bool(self.faces)):
            raise InputError("a mesh shape needs a file or vertices and faces, a primitive neither", field="file")
        if self.faces and self.file:
            raise InputError("a mesh shape takes a file or vertices and faces, not both", field="file")

    @classmethod
    def box(cls, x: float, y: float, z: float) -> "Shape":
        return cls(ShapeKind.box, (x, y, z))

    @classmethod
    def cylinder(cls, radius: float, length: float) -> "Shape":
        return cls(ShapeKind.cylinder, (radius, length))

    @classmethod
    def sphere(cls, radius: float) -> "Shape":
        return cls(ShapeKind.sphere, (radius,))

    @classmethod
    def mesh(cls, file: str, scale: Sequence[float] = (1.0, 1.0, 1.0)) -> "Shape":
        return cls(ShapeKind.mesh, tuple(scale), os.fspath(file))

    @classmethod
    def inline_mesh(cls, vertices, faces) -> "Shape":
        V, F = np.asarray(vertices, dtype=float).reshape(-1, 3), np.asarray(faces, dtype=int).reshape(-1, 3)
        return cls(ShapeKind.mesh, (1.0, 1.0, 1.0), "", tuple(map(tuple, V.tolist())), tuple(map(tuple, F.tolist())))

    @property
    def primitive(self) -> bool:
        return self.kind is not ShapeKind.mesh

    def native(self) -> "_core.Primitive":
        """The native solid primitive (``_core.Primitive``); a mesh shape has none."""
        if not self.primitive:
            raise ValueError("a mesh shape is not a primitive")
        size = list(self.size) + [0.0] * (3 - len(self.size))
        return _core.Primitive(getattr(_core.PrimitiveKind, self.kind.value), np.array(size))

    def trimesh(self):
        """A closed triangle mesh of the shape (display, PyBullet meshes, sampling): primitives from
        trimesh's creation module, a mesh shape read from its file (cached per file and scale)."""
        return _trimesh(self.kind, self.size, self.file, self.vertices, self.faces)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """(N,) exact signed distances of (N, 3) points in the shape's frame (primitives only)."""
        d, _ = self.native().signed_distance(np.asarray(points, dtype=float).reshape(-1, 3))
        return np.asarray(d)

    def to_dict(self) -> dict:
        out = {"shape": self.kind.value, "size": list(self.size)}
        if self.file:
            out["file"] = self.file
        if self.faces:
            out["vertices"], out["faces"] = [list(v) for v in self.vertices], [list(f) for f in self.faces]
        return out


@memo(256)
def _trimesh(kind: ShapeKind, size: Tuple[float, ...], file: str, vertices: tuple, faces: tuple):
    import trimesh

    if faces:
        return trimesh.Trimesh(np.asarray(vertices, dtype=float), np.asarray(faces, dtype=int), process=False)
    if kind is ShapeKind.box:
        return trimesh.creation.box(extents=size)
    if kind is ShapeKind.cylinder:
        return trimesh.creation.cylinder(radius=size[0], height=size[1], sections=48)
    if kind is ShapeKind.sphere:
        return trimesh.creation.icosphere(subdivisions=3, radius=size[0])
    if not os.path.isfile(file):
        raise FileNotFoundError(f"mesh file not found: {file}")
    mesh = trimesh.load(file, force="mesh")
    mesh.apply_scale(np.asarray(size, dtype=float))
    return mesh


@dataclass(eq=False)
class Obstacle:
    """A static obstacle of a scene: a unique name, a shape and the shape frame's world pose.
    ``support``: a surface objects may rest on (a shelf board, a bin's floor); the fingers may
    touch it at a grasp as they touch the table."""

    name: str
    shape: Shape
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    support: bool = False

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            **self.shape.to_dict(),
            "pose": np.asarray(self.pose, dtype=float).tolist(),
            **({"support": True} if self.support else {}),
        }

    @classmethod
    def from_dict(cls, d, where: str = "obstacle", relative_to: Optional[str] = None) -> "Obstacle":
        """An obstacle from its JSON form; InputError naming ``where`` and the field when it is wrong.
        A mesh's relative ``file`` is taken relative to ``relative_to``'s folder."""
        if not isinstance(d, dict):
            raise InputError(f"expected an object with name, shape, size and pose, got {type(d).__name__}", field=where)
        missing = [k for k in ("name", "shape", "size", "pose") if k not in d]
        if missing:
            raise InputError(f"missing {missing}", field=where)
        unknown = sorted(set(d) - {"name", "shape", "size", "pose", "file", "vertices", "faces", "support"})
        if unknown:
            raise InputError(f"unknown keys {unknown}", field=where)
        if not isinstance(d["name"], str) or not d["name"]:
            raise InputError(f"expected a non-empty name, got {d['name']!r}", field=f"{where}.name")
        try:
            kind = ShapeKind.parse(d["shape"], "shape")
        except ValueError as exc:
            raise InputError(str(exc), field=f"{where}.shape") from None
        file = d.get("file", "")
        if file and relative_to and not os.path.isabs(file):
            file = os.path.join(os.path.dirname(os.path.abspath(relative_to)), file)
        size = d["size"]
        if not isinstance(size, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in size):
            raise InputError(f"expected a list of numbers, got {size!r:.60}", field=f"{where}.size")
        try:
            shape = (
                Shape(kind, tuple(size), file) if "faces" not in d else _inline(d.get("vertices"), d["faces"], where)
            )
        except InputError as exc:
            raise InputError(exc.detail, field=f"{where}.{exc.field}") from None
        support = d.get("support", False)
        if not isinstance(support, bool):
            raise InputError(f"expected true or false, got {support!r}", field=f"{where}.support")
        return cls(d["name"], shape, clean_pose(d["pose"], f"{where}.pose"), support)

    def world_vertices(self) -> np.ndarray:
        """(V, 3) vertices of the shape's mesh in the world."""
        V = np.asarray(self.shape.trimesh().vertices, dtype=float)
        T = np.asarray(self.pose, dtype=float)
        return V @ T[:3, :3].T + T[:3, 3]

    def top_plane(self) -> Tuple[np.ndarray, float]:
        """The support face as (unit normal, offset), points x on it having normal . x = offset: the
        face of the shape's bounding box (in its frame) whose outward normal points most nearly up."""
        T = np.asarray(self.pose, dtype=float)
        axes = T[:3, :3]
        if self.shape.primitive:
            _, half = self.shape.native().bounds()
        else:
            half = np.abs(np.asarray(self.shape.trimesh().bounds, dtype=float)).max(axis=0)
        k = int(np.argmax(np.abs(axes[2, :])))
        normal = axes[:, k] * np.sign(axes[2, k])
        return normal, float(normal @ T[:3, 3] + np.asarray(half, dtype=float)[k])


def check_unique(names: Sequence[str], what: str = "obstacles") -> None:
    seen = set()
    for n in names:
        if n in seen:
            raise InputError(f"name {n!r} is used twice (names must be unique)", field=what)
        seen.add(n)


def add_to_sdf(scene_sdf, obstacles: Sequence[Obstacle], settings=None, grids=None) -> None:
    """Put ``obstacles`` into a ``sdf.SceneSdf``: primitives in closed form, meshes as grids (built
    with ``settings``, an ``sdf.SdfSettings``; from ``grids``, an ``sdf.GridCache``, when given)."""
    for o in obstacles:
        if o.shape.primitive:
            scene_sdf.add_primitive(o.name, o.shape, o.pose)
        else:
            grid = sdf_mod.mesh_sdf(o.shape.trimesh(), settings or sdf_mod.SdfSettings(), grids)
            scene_sdf.add_object(o.name, grid, o.pose)


def read_obstacles(items, taken: Sequence[str] = (), relative_to: Optional[str] = None) -> list:
    """Obstacles from their JSON list (``Obstacle.from_dict`` each); names unique among them and
    ``taken`` (the objects' names), and never "table"."""
    if not isinstance(items, list):
        raise InputError(f"expected a list, got {type(items).__name__}", field="obstacles")
    out = [Obstacle.from_dict(o, f"obstacles[{i}]", relative_to) for i, o in enumerate(items)]
    for i, o in enumerate(out):
        if o.name == "table" or o.name in taken:
            raise InputError(f"name {o.name!r} is taken (by the table or an object)", field=f"obstacles[{i}].name")
    check_unique([o.name for o in out])
    return out


def _inline(vertices, faces, where: str) -> Shape:
    """A mesh given as vertex and face lists (JSON), checked."""
    try:
        V = np.asarray(vertices, dtype=float)
        F = np.asarray(faces, dtype=float)
    except (TypeError, ValueError):
        raise InputError("expected lists of numbers", field="vertices") from None
    if V.ndim != 2 or V.shape[1] != 3 or not np.all(np.isfinite(V)):
        raise InputError(f"expected (V, 3) finite numbers, got shape {V.shape}", field="vertices")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or np.any(F != np.round(F)) or F.min() < 0 or F.max() >= len(V):
        raise InputError(f"expected (F, 3) indices of the {len(V)} vertices", field="faces")
    return Shape.inline_mesh(V, F.astype(int))
