"""Robot models: URDF kinematics (native), body points sampled on collision meshes.

>>> from pickplan.core import robots
>>> r = robots.panda()
>>> r.dof, r.link_names[:2]
(9, ['panda_link0', 'panda_link1'])
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import List, Optional, Sequence, Tuple, Union

import numpy as np

from pickplan import _core
from pickplan.core.description import RobotDescription, RobotInfo, parse_description
from pickplan.core.description_check import model_problems
from pickplan.core.errors import InputError, Problem
from pickplan.core.fields import FieldReader
from pickplan.core.panda import PANDA, PANDA_DESCRIPTION
from pickplan.core.meshes import geometry_to_trimesh

LinkRef = Union[int, str]


@dataclass(frozen=True)
class BodyPoints:
    """Points fixed on robot links (link-frame coordinates), with outward surface normals."""

    links: np.ndarray  # (N,) int32 link index of each point
    points: np.ndarray  # (N, 3) link-frame positions
    normals: np.ndarray  # (N, 3) link-frame unit normals

    def __len__(self) -> int:
        return int(self.links.shape[0])


class Robot:
    """A robot loaded from URDF. Immutable: ``with_base`` returns a moved copy.

    Configurations are numpy arrays of ``dof`` joint values in ``joint_names`` order,
    including gripper finger joints where the URDF has them.
    """

    def __init__(self, native: "_core.Robot", urdf_path: Optional[str] = None):
        self._native = native
        self.urdf_path = urdf_path
        # links fixed after loading (``with_attached_link``): (name, parent, origin bytes) each; what a
        # cache keyed by the model file must add to its key, since the file no longer says them
        self.attachments: Tuple[Tuple[str, str, bytes], ...] = ()

    @classmethod
    def from_urdf(cls, path: Union[str, os.PathLike], package_dirs: Sequence[str] = ()) -> "Robot":
        path = os.fspath(path)
        return cls(_core.Robot.from_urdf_file(path, [os.fspath(p) for p in package_dirs]), urdf_path=path)

    # --- model ---------------------------------------------------------------------------
    @property
    def native(self) -> "_core.Robot":
        return self._native

    @property
    def name(self) -> str:
        return self._native.name

    @property
    def dof(self) -> int:
        return self._native.dof

    @property
    def link_names(self) -> list:
        return list(self._native.link_names)

    @property
    def joint_names(self) -> list:
        return list(self._native.joint_names)

    @property
    def lower_limits(self) -> np.ndarray:
        return np.asarray(self._native.lower_limits)

    @property
    def upper_limits(self) -> np.ndarray:
        return np.asarray(self._native.upper_limits)

    @property
    def velocity_limits(self) -> np.ndarray:
        return np.asarray(self._native.velocity_limits)

    @property
    def base_pose(self) -> np.ndarray:
        return np.asarray(self._native.base_pose)

    def link_index(self, link: LinkRef) -> int:
        if isinstance(link, str):
            return self._native.link_index(link)
        if isinstance(link, bool) or not isinstance(link, (int, np.integer)):
            raise ValueError(f"link: expected a link name (str) or index (int), got {link!r:.40}")
        if not 0 <= int(link) < len(self.link_names):
            raise ValueError(f"link index {link} out of range [0, {len(self.link_names)})")
        return int(link)

    def with_base(self, base_pose: np.ndarray) -> "Robot":
        return type(self)._rewrap(self, self._native.with_base(np.asarray(base_pose, dtype=float)))

    def with_attached_link(self, name: str, parent: str, origin: np.ndarray) -> "Robot":
        """A copy with one more link, ``name``, fixed to ``parent`` at ``origin`` (4, 4; a held object)."""
        T = np.asarray(origin, dtype=float)
        new = type(self)._rewrap(self, self._native.with_attached_link(name, parent, T))
        new.attachments = tuple(getattr(self, "attachments", ())) + ((name, parent, T.tobytes()),)
        return new

    @classmethod
    def _rewrap(cls, old: "Robot", native) -> "Robot":
        new = object.__new__(cls)
        new.__dict__.update(old.__dict__)
        new._native = native
        return new

    # --- kinematics ----------------------------------------------------------------------
    def fk(self, q) -> np.ndarray:
        """World poses of every link, (num_links, 4, 4)."""
        return self._native.fk(q)

    def fk_batch(self, Q) -> np.ndarray:
        """World poses for a batch of configurations, (B, num_links, 4, 4)."""
        return self._native.fk_batch(Q)

    def link_pose(self, q, link: LinkRef) -> np.ndarray:
        return self._native.fk(q)[self.link_index(link)]

    def jacobian(self, q, link: LinkRef, point=None) -> np.ndarray:
        """6 x dof world Jacobian (linear rows, then angular) of a point fixed on ``link``."""
        return self._native.jacobian(q, link, point)

    def link_jacobians(self, q) -> np.ndarray:
        return self._native.link_jacobians(q)

    def transform_points(self, Q, body: BodyPoints) -> np.ndarray:
        """World positions (T, N, 3) of body points along a trajectory Q (T, dof)."""
        return self._native.transform_points(Q, self.check_link_indices(body.links), body.points)

    def check_link_indices(self, links, what: str = "body point links") -> np.ndarray:
        """``links`` as int32 after checking every index is in range before narrowing (so 2**32 + 3
        is refused, not wrapped to 3)."""
        arr = np.asarray(links)
        if arr.dtype.kind not in "iu":
            raise ValueError(f"{what}: expected integer link indices, got dtype {arr.dtype}")
        n = len(self.link_names)
        if arr.size and (arr.min() < 0 or arr.max() >= n):
            bad = arr[(arr < 0) | (arr >= n)].flat[0]
            raise ValueError(f"{what}: link index {int(bad)} out of range [0, {n})")
        return arr.astype(np.int32)

    def moving_links(self) -> list:
        """Indices of links moved by at least one joint (the fixed base chain is excluded)."""
        parents, q_index = self._native.link_parents, self._native.link_q_index
        moving = []
        for i in range(len(parents)):
            k = i
            while k >= 0 and q_index[k] < 0:
                k = parents[k]
            if k >= 0:
                moving.append(i)
        return moving

    def check_within_limits(self, q, name: str = "configuration", tolerance: float = 1e-6) -> np.ndarray:
        """``q`` as a float array; ValueError naming the first joint outside its limits (shape and
        NaN are checked by FK)."""
        self._native.fk(q)
        q = np.asarray(q, dtype=float)
        lo, hi = self.lower_limits - tolerance, self.upper_limits + tolerance
        bad = np.flatnonzero((q < lo) | (q > hi))
        if bad.size:
            j = int(bad[0])
            raise ValueError(
                f"{name}: joint {self.joint_names[j]} = {q[j]:.4f} is outside its limits "
                f"[{self.lower_limits[j]:.4f}, {self.upper_limits[j]:.4f}]"
            )
        return q

    def clip_to_limits(self, q) -> np.ndarray:
        return np.clip(np.asarray(q, dtype=float), self.lower_limits, self.upper_limits)

    def random_configurations(self, n: int, seed: int) -> np.ndarray:
        """n configurations uniform within the joint limits (continuous joints in [-pi, pi])."""
        rng = np.random.default_rng(seed)
        lo = np.where(np.isfinite(self.lower_limits), self.lower_limits, -np.pi)
        hi = np.where(np.isfinite(self.upper_limits), self.upper_limits, np.pi)
        return rng.uniform(lo, hi, size=(n, self.dof))

    # --- geometry ------------------------------------------------------------------------
    def collision_meshes(self, link: LinkRef):
        """The collision geometry of a link as one trimesh in the link frame (None if it has none)."""

        parts = [geometry_to_trimesh(g) for g in self._native.collision_geometries(self.link_index(link))]
        if not parts:
            return None
        import trimesh

        return trimesh.util.concatenate(parts) if len(parts) > 1 else parts[0]

    def sample_body_points(
        self, per_link: int = 20, seed: int = 0, links: Optional[Sequence[LinkRef]] = None
    ) -> BodyPoints:
        """Sample ``per_link`` points and normals on each link's collision surface (seeded).

        By default every link that moves (``moving_links``); links without collision geometry
        contribute no points.
        """
        if per_link < 1:
            raise ValueError(f"per_link must be >= 1, got {per_link}")
        import trimesh

        rng = np.random.default_rng(seed)
        chosen = self.moving_links() if links is None else [self.link_index(l) for l in links]
        all_links, all_pts, all_nrm = [], [], []
        for li in chosen:
            mesh = self.collision_meshes(li)
            if mesh is None or mesh.area <= 0:
                continue
            pts, faces = trimesh.sample.sample_surface(mesh, per_link, seed=int(rng.integers(2**31)))
            all_links.append(np.full(len(pts), li, dtype=np.int32))
            all_pts.append(np.asarray(pts, dtype=float))
            all_nrm.append(np.asarray(mesh.face_normals[faces], dtype=float))
        if not all_pts:
            return BodyPoints(np.zeros(0, np.int32), np.zeros((0, 3)), np.zeros((0, 3)))
        return BodyPoints(np.concatenate(all_links), np.concatenate(all_pts), np.concatenate(all_nrm))


class DescribedRobot(Robot):
    """A robot with a parallel gripper, built from its description (``core.description``): the hand
    and finger links and joints, the grasp frame, the start configuration and the limits (``info``)."""

    info: RobotInfo = PANDA
    description: RobotDescription = PANDA_DESCRIPTION

    @property
    def hand_link(self) -> str:
        return self.info.hand_link

    @property
    def finger_links(self) -> tuple:
        return self.info.finger_links

    @property
    def finger_joints(self) -> tuple:
        return self.info.finger_joints

    @property
    def arm_dof(self) -> int:
        return self.info.arm_dof

    @property
    def grasp_frame(self) -> np.ndarray:
        """The grasp frame in the hand link (z approach, y closing, origin between the pads)."""
        return np.array(self.info.grasp_frame)

    @property
    def ready_configuration(self) -> np.ndarray:
        return np.array(self.info.ready, dtype=float)

    def with_fingers(self, q, value: float) -> np.ndarray:
        """``q`` (one configuration or a batch) with every finger joint at ``value``."""
        q = np.array(q, dtype=float)
        q[..., self.info.arm_dof :] = value
        return q


def robot_for(desc: RobotDescription) -> Robot:
    """The kinematic model a description names, at its base pose (no check of the description)."""
    return Robot.from_urdf(desc.urdf, desc.package_dirs).with_base(desc.base_pose)


def _described(name_or_file: str) -> Tuple[Optional[RobotDescription], Optional[DescribedRobot], List[Problem]]:
    """(the description, its robot at the identity base, every problem of the file's form and of the
    description against the model): the one path ``check_description`` and ``load_robot`` share."""
    desc, problems = parse_description(name_or_file)
    if desc is None or not desc.urdf or any(p.field.startswith(("urdf", "mount")) for p in problems):
        return desc, None, problems  # no robot to check the rest against
    r = FieldReader(desc.source)
    r.problems = list(problems)
    try:
        robot = DescribedRobot(
            _core.Robot.from_urdf_file(desc.urdf, [os.fspath(p) for p in desc.package_dirs]), urdf_path=desc.urdf
        )
    except (ValueError, RuntimeError, OSError) as exc:
        message = str(exc)
        if len(desc.urdf_files) > 1:  # a composed file of pickplan's: name the user's files instead
            message = message.replace(
                desc.urdf, f"the arm's URDF {desc.urdf_files[0]} with the gripper's {desc.urdf_files[1]} mounted"
            )
        r.note("mount.urdf" if len(desc.urdf_files) > 1 else "urdf", message)
        return desc, None, r.problems
    model_problems(r, desc, robot)
    return desc, robot, r.problems


def check_description(name_or_file: str) -> Tuple[Optional[RobotDescription], List[Problem]]:
    """(the description, []) when it is usable, else (None or the description, every problem found):
    what ``pickplan robots check`` prints, and exactly what makes ``load_robot`` refuse a file."""
    desc, _, problems = _described(name_or_file)
    return desc, problems


def load_robot(name_or_file: str = "panda", base_pose: Optional[np.ndarray] = None) -> DescribedRobot:
    """The robot a description names (a shipped name, a short name like "iiwa", or a .toml file),
    placed at ``base_pose @ description.base_pose`` (``base_pose``: the scene's robot base);
    InputError with every problem ``check_description`` finds."""
    if isinstance(name_or_file, DescribedRobot):
        return (
            name_or_file
            if base_pose is None
            else name_or_file.with_base(base_pose @ name_or_file.description.base_pose)
        )
    desc, robot, problems = _described(str(name_or_file))
    if problems:
        raise InputError(problems=problems)
    robot.info, robot.description = (
        RobotInfo.from_description(desc),
        desc,
    )  # per instance: the class defaults are the Panda's
    base = np.eye(4) if base_pose is None else np.asarray(base_pose, dtype=float)
    return robot.with_base(base @ desc.base_pose)


def panda(base_pose: Optional[np.ndarray] = None) -> DescribedRobot:
    """The Panda shipped in pybullet_data (7 arm joints + 2 finger joints, real limits):
    ``load_robot("panda", base_pose)``."""
    return load_robot("panda", base_pose)
