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

import threading
from dataclasses import dataclass
from typing import NamedTuple, Tuple

import numpy as np
import trimesh

from pickplan.core.caches import memo


@dataclass(frozen=True)
class GraspabilitySettings:
    samples: int = 600  # surface points, each casting one ray inwards
    seed: int = 0
    friction_cone_deg: float = 20.0  # exit normal within this of the ray: an antipodal pair
    width_margin: float = 0.005  # m the pair must be narrower than the opening (as antipodal grasps are)
    max_slope_deg: float = 40.0  # closing axis at most this steep against the support plane
    finger_clearance: float = 0.008  # m beside each contact where a finger stands: it must see the sky
    # Fewer graspable pairs than this fraction of the rays: a seam or ridge of a scanned mesh (the YCB
    # master chef can's lid: 2 % of the rays), not a part a pad can hold.
    min_fraction: float = 0.03


class Graspability(NamedTuple):
    graspable: bool
    reason: str  # "" when graspable, else why not ("wider than the 8 cm opening ...")
    # m: the narrowest antipodal width found along a reachable closing axis with room for the fingers (inf: none)
    narrowest: float


@memo(256)
def _pairs(
    vertices: bytes, faces: bytes, samples: int, seed: int, cone_deg: float
) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    V = np.frombuffer(vertices).reshape(-1, 3)
    F = np.frombuffer(faces, dtype=np.int64).reshape(-1, 3)
    mesh = trimesh.Trimesh(V, F, process=False)
    p, face = trimesh.sample.sample_surface(mesh, samples, seed=seed)
    d = -np.asarray(mesh.face_normals[face])
    loc, ray, tri = mesh.ray.intersects_location(p + 1e-5 * d, d, multiple_hits=False)
    if len(ray) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0)
    aligned = np.einsum("ij,ij->i", mesh.face_normals[tri], d[ray]) >= np.cos(np.radians(cone_deg))
    ray, loc = ray[aligned], loc[aligned]
    return p[ray], loc, d[ray], np.linalg.norm(loc - p[ray], axis=1)


def antipodal_pairs(mesh, settings: GraspabilitySettings = GraspabilitySettings()):
    """(p, q, axes, widths) of the antipodal pairs the rays find, in the object frame: contacts
    (K, 3) each, the unit axis from p to q (K, 3), the widths (K,)."""
    V = np.ascontiguousarray(mesh.vertices, dtype=float)
    F = np.ascontiguousarray(mesh.faces, dtype=np.int64)
    return _pairs(
        V.tobytes(), F.tobytes(), int(settings.samples), int(settings.seed), float(settings.friction_cone_deg)
    )


class RayMesh:
    """A private copy of a mesh for ray queries, its ray tree built at construction, and the lock its
    queries hold: trimesh builds the tree lazily and unlocked (threads sharing a model's mesh raced on
    it: a double free in rtree), and rtree does not promise concurrent queries. Depends on the mesh
    only, so a ``ModelCache`` keeps one per object for every scene (``ModelCache.ray_mesh``)."""

    def __init__(self, mesh):
        self.mesh = trimesh.Trimesh(np.array(mesh.vertices), np.array(mesh.faces), process=False)
        self.lock = threading.Lock()
        self.mesh.ray.intersects_any(np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))  # builds the tree now


def graspability(
    model,
    pose,
    max_opening: float,
    up=(0.0, 0.0, 1.0),
    settings: GraspabilitySettings = GraspabilitySettings(),
    ray_mesh: "RayMesh | None" = None,
) -> Graspability:
    """The verdict for ``model`` at world ``pose`` on a support with normal ``up``, for a gripper
    opening ``max_opening`` m between its pads. ``ray_mesh``: the model's mesh as a ``RayMesh``
    (None: a private one for this call)."""
    if not 0 < max_opening < 1:
        raise ValueError(f"max_opening: expected metres in (0, 1), got {max_opening}")
    p, q, axes, widths = antipodal_pairs(model.mesh, settings)
    up = np.asarray(pose, float)[:3, :3].T @ (np.asarray(up, float) / np.linalg.norm(up))  # object frame
    slope = np.degrees(np.arcsin(np.clip(np.abs(axes @ up), 0.0, 1.0)))
    narrow = widths <= max_opening - settings.width_margin
    reachable = slope <= settings.max_slope_deg
    ok = narrow & reachable
    cm = f"{100 * max_opening:.0f} cm"
    enough = max(2, int(np.ceil(settings.min_fraction * len(widths))))
    if ok.sum() >= enough:
        # In sample order, a chunk at a time, until enough are open; after 8 chunks the open share of
        # the checked pairs, scaled to all of them, decides (a bounded cost for a negative verdict).
        ray_mesh = RayMesh(model.mesh) if ray_mesh is None else ray_mesh
        idx, found, checked = np.flatnonzero(ok), [], 0
        with ray_mesh.lock:
            for chunk in np.array_split(idx, int(np.ceil(len(idx) / (2 * enough))))[:8]:
                found += list(
                    chunk[
                        _fingers_see_the_sky(
                            ray_mesh.mesh, p[chunk], q[chunk], axes[chunk], up, settings.finger_clearance
                        )
                    ]
                )
                checked += len(chunk)
                if len(found) >= enough:
                    break
        if found and len(found) * len(idx) >= enough * checked:
            return Graspability(True, "", float(widths[found].min()))
        return Graspability(
            False,
            "its narrow parts are closed off from above (a finger would have to go under it or inside it)",
            float("inf"),
        )
    if narrow.sum() >= enough:
        thin = float(np.median(widths[narrow]))
        return Graspability(
            False,
            f"only {100 * thin:.1f} cm thick up from the support, wider than the {cm} "
            "opening across: a flat face under a wide object",
            float("inf"),
        )
    return Graspability(False, f"wider than the {cm} opening in every direction", float("inf"))


def _fingers_see_the_sky(mesh, p, q, axes, up, clearance: float) -> np.ndarray:
    """(K,) whether a finger can stand beside both contacts of each pair: from the point
    ``clearance`` outside each contact, some ray upwards (vertical, or 45 degrees off towards either
    side of the axis or away from the object) leaves without meeting the object."""
    side = np.cross(axes, up)
    side /= np.maximum(np.linalg.norm(side, axis=1, keepdims=True), 1e-12)
    ok = np.ones(len(p), bool)
    for point, outward in ((p, -axes), (q, axes)):
        start = point + clearance * outward
        seen = np.zeros(len(p), bool)
        for lean in (None, side, -side, outward):
            d = np.broadcast_to(up, start.shape) if lean is None else (up + lean) / np.sqrt(2.0)
            todo = np.flatnonzero(~seen)
            if len(todo) == 0:
                break
            seen[todo] = ~mesh.ray.intersects_any(start[todo], d[todo] if d.ndim == 2 else d)
        ok &= seen
    return ok
