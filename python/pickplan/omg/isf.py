"""C-Space ISF grasp refinement (OMG Sec. III-E, Algorithm 1), native, for one target in one scene."""

from __future__ import annotations

import copy
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional, Tuple

import numpy as np
import trimesh

from pickplan import _core
from pickplan.omg import grasps
from pickplan.core import sdf
from pickplan.core.settings import native_defaults, to_native

if TYPE_CHECKING:  # the world owns its refiner; isf only reads it
    from pickplan.omg.world import World


@dataclass(frozen=True)
@native_defaults(_core.IsfSettings)
class IsfSettings:
    """Mirror of the native ``IsfSettings``; alpha, beta, gamma and eta_grasp are the paper's."""

    alpha: float
    beta: float
    gamma: float
    step_size: float
    max_halvings: int
    length_unit: float
    hand_epsilon: float
    arm_epsilon: float
    max_joint_step: float

    def to_native(self, active) -> "_core.IsfSettings":
        return to_native(self, _core.IsfSettings, active=[bool(a) for a in active])


def hand_sdf(
    robot, opening: Optional[float] = None, resolution: float = 0.002, grids: "sdf.GridCache | None" = None
) -> sdf.SceneSdf:
    """The robot's hand and its fingers (at ``opening``, default open) as SDF parts in the hand-link
    frame (min over parts, so the overlapping closed meshes need no boolean union); part grids from
    ``grids`` when given."""
    q = robot.with_fingers(robot.ready_configuration, robot.info.finger_open if opening is None else opening)
    poses = robot.fk(q)
    H_inv = np.linalg.inv(poses[robot.link_index(robot.hand_link)])
    settings = sdf.SdfSettings(resolution=resolution, margin=0.03)
    names = (robot.hand_link,) + tuple(robot.finger_links)
    meshes = sdf.mesh_sdfs([robot.collision_meshes(name) for name in names], settings, grids)
    hand = sdf.SceneSdf((name, grid, H_inv @ poses[robot.link_index(name)]) for name, grid in zip(names, meshes))
    # One lookup instead of one per part, at the parts' own resolution (queries use a 1 cm cutoff).
    hand.merge(resolution=resolution, cutoff=settings.margin)
    return hand


def object_surface_local(mesh: trimesh.Trimesh, n: int = 1000, seed: int = 0) -> Tuple[np.ndarray, np.ndarray]:
    """n seeded surface samples of the object with outward normals, in the object frame."""
    pts, faces = trimesh.sample.sample_surface(mesh, n, seed=seed)
    return np.asarray(pts), np.asarray(mesh.face_normals[faces])


def object_surface(
    mesh: trimesh.Trimesh,
    pose: np.ndarray,
    n: int = 1000,
    seed: int = 0,
    local: Optional[Tuple[np.ndarray, np.ndarray]] = None,
) -> Tuple[np.ndarray, np.ndarray]:
    """n seeded surface samples of the object with outward normals, in the world (placing
    ``local``, the object-frame samples, when the caller has them)."""
    pts, normals = object_surface_local(mesh, n, seed) if local is None else local
    return (pts @ pose[:3, :3].T + pose[:3, 3], normals @ pose[:3, :3].T)


class GraspRefiner:
    """f_grasp and C-Space ISF steps for the world's target (1000 object points, as the paper).

    ``surface``: the target's points and outward normals in the world, (N, 3) each, when they come
    from elsewhere than its mesh (a depth camera's observed points); None samples the mesh."""

    def __init__(
        self,
        world: "World",
        settings: IsfSettings = IsfSettings(),
        object_points: int = 1000,
        seed: int = 0,
        surface: Optional[Tuple[np.ndarray, np.ndarray]] = None,
    ):
        robot, cache = world.robot, world.cache
        contacts = grasps.hand_contacts(robot=robot)  # this gripper's pads
        if surface is None:
            # Object-frame samples and the hand SDF depend on the model and the robot only: from the cache.
            mesh = world.target_model.mesh
            local = cache.surface(mesh, object_points, seed, object_surface_local)
            pts, nrm = object_surface(mesh, world.target_pose, object_points, seed, local=local)
        else:
            pts, nrm = (np.ascontiguousarray(a, dtype=float) for a in surface)
            if pts.ndim != 2 or pts.shape[1] != 3 or nrm.shape != pts.shape or len(pts) == 0:
                raise ValueError(
                    f"surface: expected points and normals as two (N, 3) arrays, got {pts.shape}, {nrm.shape}"
                )
        active = [i < robot.info.arm_dof for i in range(robot.dof)]
        exclude = 1 << world.sdf.index(world.target)
        self._hand_sdf = cache.robot_derived(robot, "hand_sdf", lambda: hand_sdf(robot, grids=cache.grids))
        self.settings, self._object_points, self._from_mesh = settings, object_points, surface is None
        self._pose = np.array(world.target_pose, dtype=float)  # where the samples were placed
        self._native = _core.GraspRefiner(
            robot.native,
            robot.hand_link,
            contacts.points,
            contacts.normals,
            self._hand_sdf.native,
            pts,
            nrm,
            world.sdf.native,
            world.body.links,
            world.body.points,
            exclude,
            settings.to_native(active),
        )
        fingers = tuple(getattr(robot, "finger_links", ()))
        if fingers:  # ISF steps may let the fingers touch the support, not press deeper into it
            vertices = cache.finger_geometry(robot, world.start).vertices
            normal, offset = world.support_plane
            self._native.set_support(vertices, np.asarray(normal, dtype=float), float(offset))

    def placed(self, world: "World", seed: int = 0) -> "GraspRefiner":
        """This refiner with the world's target where it lies now (it moved: ``World.move_object``); the
        object-frame samples, hand SDF and support are reused (a rebuild from the mesh would give the same)."""
        if not self._from_mesh:
            raise ValueError(
                "GraspRefiner.placed: this refiner's surface was given (observed points), not sampled "
                "from the target's mesh; build a new one for the new points"
            )
        mesh = world.target_model.mesh
        local = world.cache.surface(mesh, self._object_points, seed, object_surface_local)
        pts, nrm = object_surface(mesh, world.target_pose, self._object_points, seed, local=local)
        out = copy.copy(self)
        out._pose = np.array(world.target_pose, dtype=float)
        out._native = self._native.with_object(pts, nrm, out._pose @ np.linalg.inv(self._pose))
        return out

    def cost(self, q) -> Tuple["_core.GraspTerms", np.ndarray]:
        """f_grasp terms (pml, align, isf, hand, obstacle, collision, total) and the gradient."""
        return self._native.cost(q)

    def refine(self, q, iterations: int = 1) -> Tuple[np.ndarray, "_core.GraspTerms"]:
        return self._native.refine(q, iterations)

    def support_depth(self, q) -> float:
        """How far the fingers reach below the support plane at q (m; negative: above it)."""
        return self._native.support_depth(q)
