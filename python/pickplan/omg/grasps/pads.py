"""Finger-pad contact points of a parallel gripper (what C-Space ISF pulls onto the object's surface),
in the hand-link frame, derived for every described robot (the Panda's included) from its finger links'
collision geometry.

A grid of rays is cast from the grasp frame's mid-plane (y = 0, between the pads) outwards along the
closing axis onto each finger; the first hit of each ray on a face turned towards the other finger,
within ``flat_tol`` of the innermost hit, inside the pad's extent (``pad_length`` along the approach
axis centred on the grasp frame's origin, ``pad_width`` across) is a contact point.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import trimesh

from pickplan.core.caches import memo


@dataclass(frozen=True)
class HandContacts:
    """Finger-pad points and inward normals (towards the other finger) in the hand-link frame."""

    points: np.ndarray  # (M, 3) at finger joints = ``opening``
    normals: np.ndarray  # (M, 3) unit, pointing into the grasp (opposite the object's outward normal)
    finger: np.ndarray  # (M,) index of the finger (its finger joint) each point is on
    axes: np.ndarray  # (F, 3) direction each finger moves as its joint value grows
    opening: float = 0.0  # the finger joint value the points are for

    def at(self, opening: float) -> "HandContacts":
        """The same contacts with every finger joint at ``opening``."""
        pts = self.points + self.axes[self.finger] * (float(opening) - self.opening)
        return replace(self, points=pts, opening=float(opening))


@dataclass(frozen=True)
class RayPadSettings:
    rows: int = 7  # rays along the approach axis
    cols: int = 7  # rays across the finger
    margin: float = 0.0012  # m kept from the pad's edges
    flat_tol: float = 0.0005  # m: hits deeper than this behind the innermost are not pad
    max_normal_deg: float = 5.0  # faces turned more than this from the closing axis are not pad


def gripper_contacts(robot, settings: RayPadSettings = RayPadSettings()) -> HandContacts:
    """The pads of a ``robots.DescribedRobot``'s fingers at its open configuration (remembered per
    gripper: the pads are a property of the description, not of one robot instance)."""
    return _contacts(robot, settings)


@memo(16, key=lambda robot, settings: (robot.info.key, settings))
def _contacts(robot, settings: RayPadSettings) -> HandContacts:
    info = robot.info
    q = robot.ready_configuration
    poses = robot.fk(q)
    H_inv = np.linalg.inv(poses[robot.link_index(info.hand_link)])
    G = info.grasp_frame  # grasp frame in the hand link
    G_inv = np.linalg.inv(G)
    pad_width = float(robot.description.gripper.pad_width) or np.inf
    pts, nrm, idx, axes = [], [], [], []
    for k, (link, joint) in enumerate(zip(info.finger_links, info.finger_joints)):
        mesh = robot.collision_meshes(link)
        if mesh is None:
            raise ValueError(f"{info.name}: finger link {link!r} has no collision geometry to find its pad on")
        mesh = mesh.copy()
        mesh.apply_transform(G_inv @ H_inv @ poses[robot.link_index(link)])  # finger in the grasp frame
        dq = np.zeros(robot.dof)
        dq[robot.joint_names.index(joint)] = 1e-4
        moved = (H_inv @ robot.fk(q + dq)[robot.link_index(link)])[:3, 3] - (H_inv @ poses[robot.link_index(link)])[
            :3, 3
        ]
        axes.append(moved / 1e-4)
        side = 1.0 if mesh.vertices[:, 1].mean() > 0 else -1.0  # the finger at +y or -y of the gap
        lo, hi = mesh.bounds
        half_len = 0.5 * info.pad_length - settings.margin
        zs = np.linspace(max(-half_len, lo[2] + settings.margin), min(half_len, hi[2] - settings.margin), settings.rows)
        half_w = min(0.5 * (hi[0] - lo[0]), 0.5 * pad_width) - settings.margin
        xs = np.linspace(0.5 * (hi[0] + lo[0]) - half_w, 0.5 * (hi[0] + lo[0]) + half_w, settings.cols)
        origins = np.array([[x, 0.0, z] for z in zs for x in xs])
        direction = np.array([0.0, side, 0.0])
        loc, ray, tri = trimesh.ray.ray_triangle.RayMeshIntersector(mesh).intersects_location(
            origins, np.tile(direction, (len(origins), 1)), multiple_hits=False
        )
        if len(loc) == 0:
            raise ValueError(
                f"{info.name}: no pad found on {link!r} between the grasp frame's z = "
                f"+-{info.pad_length / 2} m (is the grasp frame between the pads?)"
            )
        good = (mesh.face_normals[tri] @ -direction) > np.cos(np.radians(settings.max_normal_deg))
        depth = (loc - origins[ray]) @ direction
        good &= depth <= depth[good].min() + settings.flat_tol if good.any() else good
        order = np.argsort(ray[good])
        local = np.c_[loc[good][order], np.ones(int(good.sum()))]
        pts.append((G @ local.T).T[:, :3])
        nrm.append(np.tile(G[:3, :3] @ -direction, (int(good.sum()), 1)))
        idx.append(np.full(int(good.sum()), k))
    return HandContacts(
        np.concatenate(pts),
        np.concatenate(nrm),
        np.concatenate(idx).astype(np.int64),
        np.asarray(axes),
        float(info.finger_open),
    )
