"""Whether a parallel gripper can grasp an object lying on a support at all, from geometry alone.

A two-finger grasp needs two opposing surface patches (antipodal: each normal within the friction
cone of the line joining them) closer together than the gripper opens, along a closing axis the
fingers can reach: roughly parallel to the support, since a finger cannot go under an object lying
on it. The patches are found by rays: from seeded surface samples into the object along the inward
normal to the surface they leave it through (meshes that are not watertight just lose the rays that
find no exit). The object's own frame gives the pairs once; a pose only tilts their axes.

>>> verdict = graspability(model, scene.object(scene.target).pose, max_opening=0.08)
>>> verdict.graspable, verdict.reason   # (False, "wider than the 8 cm opening in every direction")
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple, Tuple

import numpy as np
import trimesh


@dataclass(frozen=True)
class GraspabilitySettings:
    samples: int = 600            # surface points, each casting one ray inwards
    seed: int = 0
    friction_cone_deg: float = 20.0   # exit normal within this of the ray: an antipodal pair
    width_margin: float = 0.005   # m the pair must be narrower than the opening (as antipodal grasps are)
    max_slope_deg: float = 40.0   # closing axis at most this steep against the support plane
    # Fewer graspable pairs than this fraction of the rays: a seam or ridge of a scanned mesh (the YCB
    # master chef can's lid: 2 % of the rays), not a part a pad can hold.
    min_fraction: float = 0.03


class Graspability(NamedTuple):
    graspable: bool
    reason: str                   # "" when graspable, else why not ("wider than the 8 cm opening ...")
    narrowest: float              # m: the narrowest antipodal width along a reachable closing axis (inf: none)


@functools.lru_cache(maxsize=256)  # a memo of a deterministic function of the mesh; bounded
def _pairs(vertices: bytes, faces: bytes, samples: int, seed: int, cone_deg: float) -> Tuple[np.ndarray, np.ndarray]:
    V = np.frombuffer(vertices).reshape(-1, 3)
    F = np.frombuffer(faces, dtype=np.int64).reshape(-1, 3)
    mesh = trimesh.Trimesh(V, F, process=False)
    p, face = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    d = -np.asarray(mesh.face_normals[face])
    loc, ray, tri = mesh.ray.intersects_location(p + 1e-5 * d, d, multiple_hits=False)
    if len(ray) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    aligned = np.einsum("ij,ij->i", mesh.face_normals[tri], d[ray]) >= np.cos(np.radians(cone_deg))
    ray, loc = ray[aligned], loc[aligned]
    return d[ray], np.linalg.norm(loc - p[ray], axis=1)


def antipodal_widths(mesh, settings: GraspabilitySettings = GraspabilitySettings()) -> Tuple[np.ndarray, np.ndarray]:
    """(axes (K, 3) in the object frame, widths (K,)) of the antipodal pairs the rays find."""
    V = np.ascontiguousarray(mesh.vertices, dtype=float)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    return _pairs(V.tobytes(), F.tobytes(), int(settings.samples), int(settings.seed),
                  float(settings.friction_cone_deg))


def graspability(model, pose, max_opening: float, up=(0.0, 0.0, 1.0),
                 settings: GraspabilitySettings = GraspabilitySettings()) -> Graspability:
    """The verdict for ``model`` at world ``pose`` on a support with normal ``up``, for a gripper
    opening ``max_opening`` m between its pads."""
    if not 0 < max_opening < 1:
        raise ValueError(f"max_opening: expected metres in (0, 1), got {max_opening}")
    axes, widths = antipodal_widths(model.mesh, settings)
    up = np.asarray(up, float) / np.linalg.norm(up)
    slope = np.degrees(np.arcsin(np.clip(np.abs(axes @ (np.asarray(pose, float)[:3, :3].T @ up)), 0.0, 1.0)))
    narrow = widths <= max_opening - settings.width_margin
    reachable = slope <= settings.max_slope_deg
    ok = narrow & reachable
    cm = f"{100 * max_opening:.0f} cm"
    enough = max(2, int(np.ceil(settings.min_fraction * len(widths))))
    if ok.sum() >= enough:
        return Graspability(True, "", float(widths[ok].min()))
    if narrow.sum() >= enough:
        thin = float(np.median(widths[narrow]))
        return Graspability(False, f"only {100 * thin:.1f} cm thick up from the support, wider than the {cm} "
                                   "opening across: a flat face under a wide object", float("inf"))
    return Graspability(False, f"wider than the {cm} opening in every direction", float("inf"))
