"""What a planning world needs that depends only on an object model or on the robot, built once
and reused by every scene and every checker kind: SDF grids, FCL shapes (mesh + BVH), object
surface samples, the robot model, its collision meshes and body points, the hand SDF. Per scene
only placement remains.

>>> cache = ModelCache()
>>> worlds = [World(scene, cache=cache) for scene in scenes]   # objects seen before: no rebuild

Explicit and bounded: the caller owns it and passes it in; a World made without one gets its own.
"""

from __future__ import annotations

from typing import Callable, Hashable, Optional

import numpy as np

from pickplan.core import collision
from pickplan.core.graspability import RayMesh
from pickplan.core import robots
from pickplan.core import sdf
from pickplan.core.caches import BoundedCache, mesh_content_key


class ModelCache:
    """Per-object and per-robot data shared by worlds; ``max_objects`` bounds each kind."""

    def __init__(self, max_objects: int = 64):
        self.grids = sdf.GridCache(max_objects + 8)  # + the hand's parts
        self.shapes = collision.ShapeCache(max_objects + 32)  # + the robot's links
        self._derived = BoundedCache(2 * max_objects + 16)  # surface samples, robot data
        self.grasp_verdicts = BoundedCache(256 * max_objects)  # per grasp: its quality's margin and fit

    def derived(self, key: Hashable, build: Callable):
        """Any other per-object or per-robot value, by a key naming what it is built from."""
        return self._derived.get(key, build)

    @staticmethod
    def robot_key(robot) -> Optional[tuple]:
        """What a robot's shape-only data is keyed by (its model file and the links attached since, a held
        object's grasp among them: an IK solver built for one grasp's robot places another's held link
        wrongly); None: not cacheable."""
        path = getattr(robot, "urdf_path", None)
        return (type(robot).__name__, path, tuple(getattr(robot, "attachments", ()))) if path else None

    def robot(self, name_or_file, base_pose) -> robots.DescribedRobot:
        """The described robot (``robots.load_robot``: a name, a file or a ``DescribedRobot``) at the
        scene's ``base_pose``: a description and its URDF are parsed once, only the base changes."""
        base = np.asarray(base_pose, dtype=float)
        if isinstance(name_or_file, robots.DescribedRobot):
            return robots.load_robot(name_or_file, base)
        loaded = self.derived(("robot", str(name_or_file)), lambda: robots.load_robot(str(name_or_file)))
        return robots.load_robot(loaded, base)

    def panda(self, base_pose) -> robots.DescribedRobot:
        """The Panda at ``base_pose``."""
        return self.robot("panda", base_pose)

    def robot_derived(self, robot, what: Hashable, build: Callable):
        key = self.robot_key(robot)
        return build() if key is None else self.derived((key, what), build)

    def link_meshes(self, robot) -> dict:
        """Link name -> collision mesh in the link frame (None without geometry)."""
        return self.robot_derived(
            robot, "link_meshes", lambda: {name: robot.collision_meshes(name) for name in robot.link_names}
        )

    def finger_geometry(self, robot, q) -> Optional[collision.HandGeometry]:
        """The fingers' collision hulls in the hand frame with the fingers as in ``q`` (None for a hand
        without finger links), kept per robot model and opening: a plan does not load the finger meshes
        and build their hulls again."""
        fingers = tuple(getattr(robot, "finger_links", ()))
        if not fingers:
            return None
        q = np.asarray(q, dtype=float)

        def build():
            vertices = collision.HandGeometry(robot, q, robot.hand_link, fingers).vertices
            vertices.setflags(write=False)  # shared by every world of this robot
            return vertices

        vertices = self.robot_derived(robot, ("finger_hull_vertices", q.tobytes()), build)
        return collision.HandGeometry.from_vertices(vertices)

    def body_points(self, robot, per_link: int, seed: int):
        return self.robot_derived(
            robot, ("body", int(per_link), int(seed)), lambda: robot.sample_body_points(per_link, seed=seed)
        )

    def ray_mesh(self, mesh) -> RayMesh:
        """The mesh's private copy with its ray tree built (graspability's rays), kept per mesh content."""
        return self.derived(("ray_mesh", mesh_content_key(mesh)), lambda: RayMesh(mesh))

    def surface(self, mesh, n: int, seed: int, sample: Callable):
        """``sample(mesh, n, seed)`` -> object-frame surface samples, kept per mesh content."""
        return self.derived(("surface", mesh_content_key(mesh), int(n), int(seed)), lambda: sample(mesh, n, seed))
