"""One scene, prepared for planning: the robot at its base, object models, the scene SDF,
body points and FCL collision checkers. Built once per scene; immutable afterwards."""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field, replace
from typing import Optional, Tuple, Union

import numpy as np

from pickplan.core import collision
from pickplan.core import objects
from pickplan.core import robots
from pickplan.core import sdf
from pickplan.core import shapes
from pickplan.core.caches import mesh_content_key
from pickplan.core.graspability import Graspability, graspability
from pickplan.core.settings import Option
from pickplan.sim.scenes import Scene
from pickplan.omg import isf
from pickplan.omg.chomp import Chomp
from pickplan.omg.grasps import quality, verify
from pickplan.omg.model_cache import ModelCache


def _rounded(values) -> np.ndarray:
    """Float values rounded to 1e-9 for cache keys (-0.0 taken as 0.0); ``.tobytes()`` of it (or of a row) is the key."""
    return np.round(np.asarray(values, float), 9) + 0.0


class _HashedKey:
    """A tuple key hashed once (dict lookups of many keys sharing it hash it once, not per key)."""

    __slots__ = ("value", "_hash")

    def __init__(self, value: tuple):
        self.value, self._hash = value, hash(value)

    def __hash__(self) -> int:
        return self._hash

    def __eq__(self, other) -> bool:
        return isinstance(other, _HashedKey) and self._hash == other._hash and self.value == other.value


class CheckerKind(Option):
    """What a world's FCL checker lets touch (``World.checker``)."""

    # the fingers may touch the target (grasp configurations close around it) and the table (its depth is checked
    # against the support plane apart)
    goal = "goal"
    hand = "hand"  # the same, for the hand and fingers alone
    strict = "strict"  # nothing may touch anything
    obstacles = "obstacles"  # the target is ignored entirely (trajectory validation)
    # the same, but the fingers may touch the table (their depth into the support is checked apart, as the success
    # test does): sampling planners' validity
    transit = "transit"
    # the scene's obstacles alone, the links as convex hulls (as PyBullet takes them): distances the executed lift
    # keeps (``goals.lift_blocked_configurations``)
    furniture = "furniture"
    # the same with the objects but the target (their meshes) beside the obstacles: the exact clearance a plan
    # among furniture keeps (``omg.furniture_check``)
    surroundings = "surroundings"
    # the target alone, every link against its mesh: the exact clearance a transit keeps from what it will grasp
    # (``planner.transit_target_distance``)
    target = "target"


@dataclass(frozen=True)
class WorldSettings:
    sdf: sdf.SdfSettings = field(default_factory=sdf.SdfSettings)
    body_points_per_link: Optional[int] = None  # None: the robot description's (the shipped ones: the paper's 20)
    # ... among furniture (a scene with obstacles; None: as above): the optimizer keeps a hand reaching into a
    # cabinet clear of it through these points alone, and the paper's 20 leave several cm of a link's surface
    # unsampled (panda_link6 went 2.3 cm into a cabinet's top between them); the tabletop keeps the paper's
    furniture_body_points_per_link: Optional[int] = 60
    body_seed: int = 0
    robot: str = "panda"  # the robot planned for: a shipped description's name or a .toml file


def _without_table_links(body, robot):
    """Body points without those of the links ``collision.table_pairs`` names (sampled first, so every other
    link keeps the points it has without the pairs)."""
    skip = [robot.link_index(a) for a, _ in collision.table_pairs(robot)]
    if not skip:
        return body
    keep = ~np.isin(body.links, skip)
    return robots.BodyPoints(body.links[keep], body.points[keep], body.normals[keep])


class World:
    """Planning view of a ``Scene``: ``robot``, ``models``, ``sdf`` (SceneSdf), ``body`` points,
    ``checker(kind)`` (FCL; "goal" lets the fingers touch the target, "strict" does not).
    ``robot``: a ``robots.DescribedRobot`` or a description's name or file (default ``settings.robot``),
    placed at the scene's robot base. ``cache`` (a ``ModelCache``) holds what depends only on the
    objects or the robot; worlds that share one build it once (None: this world's own)."""

    def __init__(
        self,
        scene: Scene,
        settings: WorldSettings = WorldSettings(),
        library: Optional[objects.ObjectLibrary] = None,
        robot=None,
        cache: Optional[ModelCache] = None,
    ):
        self.scene = scene
        self.settings = settings
        self.cache = cache = ModelCache() if cache is None else cache
        self.robot = cache.robot(settings.robot if robot is None else robot, scene.robot_base)
        self.models = {}
        for o in scene.objects:
            self.models[o.name] = (
                library.get(o.name)
                if library is not None and o.name in library
                else objects.model_from_source(o.name, o.source)
            )
        meshes = sdf.mesh_sdfs([self.models[o.name].mesh for o in scene.objects], settings.sdf, cache.grids)
        grids = [(o.name, grid, o.pose) for o, grid in zip(scene.objects, meshes)]
        table = None if scene.table is None else (np.asarray(scene.table.size), np.asarray(scene.table.pose))
        self.sdf = sdf.SceneSdf(grids, table=table)
        shapes.add_to_sdf(self.sdf, scene.obstacles, settings.sdf, cache.grids)  # shelves, bins: closed forms
        per_link = settings.body_points_per_link or self.robot.description.body_points_per_link
        if scene.obstacles and settings.body_points_per_link is None and settings.furniture_body_points_per_link:
            per_link = settings.furniture_body_points_per_link
        self.body = _without_table_links(cache.body_points(self.robot, per_link, settings.body_seed), self.robot)
        self._checkers: dict = {}
        self._refiners: dict = {}
        self._chomps: dict = {}
        if scene.target is None:
            raise ValueError("scene has no target: a world plans a grasp of one (omg.motion plans motions alone)")
        scene.object(scene.target)  # a clear KeyError now rather than deep inside a planner
        t0 = time.perf_counter()
        if settings.sdf.merged:
            # Two object masks, one merged grid each (bricks fill lazily, on first lookup): the target
            # left out (grasping, the success test, the approach) and the target in (the transit's
            # obstacle cost when it avoids the target, ``World.chomp(avoid_target=True)``).
            for exclude in ((scene.target,), ()):
                self.sdf.merge(
                    exclude=exclude, resolution=settings.sdf.merged_resolution, cutoff=settings.sdf.merged_cutoff
                )
        self.merge_seconds = time.perf_counter() - t0

    @property
    def target(self) -> str:
        return self.scene.target

    @property
    def target_pose(self) -> np.ndarray:
        return np.asarray(self.scene.object(self.target).pose, dtype=float)

    @property
    def target_model(self) -> objects.ObjectModel:
        return self.models[self.target]

    @property
    def start(self) -> np.ndarray:
        q = self.scene.robot_configuration  # stored for the robot the scene was made for (Scene.robot)
        use_scene = len(q) and self.scene.robot == self.robot.info.name
        return np.asarray(q, dtype=float) if use_scene else self.robot.ready_configuration

    def move_object(self, name: str, pose) -> None:
        """Move object ``name`` to ``pose`` in place, for replanning as the world moves (``omg.replan``):
        the scene, the SDF (the object leaves the merged grids, queried on its own grid beside them) and every FCL
        checker built so far follow; C-Space ISF's object samples are placed again, and what else depends
        on the target's pose (its graspability) is built again on next use. The CHOMP problems read the moved SDF."""
        T = np.asarray(pose, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"pose of {name!r}: expected a finite 4x4 matrix, got shape {T.shape}")
        self.scene.object(name)  # a KeyError naming the objects
        self.sdf.set_pose(name, T)  # checks rigidity before anything changed
        for kind, checker in self._checkers.items():
            # the furniture checker holds the obstacles alone, the surroundings' all objects but the target
            if kind is not CheckerKind.furniture and (kind is not CheckerKind.surroundings or name != self.target):
                checker.set_object_pose(name, T)
        self.scene = replace(
            self.scene, objects=[replace(o, pose=T.copy()) if o.name == name else o for o in self.scene.objects]
        )
        if name == self.target:
            self._refiners = {key: r.placed(self, key[1]) for key, r in self._refiners.items()}
            self.__dict__.pop("graspability", None)

    def expect_motion(self, name: str) -> None:
        """Object ``name`` will move (a replanner's target): the SDF queries it on its own grid from now
        on, so that its first move re-merges nothing and refills no brick of the rest."""
        self.sdf.set_pose(name, np.asarray(self.scene.object(name).pose, dtype=float))

    def scene_meshes(self):
        """Objects (meshes) and obstacles (primitives and meshes) as the FCL checkers take them."""
        return [collision.SceneMesh(o.name, self.models[o.name].mesh, o.pose) for o in self.scene.objects] + [
            collision.SceneMesh(o.name, o.shape, o.pose) for o in self.scene.obstacles
        ]

    def checker(self, kind: Union[CheckerKind, str] = CheckerKind.goal) -> collision.CollisionChecker:
        """FCL checker against objects and table, of a ``CheckerKind`` (or its spelling: "goal").
        Built once per kind and kept by this world (not in a module-level cache, which would keep
        worlds alive and rebuild them when a user alternates between scenes)."""
        kind = CheckerKind.parse(kind, "checker kind")
        if kind not in self._checkers:
            self._checkers[kind] = self._build_checker(kind)
        return self._checkers[kind]

    def _build_checker(self, kind: CheckerKind) -> collision.CollisionChecker:
        if kind in (CheckerKind.furniture, CheckerKind.surroundings):
            others = [o for o in self.scene.objects if o.name != self.target and kind is CheckerKind.surroundings]
            return collision.CollisionChecker(
                self.robot,
                [collision.SceneMesh(o.name, self.models[o.name].mesh, o.pose) for o in others]
                + [collision.SceneMesh(o.name, o.shape, o.pose) for o in self.scene.obstacles],
                None,
                convex_links=True,
                shapes=self.cache.shapes,
                link_meshes=self.cache.link_meshes(self.robot),
            )
        if kind is CheckerKind.target:
            others = tuple(o.name for o in self.scene.objects if o.name != self.target) + tuple(
                o.name for o in self.scene.obstacles
            )  # no table given: none checked
            return collision.CollisionChecker(
                self.robot,
                self.scene_meshes(),
                None,
                collision.CollisionSettings(excluded_objects=others),
                shapes=self.cache.shapes,
                link_meshes=self.cache.link_meshes(self.robot),
            )
        fingers = self.robot.finger_links
        mounted = collision.mounted_pairs(self.robot)  # the base stands on the table
        links = None
        if kind in (CheckerKind.goal, CheckerKind.hand):
            # The fingers may touch the target, and the table within a tolerance the goal set checks
            # exactly against the support plane (goals.support_adjusted); the palm stays strict.
            touching = tuple((f, self.target) for f in fingers) + tuple((f, "table") for f in fingers)
            settings = collision.CollisionSettings(allowed_pairs=mounted + touching)
            if kind is CheckerKind.hand:  # only what the grasp pose places: hand and fingers
                links = (self.robot.hand_link,) + tuple(fingers)
        elif kind is CheckerKind.strict:
            settings = collision.CollisionSettings(allowed_pairs=mounted)
        elif kind is CheckerKind.transit:
            touching = tuple((f, "table") for f in fingers)
            settings = collision.CollisionSettings(allowed_pairs=mounted + touching, excluded_objects=(self.target,))
        else:
            settings = collision.CollisionSettings(allowed_pairs=mounted, excluded_objects=(self.target,))
        table = None
        if self.scene.table is not None:
            table = collision.Table(
                size=tuple(np.asarray(self.scene.table.size, dtype=float)),
                pose=np.asarray(self.scene.table.pose, dtype=float),
            )
        else:  # no table: nothing is mounted on it or may touch it
            settings = replace(settings, allowed_pairs=tuple(p for p in settings.allowed_pairs if p[1] != "table"))
        return collision.CollisionChecker(
            self.robot,
            self.scene_meshes(),
            table,
            settings,
            links=links,
            shapes=self.cache.shapes,
            link_meshes=self.cache.link_meshes(self.robot),
        )

    @property
    def support_plane(self) -> Tuple[np.ndarray, float]:
        """The table top the target rests on as (unit normal, offset): normal . x = offset on it."""
        table = self.scene.table
        if table is None:  # nothing to rest on: a plane no point reaches below
            return np.array([0.0, 0.0, 1.0]), -np.inf
        return collision.support_plane(
            collision.Table(tuple(np.asarray(table.size, float)), np.asarray(table.pose, float))
        )

    def open_approach(self, room: float = 0.3) -> np.ndarray:
        """The world direction a grasp of the target is best approached along (the centre of the
        grasp generator's fan of approaches): down onto it (a tabletop, a bin), unless an obstacle lies
        within ``room`` (m: the hand, its standoff and the wrist) above the target's top (a shelf's next
        board, a cabinet's top); then level, from the robot's base towards the target (into the shelf)."""
        T = self.target_pose
        V = np.asarray(self.target_model.mesh.vertices, float) @ T[:3, :3].T + T[:3, 3]
        top = np.array([*V[:, :2].mean(axis=0), V[:, 2].max()])
        step = 0.01
        points = top + np.outer(np.arange(step, room + step / 2, step), [0.0, 0.0, 1.0])
        others = [o.name for o in self.scene.objects]  # furniture only: objects are not a roof
        d, _ = (
            self.sdf.distance(points, cutoff=step, exclude=others, exclude_table=True)
            if self.scene.obstacles
            else (np.full(len(points), np.inf), None)
        )
        if np.all(np.asarray(d) > step / 2):
            return np.array([0.0, 0.0, -1.0])
        level = top - np.asarray(self.scene.robot_base, float)[:3, 3]
        level[2] = 0.0
        n = np.linalg.norm(level)
        return level / n if n > 1e-9 else np.array([1.0, 0.0, 0.0])

    def over_support(self, points: np.ndarray) -> np.ndarray:
        """(N,) whether world points lie over the table top's footprint (where its plane is a support)."""
        table = self.scene.table
        if table is None:
            return np.zeros(len(np.asarray(points).reshape(-1, 3)), dtype=bool)
        T = collision.Table(tuple(np.asarray(table.size, float)), np.asarray(table.pose, float)).pose_matrix()
        local = (np.asarray(points, float) - T[:3, 3]) @ T[:3, :3]
        return np.all(np.abs(local[:, :2]) <= 0.5 * np.asarray(table.size, float)[:2], axis=1)

    @functools.cached_property
    def graspability(self) -> Graspability:
        """Whether this robot's gripper can grasp the target as it lies at all (``core.graspability``):
        geometry of the target and the support, computed once per world."""
        up = np.array([0.0, 0.0, 1.0]) if self.scene.table is None else np.asarray(self.scene.table.pose, float)[:3, 2]
        return graspability(
            self.target_model,
            self.target_pose,
            self.robot.info.max_opening,
            up,
            ray_mesh=self.cache.ray_mesh(self.target_model.mesh),
        )

    def grasp_quality(self, grasps: np.ndarray, settings: quality.QualitySettings) -> quality.Quality:
        """The quality (``grasps.quality``) of hand poses in the target's frame, the target as it lies,
        for this robot's gripper; the target's surface samples and their k-d tree are kept by the cache."""
        model = self.target_model
        key = ("pad_points", mesh_content_key(model.mesh), settings.spacing, settings.max_samples, settings.seed)
        surface = self.cache.derived(key, lambda: quality.surface_tree(model.mesh, settings))
        return quality.model_quality(model, grasps, self.target_pose, self.robot.info, settings, surface)

    @functools.cached_property
    def _target_key(self) -> tuple:
        return mesh_content_key(self.target_model.mesh)

    def grasp_verdicts(self, grasps: np.ndarray, settings: quality.QualitySettings) -> Tuple[np.ndarray, list]:
        """(margins, fits) of ``grasp_quality``, each kept per grasp by the cache: a grasp's quality depends
        only on the grasp in the target's frame, the target's model and gripper and which way is down in
        its frame, so a moved target that did not turn, or another scene with the object lying the same
        way, reuses it (grasps equal to 1 nm and 1e-9 rad)."""
        grasps = np.asarray(grasps, float).reshape(-1, 4, 4)
        model, info = self.target_model, self.robot.info
        down = quality.model_load(model, self.target_pose).down
        friction = model.friction if getattr(model, "friction", None) is not None else settings.object_friction
        common = _HashedKey(
            (
                self._target_key,
                float(model.mass),
                _rounded(model.com).tobytes(),
                friction,
                quality.Grip.of(info, friction),
                _rounded(info.grasp_frame).tobytes(),
                settings,
                _rounded(down).tobytes(),
            )
        )
        keys = [(common, g.tobytes()) for g in _rounded(grasps[:, :3])]

        def build(rows):
            q = self.grasp_quality(grasps[rows], settings)
            return list(zip(q.margin.tolist(), q.fit))

        verdicts = self.cache.grasp_verdicts.get_many(keys, build)
        return np.array([v[0] for v in verdicts], dtype=float), [v[1] for v in verdicts]

    def verify_grasps(self, grasps: np.ndarray, settings: verify.VerifySettings) -> verify.Verified:
        """``grasps.verify.verify_grasps`` of hand poses in the target's frame, the target lying as it
        does on the scene's table, for this robot's gripper (``settings``: a ``VerifySettings``)."""
        return verify.verify_grasps(self.target_model, grasps, self._target_on_table, self.robot.info, settings)

    def lift_grasps(self, grasps: np.ndarray, settings: verify.VerifySettings) -> np.ndarray:
        """``grasps.verify.lift_grasps``: each grasp (target frame) lifted in PyBullet, the target lying as
        it does on the scene's table; (N,) ``LiftVerdict``."""
        return verify.lift_grasps(self.target_model, grasps, self._target_on_table, self.robot.info, settings)

    @property
    def _target_on_table(self) -> np.ndarray:
        """The target turned as it lies, its lowest point on a table top at z = 0 (the physics checks'
        table; from its mesh, so a target on a shelf board is checked as it lies there too)."""
        rest = np.array(self.target_pose, dtype=float)
        rest[2, 3] = -float((self.target_model.mesh.vertices @ rest[2, :3]).min())
        return rest

    @functools.cached_property
    def clearance_problem(self):
        """A CHOMP problem on this scene with the target excluded: what the success test measures
        clearances with (body points in the scene SDF); the goal set checks approaches with it."""
        return Chomp(self.robot, self.sdf, self.body, exclude=(self.target,)).problem

    def chomp(self, settings, avoid_target: bool = False) -> Chomp:
        """The CHOMP problem on this scene with ``settings`` (a ``ChompSettings``; the target left out of
        the metrics, and of the obstacle cost unless ``avoid_target``), built once per (settings,
        avoid_target) and kept by this world: every plan in it shares the problem (immutable; per-call
        scratch is the workspace)."""
        key = (settings, bool(avoid_target))
        if key not in self._chomps:
            self._chomps[key] = Chomp(
                self.robot,
                self.sdf,
                self.body,
                settings,
                exclude=(self.target,),
                obstacle_exclude=() if avoid_target else (self.target,),
            )
        return self._chomps[key]

    def grasp_refiner(self, settings=None, seed: int = 0):
        """C-Space ISF for this scene's target (``isf.GraspRefiner``), built once per (settings,
        seed) and kept by this world: the hand SDF and the object's surface samples are scene
        constants, not per-plan work."""
        settings = settings or isf.IsfSettings()
        key = (settings, int(seed))
        if key not in self._refiners:
            self._refiners[key] = isf.GraspRefiner(self, settings, seed=seed)
        return self._refiners[key]
