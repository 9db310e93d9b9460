"""The planner's world from a depth observation: no object mesh and no stored grasp is read.

``PerceivedWorld(observation)`` has the interface ``OMGPlanner`` uses of a ``World``:

- ``sdf``: the fused depth field (``perception.field.perceive``: everything the cameras saw but the
  target, unseen space behind a surface occupied) plus the support plane as the table, and the
  observed target as an unsigned-distance grid (only ever excluded, as a mesh world's target is);
- grasps from the target's observed points (``omg.grasps.points.grasps_from_points``), kept when the
  open hand clears the fused field and the support plane: the fingers may touch the plane (less
  ``PointGraspSettings.table_contact``), the palm may not, at the grasp and at the pre-grasp (the
  height above a plane is linear along the standoff, so both ends bound it);
- goal sets: IK as for any world; every configuration of the approach (pre-grasp to grasp) keeps the
  approach clearance from the fused field, every body point (``clearance_problem``, checked natively);
  there is no FCL model of a perceived scene (``checker`` says so), the table is the plane's slab in
  the field, which the success test measures for every link;
- C-Space ISF on the observed target points and normals (``grasp_refiner``).

Camera poses are in the robot base frame (the robot stands at the origin, as in every ``Scene``).

>>> world = PerceivedWorld(Observation.load("obs.npz"))
>>> result = PerceivedPlanner(world).plan()
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field as dataclass_field
from typing import Optional, Tuple

import numpy as np
from scipy.spatial import cKDTree

from pickplan import _core
from pickplan.core.errors import InputError
from pickplan.core.graspability import Graspability
from pickplan.core.observation import Observation
from pickplan.core.sdf import SceneSdf, SdfQuery
from pickplan.omg import isf
from pickplan.omg.chomp import Chomp
from pickplan.omg.goals import GoalSetSettings
from pickplan.omg.grasps import quality
from pickplan.omg.grasps.point_geometry import denoised, points_load
from pickplan.omg.grasps.points import PointGraspSettings, grasps_from_points
from pickplan.omg.grasps.sets import GraspSet
from pickplan.omg.model_cache import ModelCache
from pickplan.omg.native_loop import StageClock
from pickplan.omg.planner import OMGPlanner, OMGSettings
from pickplan.omg.world import CheckerKind, World
from pickplan.perception.field import FieldSettings, PerceivedScene, perceive
from pickplan.perception.hull import HullSettings, visibility_hull

TARGET = "observed target"  # the target's name in a perceived world's SDF


@dataclass(frozen=True)
class PerceivedWorldSettings:
    field: FieldSettings = dataclass_field(default_factory=FieldSettings)
    grasps: PointGraspSettings = dataclass_field(default_factory=PointGraspSettings)
    body_points_per_link: Optional[int] = None  # as WorldSettings: None, the robot description's
    body_seed: int = 0
    hand_points_per_link: int = 60  # open-hand samples checked against the field and the plane
    target_resolution: float = 0.005  # m, the target's (excluded) distance grid
    isf_points: int = 1000  # observed target points C-Space ISF refines on (the paper: 1000)
    seed: int = 0  # plane RANSAC, hand samples, ISF subsample
    hull: HullSettings = dataclass_field(default_factory=HullSettings)
    use_hull: bool = False  # grasps clear the target's visibility hull, not only its observed points
    # where the seen surface gives fewer grasps than asked: pinches of parts seen from one side, their
    # far side bounded by the visibility hull (``grasps.hull_pinches``)
    hull_pinches: bool = True
    clock: StageClock = StageClock.wall  # what ``PerceivedWorld.seconds`` read (thread_cpu: a shared machine's
    #                                      other processes do not count)

    def __post_init__(self):
        object.__setattr__(self, "clock", StageClock.parse(self.clock, "stage clock"))

    def timer(self):
        return self.clock.timer()


@dataclass(frozen=True)
class ObservedScene:
    """What ``OMGPlanner`` reads of its scene when it plans in a perceived world: the target's name."""

    target: str = TARGET


class FieldChecker:
    """Collision test of a configuration against a perceived world: every body point outside the
    fused field (the target excluded: the fingers close on it); above the support plane, the
    fingers down to ``table_contact`` into it. ``native`` is None: a perceived scene has no FCL
    model, so the native goal set checks approaches with the clearance problem instead."""

    native = None

    def __init__(self, world: "PerceivedWorld", table_contact: float):
        self.world, self.table_contact = world, float(table_contact)

    def penetration(self, q) -> Tuple[float, float]:
        """(deepest body point in the field, deepest below the plane) in metres; >= 0 is clear."""
        w = self.world
        X = w.robot.transform_points(np.asarray(q, float)[None], w.body)[0]
        d, _ = w.sdf.distance(X, cutoff=0.05, exclude=(TARGET,), exclude_table=True)
        n, off = w.plane
        height = X @ n - off
        fingers = np.isin(w.body.links, [w.robot.link_index(f) for f in w.robot.finger_links])
        height = np.where(fingers, height + self.table_contact, height)
        return float(min(d.min(), 0.05)), float(min(height.min(), 0.05))

    def in_collision(self, q) -> bool:
        return min(self.penetration(q)) < 0.0


def target_grid(points: np.ndarray, resolution: float, margin: float = 0.03) -> "_core.SdfGrid":
    """Unsigned distance to the observed target points on a grid around them (world frame; exact,
    natively: ``_core.point_distance_grid``)."""
    lo = points.min(axis=0) - margin
    dims = np.ceil((points.max(axis=0) + margin - lo) / resolution).astype(int) + 1
    return _core.SdfGrid.from_values(lo, resolution, _core.point_distance_grid(points, lo, resolution, dims))


class PerceivedWorld:
    """A ``World`` built from an ``Observation`` (see the module docstring). ``robot`` None: the Panda; any described robot
    (``robots.load_robot``) otherwise."""

    def __init__(
        self,
        observation: Observation,
        robot=None,
        settings: PerceivedWorldSettings = PerceivedWorldSettings(),
        perceived: Optional[PerceivedScene] = None,
        cache: Optional[ModelCache] = None,
    ):
        if not isinstance(observation, Observation):
            raise TypeError(f"observation: expected a pickplan Observation, got {type(observation).__name__}")
        if robot is not None and not isinstance(robot, str) and not hasattr(robot, "info"):
            raise ValueError(
                "robot: expected a description name or file or a described robot (robots.load_robot), "
                f"got {type(robot).__name__}"
            )
        self.observation, self.settings = observation, settings
        self.scene = ObservedScene()
        clock = settings.timer()
        self.perceived = perceived or perceive(observation, settings.field, seed=settings.seed, clock=clock)
        t0 = clock()
        self.cache = ModelCache() if cache is None else cache  # the robot's data, shared with other worlds
        self.robot = self.cache.robot(robot if robot is not None else "panda", np.eye(4))
        if len(self.perceived.target_points) < 3:
            raise InputError(
                "fewer than 3 target points with depth inside the workspace; the target is not seen",
                path=None if observation.source == "<memory>" else observation.source,
                field="target_mask",
            )
        self.sdf: SceneSdf = self.perceived.sdf
        if TARGET not in self.sdf.names:  # a PerceivedScene handed to a second world has it already
            self.sdf.add_object(
                TARGET, target_grid(self.perceived.target_points, settings.target_resolution), np.eye(4)
            )
        self.body = self.cache.body_points(
            self.robot, settings.body_points_per_link or self.robot.description.body_points_per_link, settings.body_seed
        )
        self._refiners: dict = {}
        self._chomps: dict = {}
        self.seconds = dict(self.perceived.seconds, world=clock() - t0, grasps=0.0)

    @classmethod
    def load(cls, path, robot=None, settings: PerceivedWorldSettings = PerceivedWorldSettings()) -> "PerceivedWorld":
        return cls(Observation.load(path), robot, settings)

    @property
    def target(self) -> str:
        return TARGET

    @property
    def target_pose(self) -> np.ndarray:
        return np.eye(4)  # grasps from points are in the world frame

    @property
    def target_model(self):
        raise ValueError(
            "a perceived world has no object model: its grasps come from the observed points "
            "(PerceivedWorld.grasps; PerceivedPlanner plans with them)"
        )

    @property
    def graspability(self) -> Graspability:
        """Not judged from points (a partial view cannot show a width in every direction): a target
        no grasp from points fits ends as ``no_goals``."""
        return Graspability(True, "", float("nan"))

    @property
    def support_plane(self) -> Tuple[np.ndarray, float]:
        """The observed support plane as (unit normal, offset), as ``World.support_plane``."""
        return self.perceived.plane

    def over_support(self, points: np.ndarray) -> np.ndarray:
        """(N,) all True: the observed plane has no known edge."""
        return np.ones(len(points), dtype=bool)

    @property
    def plane(self) -> Tuple[np.ndarray, float]:
        return self.perceived.plane

    @property
    def start(self) -> np.ndarray:
        return self.robot.ready_configuration

    def checker(self, kind=CheckerKind.goal) -> FieldChecker:
        CheckerKind.parse(kind, "checker kind")
        return FieldChecker(self, self.settings.grasps.table_contact)

    @functools.cached_property
    def clearance_problem(self):
        """Body points in the fused field, target and table left out (as ``World.clearance_problem``)."""
        return Chomp(self.robot, self.sdf, self.body, exclude=(TARGET,)).problem

    @functools.cached_property
    def hull(self) -> np.ndarray:
        """Samples of where the target's unseen rest may be (``perception.hull.visibility_hull``; timed
        with the grasps that read it)."""
        return visibility_hull(self.observation, self.perceived.target_points, self.plane, self.settings.hull)

    @functools.cached_property
    def hand_sdf(self) -> SceneSdf:
        return self.cache.robot_derived(
            self.robot, "hand_sdf", lambda: isf.hand_sdf(self.robot, grids=self.cache.grids)
        )

    @functools.cached_property
    def hand_points(self) -> Tuple[np.ndarray, np.ndarray]:
        """Samples on the open hand and fingers in the hand frame, and whether each is on a finger (the
        robot's data: kept in the cache for every world of this robot)."""
        key = ("hand_points", self.settings.hand_points_per_link, self.settings.seed)
        return self.cache.robot_derived(self.robot, key, self._sample_hand_points)

    def _sample_hand_points(self) -> Tuple[np.ndarray, np.ndarray]:
        robot = self.robot
        links = (robot.hand_link,) + tuple(robot.finger_links)
        body = robot.sample_body_points(self.settings.hand_points_per_link, seed=self.settings.seed, links=links)
        q = robot.ready_configuration.copy()
        q[robot.info.arm_dof :] = robot.info.finger_open
        poses = robot.fk(q)
        H_inv = np.linalg.inv(poses[robot.link_index(robot.hand_link)])
        rel = np.einsum("ij,njk->nik", H_inv, poses[body.links])
        pts = np.einsum("nij,nj->ni", rel[:, :3, :3], body.points) + rel[:, :3, 3]
        return pts, np.isin(body.links, [robot.link_index(f) for f in robot.finger_links])

    @functools.cached_property
    def obstacle_distance(self) -> SdfQuery:
        """Distance of world points from the fused obstacles (target and table left out)."""
        return SdfQuery(self.sdf, cutoff=0.1, exclude=(TARGET,), exclude_table=True)

    def clear_of_plane(self, poses: np.ndarray, standoff: float) -> np.ndarray:
        """Per hand pose: the palm above the plane and the fingers above it less ``table_contact``, at
        the grasp and at the pre-grasp ``standoff`` back along the approach."""
        pts, fingers = self.hand_points
        n, d = self.plane
        allowance = np.where(fingers, self.settings.grasps.table_contact, 0.0)
        # a sample's height is p . (R^T n) + t . n - d: one product per sample and pose, no world points
        up = pts @ (poses[:, :3, :3].transpose(0, 2, 1) @ n).T + allowance[:, None]  # (samples, poses)
        lowest = up.min(axis=0)
        ok = np.ones(len(poses), dtype=bool)
        for back in (0.0, standoff):
            ok &= lowest + (poses[:, :3, 3] - back * poses[:, :3, 2]) @ n - d >= 0.0
        return ok

    def grasps(self, n: int = 100, seed: int = 0, standoff: float = GoalSetSettings.standoff) -> GraspSet:
        """Up to ``n`` grasps of the observed target (world frame) clear of the field and the plane: from
        its seen surface, then, where those are fewer than ``n`` (``settings.hull_pinches``), pinches of
        parts seen from one side, bounded by the visibility hull (``grasps.hull_pinches``)."""
        clock = self.settings.timer()
        t0 = clock()
        out = self._grasps_from_points(n, seed, standoff, self.hull if self.settings.use_hull else None, False)
        if len(out) < n and self.settings.hull_pinches:
            more = self._grasps_from_points(n - len(out), seed, standoff, self.hull, True)
            out = GraspSet(
                out.name,
                np.concatenate([out.poses, more.poses]),
                out.object_name,
                scores=np.concatenate([out.scores, more.scores]),
                info={k: np.concatenate([out.info[k], more.info[k]]) for k in out.info},
            )
        self.seconds["grasps"] += clock() - t0
        return out

    def _grasps_from_points(self, n: int, seed: int, standoff: float, hull, hull_pinches: bool) -> GraspSet:
        gs = grasps_from_points(
            self.perceived.target_points,
            self.perceived.target_normals,
            self.plane,
            self.hand_sdf,
            n=n,
            seed=seed,
            scene_distance=self.obstacle_distance,
            hand_points=self.hand_points[0],
            settings=self.settings.grasps,
            gripper=self.robot.info,
            hull=hull,
            denoised_points=self._quality_points[0] if self.settings.grasps.denoise else None,
            hull_pinches=hull_pinches,
        )
        keep = self.clear_of_plane(gs.poses, standoff) if len(gs) else np.zeros(0, dtype=bool)
        return GraspSet(
            gs.name,
            gs.poses[keep],
            gs.object_name,
            scores=gs.scores[keep],
            info={k: np.asarray(v)[keep] for k, v in gs.info.items()},
        )

    @functools.cached_property
    def _quality_points(self):
        """The observed target points denoised as grasps from points read them, and their k-d tree."""
        P = self.perceived.target_points
        if self.settings.grasps.denoise:
            P = denoised(P, self.perceived.target_normals, self.settings.grasps.patch_radius)
        return P, cKDTree(P)

    def grasp_verdicts(self, grasps: np.ndarray, settings: quality.QualitySettings):
        """(margins, fits) of ``grasp_quality``, as ``World.grasp_verdicts``; not kept: the points are new
        with every observation."""
        q = self.grasp_quality(grasps, settings)
        return q.margin, q.fit

    def light_load_holds(self, grasps: np.ndarray, settings: quality.QualitySettings) -> np.ndarray:
        """(N,) bool: which hand poses hold the target were it as light as such a target can be
        (``settings.point_density_light``): the goal set's second look at grasps that slip under the
        estimated load (``goals._second_look``)."""
        q = self.grasp_quality(grasps, settings, density=settings.point_density_light)
        return np.array([fit == quality.GraspFit.holds for fit in q.fit], dtype=bool)

    def grasp_quality(
        self, grasps: np.ndarray, settings: quality.QualitySettings, density: Optional[float] = None
    ) -> quality.Quality:
        """The quality (``grasps.quality``) of hand poses (world frame) on the observed target: patches
        on its denoised points (an unseen side mirrors the seen one), its load from the points
        (``point_geometry.points_load``: ``density``, by default ``settings.point_density``, over their
        hull down to the plane)."""
        P, tree = self._quality_points
        load = points_load(P, self.plane, settings.point_density if density is None else density)
        frames = np.asarray(grasps, float).reshape(-1, 4, 4) @ self.robot.info.grasp_frame
        grip = quality.Grip.of(self.robot.info, settings.object_friction)
        # no normals: fitted on a few noisy points of a pen or an edge they are too rough to tilt a
        # friction cone by (the patches come from the points' positions alone)
        return quality.grasp_quality(
            P, frames, load, grip, settings, tree, mirror=True, compliance=settings.point_compliance
        )

    def isf_surface(self, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
        """A seeded subsample of the observed target points and normals (what ISF refines on)."""
        P, N = self.perceived.target_points, self.perceived.target_normals
        k = min(self.settings.isf_points, len(P))
        idx = np.sort(np.random.default_rng(seed).choice(len(P), k, replace=False))
        return P[idx], N[idx]

    chomp = World.chomp  # the same per-world CHOMP problems, on the fused field

    def grasp_refiner(self, settings: Optional[isf.IsfSettings] = None, seed: int = 0) -> isf.GraspRefiner:
        """C-Space ISF on the observed target points, built once per (settings, seed)."""
        settings = settings or isf.IsfSettings()
        key = (settings, int(seed))
        if key not in self._refiners:
            self._refiners[key] = isf.GraspRefiner(self, settings, seed=seed, surface=self.isf_surface(seed))
        return self._refiners[key]


class PerceivedPlanner(OMGPlanner):
    """``OMGPlanner`` on a ``PerceivedWorld``: the same Algorithm 2; default grasps from points.

    Made once and asked again and again, frame after frame: ``plan(observation=...)`` perceives the
    next observation into a new world that shares the planner's cache (the robot's data: its body and
    open-hand samples, the hand's field), so only what depends on the frame is computed again.

    >>> planner = PerceivedPlanner(settings=OMGSettings())      # the Panda; robot= any described robot
    >>> for obs in frames:
    ...     result = planner.plan(observation=obs)
    """

    def __init__(
        self,
        world: Optional[PerceivedWorld] = None,
        settings: OMGSettings = OMGSettings(),
        robot=None,
        world_settings: PerceivedWorldSettings = PerceivedWorldSettings(),
        cache: Optional[ModelCache] = None,
    ):
        if world is not None and not isinstance(world, PerceivedWorld):
            raise TypeError(f"world: expected a PerceivedWorld, got {type(world).__name__}")
        super().__init__(
            None, world.scene if world is not None else ObservedScene(), settings, world=world, cache=cache
        )
        self.perceived_robot = robot if robot is not None else (world.robot if world is not None else None)
        self.world_settings = world.settings if world is not None else world_settings

    def use_observation(self, observation: Observation) -> PerceivedWorld:
        """Plan in the world perceived from ``observation`` from now on (built now, from the cache)."""
        self._world = PerceivedWorld(observation, self.perceived_robot, self.world_settings, cache=self.cache)
        return self._world

    def world(self, target: Optional[str] = None) -> PerceivedWorld:
        if self._world is None:
            raise ValueError("no observation: give one (PerceivedPlanner(world) or plan(observation=...))")
        return self._world

    def plan(
        self,
        start: Optional[np.ndarray] = None,
        target: Optional[str] = None,
        grasps=None,
        scene=None,
        observation: Optional[Observation] = None,
    ):
        """``OMGPlanner.plan`` in the world of ``observation`` (``use_observation``) if given, else the
        current one; a perceived world has one target (``target`` and ``scene`` do not apply)."""
        if scene is not None:
            raise ValueError("a perceived planner plans from observations: plan(observation=...), not scene=")
        if observation is not None:
            self.use_observation(observation)
        return super().plan(start, None, grasps)

    def default_grasps(self, world: PerceivedWorld) -> np.ndarray:
        s = self.settings
        return world.grasps(s.grasp_count, s.seed, s.goals.standoff).poses
