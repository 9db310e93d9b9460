"""Depth observations of a scene rendered in PyBullet, from cameras a user could mount.

The robot is not rendered: a real system filters its own body out of the depth images (from its
joint states and model), and the planner checks the robot against the scene, not against itself.
Depth comes from PyBullet's depth buffer, the target mask from its segmentation buffer; optional
Gaussian depth noise (seeded).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import List, Sequence

import numpy as np

from pickplan.core.observation import Observation
from pickplan.sim import scenes as scenes_mod


@dataclass(frozen=True)
class CameraRig:
    """Cameras on a circle around the table's work area, looking at its centre."""

    width: int = 640
    height: int = 480
    fov_deg: float = 58.0  # vertical field of view (a RealSense D435's depth camera)
    near: float = 0.1
    far: float = 4.0
    look_at: Sequence[float] = (0.55, 0.0, 0.05)
    distance: float = 1.1  # m from the look-at point
    elevation_deg: float = 50.0  # above the table plane
    azimuths_deg: Sequence[float] = (0.0, 70.0, -70.0)  # 0: across the table, facing the robot

    def intrinsics(self) -> np.ndarray:
        fy = 0.5 * self.height / math.tan(math.radians(self.fov_deg) / 2)
        return np.array([[fy, 0.0, self.width / 2], [0.0, fy, self.height / 2], [0.0, 0.0, 1.0]])

    def camera_poses(self, views: int) -> List[np.ndarray]:
        """Camera -> world (OpenCV axes) of the first ``views`` cameras."""
        if not 1 <= views <= len(self.azimuths_deg):
            raise ValueError(f"views: expected 1 to {len(self.azimuths_deg)}, got {views}")
        target = np.asarray(self.look_at, float)
        poses = []
        for az in self.azimuths_deg[:views]:
            a, e = math.radians(az), math.radians(self.elevation_deg)
            eye = target + self.distance * np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
            z = (target - eye) / np.linalg.norm(target - eye)
            x = np.cross(z, [0.0, 0.0, 1.0])
            x /= np.linalg.norm(x)
            T = np.eye(4)
            T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
            T[:3, 3] = eye
            poses.append(T)
        return poses


def render_observation(
    scene: scenes_mod.Scene, views: int = 3, noise: float = 0.0, seed: int = 0, rig: CameraRig = CameraRig()
) -> Observation:
    """Depth images of ``scene`` from ``views`` cameras of ``rig`` (noise: depth sigma in metres)."""
    from pickplan.sim.bullet import connect, pb

    if not (np.isfinite(noise) and noise >= 0):
        raise ValueError(f"noise: expected a depth sigma >= 0 (m), got {noise}")
    rng = np.random.default_rng(seed)
    client = connect()
    try:
        ids = scenes_mod.load_into_pybullet(scene, client, with_robot=False)
        K = rig.intrinsics()
        aspect = rig.width / rig.height
        proj = pb.computeProjectionMatrixFOV(rig.fov_deg, aspect, rig.near, rig.far, physicsClientId=client)
        depths, masks, rgbs, poses = [], [], [], rig.camera_poses(views)
        for T in poses:
            eye, forward, down = T[:3, 3], T[:3, 2], T[:3, 1]
            view = pb.computeViewMatrix(
                eye.tolist(), (eye + forward).tolist(), (-down).tolist(), physicsClientId=client
            )
            _, _, rgba, zbuf, seg = pb.getCameraImage(
                rig.width, rig.height, view, proj, renderer=pb.ER_TINY_RENDERER, physicsClientId=client
            )
            z = np.reshape(np.asarray(zbuf, float), (rig.height, rig.width))
            depth = rig.far * rig.near / (rig.far - (rig.far - rig.near) * z)
            depth[z >= 1.0 - 1e-7] = 0.0  # nothing hit: no return
            if noise > 0:
                hit = depth > 0
                depth[hit] += rng.normal(0.0, noise, int(hit.sum()))
            seg = np.reshape(np.asarray(seg, np.int64), (rig.height, rig.width))
            depths.append(depth.astype(np.float32))
            masks.append((seg & ((1 << 24) - 1)) == ids[scene.target])
            rgbs.append(np.reshape(np.asarray(rgba, np.uint8), (rig.height, rig.width, 4))[..., :3])
        return Observation(
            np.stack(depths),
            np.stack([K] * views),
            np.stack(poses),
            np.stack(masks),
            np.stack(rgbs),
            source=f"render of scene seed {scene.seed}",
        )
    finally:
        pb.disconnect(client)
