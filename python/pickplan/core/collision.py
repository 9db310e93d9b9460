"""Exact collision checking (native, FCL): a robot against scene meshes and a table box.

>>> import numpy as np, trimesh
>>> from pickplan.core import robots
>>> from pickplan.core.collision import CollisionChecker, SceneMesh, Table
>>> panda = robots.panda()
>>> box = trimesh.creation.box(extents=[0.1, 0.1, 0.2])
>>> pose = np.eye(4); pose[:3, 3] = [0.5, 0.0, 0.1]
>>> checker = CollisionChecker(panda, [SceneMesh("box", box, pose)], Table(size=(1.0, 1.4, 0.05)))
>>> bool(checker.in_collision(panda.ready_configuration))
False

Link meshes are the robot's collision meshes in the link frames (``robot.collision_meshes``),
object meshes are triangle surfaces, the table is a solid box. Distances are exact when apart
and <= 0 in collision: minus a lower bound of the penetration (the deepest triangle's depth
against the table, 0 for intersecting meshes, minus the surface gap for a mesh contained in
another). See ``cpp/include/pickplan/collision.hpp`` for the precise semantics.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import List, NamedTuple, Optional, Sequence, Tuple

import numpy as np

from pickplan import _core
from pickplan.core.caches import BoundedCache, mesh_content_key
from pickplan.core.meshes import check_mesh_arrays
from pickplan.core.panda import PANDA_DESCRIPTION
from pickplan.core.robots import Robot
from pickplan.core.settings import native_defaults, to_native
from pickplan.core.shapes import Shape


class SceneMesh(NamedTuple):
    """A scene object: unique name, mesh (anything with ``vertices`` and ``faces``, or a
    ``shapes.Shape``: a primitive is checked as FCL's exact solid) in the object frame, and its
    4x4 pose in the world."""

    name: str
    mesh: object
    pose: np.ndarray


@dataclass(frozen=True)
class Table:
    """A solid box; by default its top face is at z = 0, centred at (0.75, 0) in front of the robot."""

    size: Tuple[float, float, float] = (1.1, 1.4, 0.05)
    pose: Optional[np.ndarray] = None  # box centre; None: translation (0.75, 0, -size_z / 2)

    def pose_matrix(self) -> np.ndarray:
        if self.pose is not None:
            return np.asarray(self.pose, dtype=float)
        T = np.eye(4)
        T[:3, 3] = [0.75, 0.0, -0.5 * float(self.size[2])]
        return T


@dataclass(frozen=True)
@native_defaults(_core.CollisionSettings)
class CollisionSettings:
    """Mirror of the C++ ``CollisionSettings`` (same field names and defaults)."""

    allowed_pairs: Tuple[Tuple[str, str], ...]  # (link, object | "table" | link) never checked
    excluded_objects: Tuple[str, ...]  # object names (or "table") ignored entirely
    self_collision: bool  # adjacent links and pairs touching at the reference skipped
    self_collision_reference: Optional[Tuple[float, ...]] = None  # None: zero clipped to the limits
    margin: float  # in_collision when closer than this (m)
    detect_containment: bool  # a mesh entirely inside another collides

    def to_native(self) -> "_core.CollisionSettings":
        return to_native(
            self,
            _core.CollisionSettings,
            allowed_pairs=[(str(a), str(b)) for a, b in self.allowed_pairs],
            excluded_objects=[str(n) for n in self.excluded_objects],
            self_collision_reference=[]
            if self.self_collision_reference is None
            else [float(v) for v in self.self_collision_reference],
        )


@dataclass(frozen=True)
class Contact:
    """A checked pair in collision (distance <= 0) or within the requested distance."""

    link: str
    other: str
    kind: str  # "object", "table" or "link"
    distance: float  # > 0 separation (exact); <= 0 in collision (see the module docstring)
    point_link: np.ndarray  # world coordinates
    point_other: np.ndarray


def _mesh_arrays(mesh, what: str):
    mesh = _checked_mesh(mesh, what)
    return check_mesh_arrays(mesh.vertices, mesh.faces, what)


class ShapeCache(BoundedCache):
    """FCL shapes (a mesh and its BVH) by mesh content: built once per object or link and shared by
    every checker of every scene that places it."""

    def shape(self, mesh, what: str) -> "_core.CollisionShape":
        if isinstance(mesh, Shape):
            if mesh.primitive:
                return self.get(
                    ("primitive", mesh.kind.value, mesh.size),
                    lambda: _core.CollisionShape.from_primitive(mesh.native(), what),
                )
            mesh = mesh.trimesh()

        def build():
            V, F = _mesh_arrays(mesh, what)
            return _core.CollisionShape(V, F, what)

        return self.get(mesh_content_key(_checked_mesh(mesh, what)), build)

    def convex(self, mesh, what: str) -> "_core.CollisionShape":
        """The convex hull of ``mesh`` as FCL's convex solid."""

        def build():
            V, F = _mesh_arrays(_checked_mesh(mesh, what).convex_hull, what)
            return _core.CollisionShape.convex(V, F, what)

        return self.get(("convex",) + tuple(mesh_content_key(_checked_mesh(mesh, what))), build)


def _checked_mesh(mesh, what: str):
    if mesh is None or not hasattr(mesh, "vertices") or not hasattr(mesh, "faces"):
        raise ValueError(f"{what}: expected a mesh with vertices and faces, got {type(mesh).__name__}")
    return mesh


class CollisionChecker:
    """Robot-vs-scene collision checker, built once per scene; immutable and thread-safe.

    ``convex_links=True`` hands the convex hull of each link mesh to FCL as a convex solid instead
    of the mesh itself (what PyBullet does with URDF meshes): conservative, identical geometry
    when comparing with PyBullet, and fast (a GJK query per pair instead of a BVH walk).
    """

    def __init__(
        self,
        robot: Robot,
        objects: Sequence[SceneMesh] = (),
        table: Optional[Table] = None,
        settings: CollisionSettings = CollisionSettings(),
        convex_links: bool = False,
        links: Optional[Sequence[str]] = None,
        shapes: Optional[ShapeCache] = None,
        link_meshes: Optional[dict] = None,
    ):
        """``links``: check only these links (default: every link with collision geometry).
        ``shapes``: a cache of FCL shapes shared with other checkers (None: built for this one).
        ``link_meshes``: link name -> mesh, the robot's collision meshes when the caller has them."""
        self.robot = robot
        self.settings = settings
        native_links = []
        for name in robot.link_names if links is None else links:
            mesh = (
                link_meshes[name] if link_meshes is not None and name in link_meshes else robot.collision_meshes(name)
            )
            if mesh is None:
                continue
            what = f"mesh of link '{name}'"
            if convex_links:  # FCL's convex solid: one GJK query per pair, no BVH walk
                native_links.append((name, (shapes or ShapeCache()).convex(mesh, what)))
                continue
            native_links.append(
                (name, shapes.shape(mesh, what)) if shapes is not None else (name, *_mesh_arrays(mesh, what))
            )
        native_objects = []
        for obj in objects:
            name, mesh, pose = obj
            what = f"object '{name}'"
            if isinstance(mesh, Shape) and shapes is None:
                shapes = ShapeCache()  # primitives always go as prebuilt shapes
            geometry = (shapes.shape(mesh, what),) if shapes is not None else _mesh_arrays(mesh, what)
            native_objects.append((str(name), *geometry, np.asarray(pose, dtype=float)))
        size = pose = None
        if table is not None:
            size, pose = np.asarray(table.size, dtype=float), table.pose_matrix()
        self._native = _core.CollisionChecker(
            robot.native, native_links, native_objects, size, pose, settings.to_native()
        )

    @property
    def native(self) -> "_core.CollisionChecker":
        return self._native

    @property
    def object_names(self) -> List[str]:
        return list(self._native.object_names)

    @property
    def checked_pairs(self) -> List[Tuple[str, str]]:
        """(link, other) pairs actually checked, after exclusions and self-collision filtering."""
        return [tuple(p) for p in self._native.checked_pairs]

    def set_object_pose(self, name: str, pose) -> None:
        """Move the object ``name`` to ``pose`` (4x4 rigid): a world that moves, checked again."""
        self._native.set_object_pose(str(name), np.asarray(pose, dtype=float))

    def in_collision(self, q) -> bool:
        return bool(self._native.in_collision(q))

    def min_distance(self, q) -> float:
        """Smallest signed distance over the checked pairs (inf when there are none)."""
        return float(self._native.min_distance(q))

    def in_collision_batch(self, Q, threads: int = 1) -> np.ndarray:
        """(B,) bool for a (B, dof) batch; ``threads <= 0`` uses every core."""
        return np.asarray(self._native.in_collision_batch(Q, threads))

    def min_distance_batch(self, Q, threads: int = 1) -> np.ndarray:
        return np.asarray(self._native.min_distance_batch(Q, threads))

    def contacts(self, q, within: float = 0.0) -> List[Contact]:
        """Pairs in collision, or closer than ``max(margin, within)``, nearest first."""
        return [
            Contact(c.link, c.other, c.kind.name, float(c.distance), np.array(c.point_link), np.array(c.point_other))
            for c in self._native.contacts(q, float(within))
        ]


# --- the support surface ----------------------------------------------------------------------------
#: Default fingertip penetration allowed into the support, as a fraction of the gripper's pad length
#: (Panda: 0.15 x 18 mm = 2.7 mm): fingertips resting on a table press slightly into it, and the
#: sampled grasp geometry is no more exact than that.
SUPPORT_TOLERANCE_FRACTION = 0.15


def table_pairs(robot) -> tuple:
    """(link, "table") pairs the description skips: links standing on the table (a housing that only
    turns about the vertical) whose nearness to it the planner can neither change nor should pay for."""
    desc = getattr(robot, "description", None)
    skips = desc.skip_collision if desc is not None else ()
    return tuple((a, b) if b == "table" else (b, a) for a, b in skips if "table" in (a, b))


def mounted_pairs(robot) -> tuple:
    """(link, "table") pairs a checker allows because the base is mounted on the table: the links that never
    move always touch it, and those ``table_pairs`` names."""
    moving = set(robot.moving_links())
    return tuple((name, "table") for i, name in enumerate(robot.link_names) if i not in moving) + table_pairs(robot)


def gripper_spec(robot):
    """The robot's gripper spec (``description.GripperSpec``): from its description, else the Panda's."""
    desc = getattr(robot, "description", None)
    return (PANDA_DESCRIPTION if desc is None else desc).gripper


@dataclass(frozen=True)
class SupportContact:
    """The table top as the fingers may touch it: the finger links (the gripper's ``finger_links``)
    may press into the support plane up to ``tolerance`` (m; None: ``SUPPORT_TOLERANCE_FRACTION`` of
    the gripper's pad length); palm, hand body, arm and other objects stay strict."""

    tolerance: Optional[float] = None

    def resolved(self, robot) -> float:
        if self.tolerance is None:
            return SUPPORT_TOLERANCE_FRACTION * float(gripper_spec(robot).pad_length)
        if not 0.0 <= float(self.tolerance) <= 0.02:
            raise ValueError(f"support tolerance: expected metres in [0, 0.02], got {self.tolerance}")
        return float(self.tolerance)


def support_plane(table: Table) -> Tuple[np.ndarray, float]:
    """The table's top face as (unit normal, offset): points x on it satisfy normal . x = offset."""
    T = table.pose_matrix()
    normal = T[:3, 2]
    return normal, float(normal @ T[:3, 3] + 0.5 * float(table.size[2]))


class HandGeometry:
    """Collision-hull vertices of some links of the hand (the fingers, or the palm) in the hand
    link's frame, with the fingers as in ``q`` (open): how deep a hand pose pushes them into a plane
    is exact from them (the deepest point of a convex hull is a vertex)."""

    def __init__(self, robot, q, hand_link: str, finger_links: Sequence[str]):
        poses = robot.fk(q)
        inv = np.linalg.inv(poses[robot.link_index(hand_link)])
        chunks = []
        for name in finger_links:
            mesh = robot.collision_meshes(name)
            if mesh is None:
                continue
            V = np.asarray(mesh.convex_hull.vertices, dtype=float)
            T = inv @ poses[robot.link_index(name)]
            chunks.append(V @ T[:3, :3].T + T[:3, 3])
        if not chunks:
            raise ValueError(f"links {list(finger_links)} have no collision geometry")
        self.vertices = np.concatenate(chunks)  # (V, 3) in the hand frame

    @classmethod
    def from_vertices(cls, vertices) -> "HandGeometry":
        """The same from hull vertices already in the hand frame (e.g. kept by a ``ModelCache``)."""
        V = np.asarray(vertices, dtype=float)
        if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
            raise ValueError(f"hand geometry: expected (V, 3) vertices, got shape {V.shape}")
        out = cls.__new__(cls)
        out.vertices = V
        return out

    def penetration(self, hand_poses, normal: np.ndarray, offset: float) -> np.ndarray:
        """(N,) how far the links reach below the plane (m; negative: above it) for (N, 4, 4) hand poses."""
        H = np.asarray(hand_poses, dtype=float).reshape(-1, 4, 4)
        # height of every finger vertex above the plane, per pose: n . (R v + p) - offset
        Rn = np.einsum("nij,i->nj", H[:, :3, :3], normal)
        heights = Rn @ self.vertices.T + (H[:, :3, 3] @ normal - offset)[:, None]
        return -heights.min(axis=1)
