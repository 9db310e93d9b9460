"""Mesh helpers shared by robots and objects (trimesh)."""

from __future__ import annotations

from typing import List

import numpy as np
from pickplan.core.errors import InputError


def geometry_to_trimesh(geom):
    """A URDF collision geometry (the native Robot's ``CollisionGeometry``) as a trimesh in the link frame."""
    import trimesh

    kind = geom.kind.name
    if kind == "mesh":
        loaded = trimesh.load(geom.mesh_path, force="mesh", process=False)
        mesh = loaded.copy()
        mesh.apply_scale(np.asarray(geom.scale, dtype=float))
    elif kind == "box":
        mesh = trimesh.creation.box(extents=np.array(geom.size, dtype=float))
    elif kind == "cylinder":
        mesh = trimesh.creation.cylinder(radius=geom.size[0], height=geom.size[1], sections=32)
    elif kind == "sphere":
        mesh = trimesh.creation.icosphere(subdivisions=2, radius=geom.size[0])
    else:  # pragma: no cover - the native side only produces the kinds above
        raise ValueError(f"unknown collision geometry kind {kind!r}")
    mesh.apply_transform(np.asarray(geom.origin, dtype=float))
    return mesh


MIN_THICKNESS = 1e-6  # m: a mesh thinner than this along its thinnest principal axis encloses no volume


def check_mesh_arrays(vertices, faces, what: str = "mesh"):
    """(V float64 (N, 3), F int32 (M, 3)) of a triangle mesh that encloses some volume, or InputError
    naming ``what``: empty, non-finite, out-of-range face indices, or degenerate (zero volume)."""

    try:
        V = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64))
        F_in = np.asarray(faces)
    except (TypeError, ValueError) as exc:
        raise InputError(f"vertices and faces must be numbers ({exc})", field=what) from exc
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise InputError(f"empty mesh or bad vertices: expected shape (N, 3) with N > 0, got {V.shape}", field=what)
    if F_in.ndim != 2 or F_in.shape[1] != 3 or len(F_in) == 0:
        raise InputError(f"empty mesh or bad faces: expected shape (M, 3) with M > 0, got {F_in.shape}", field=what)
    if not np.all(np.isfinite(V)):
        raise InputError("vertices contain NaN or infinity", field=what)
    if F_in.dtype.kind not in "iu":
        if F_in.dtype.kind != "f" or not np.all(np.isfinite(F_in)) or np.any(F_in != np.round(F_in)):
            raise InputError(f"face indices must be integers, got dtype {F_in.dtype}", field=what)
    if F_in.min() < 0 or F_in.max() >= len(V):  # checked before narrowing: 2**32 + 3 must not wrap to 3
        raise InputError(f"face index out of range [0, {len(V)}): {int(F_in.min())}..{int(F_in.max())}", field=what)
    F = np.ascontiguousarray(F_in, dtype=np.int32)
    used = V[np.unique(F)]
    centred = used - used.mean(axis=0)
    thickness = (
        np.ptp(centred @ np.linalg.svd(centred, full_matrices=False)[2].T, axis=0).min() if len(used) >= 3 else 0.0
    )
    if thickness <= MIN_THICKNESS:
        raise InputError(f"degenerate mesh: it encloses no volume (thinnest extent {thickness:.1e} m)", field=what)
    return V, F


def farthest_points(candidates: np.ndarray, k: int, existing: np.ndarray | None = None) -> np.ndarray:
    """Indices of ``k`` of ``candidates`` (N, d) picked one by one, each farthest from ``existing`` and
    those picked before it (the first: candidate 0 when nothing exists yet): an even spread."""
    candidates = np.asarray(candidates, dtype=float)
    if k <= 0 or len(candidates) == 0:
        return np.zeros(0, dtype=int)
    if existing is None or len(existing) == 0:
        d = np.full(len(candidates), np.inf)
        d[0] = np.finfo(float).max  # deterministic start
    else:
        d = np.sqrt(((candidates[:, None, :] - np.asarray(existing, float)[None]) ** 2).sum(-1)).min(axis=1)
    picked = []
    for _ in range(min(k, len(candidates))):
        i = int(np.argmax(d))
        picked.append(i)
        d = np.minimum(d, np.sqrt(((candidates - candidates[i]) ** 2).sum(-1)))
    return np.asarray(picked, dtype=int)


def symmetry_axes(mesh, samples: int = 400, seed: int = 0, tolerance: float = 0.04) -> List[np.ndarray]:
    """The unit axes (mesh frame, through its surface centroid) about which ``mesh`` is rotationally
    symmetric: the principal axes of its surface about which its surface samples, turned by 37, 83 and
    141 degrees, stay on the surface (9 in 10 nearer than ``tolerance`` x their RMS distance from the
    axis; each sample's distance to the surface compared with its own). None, one (a pen or a can
    turned about its axis is the same object in the same place) or all three: turns about two axes
    make every rotation, so a ball has no orientation to keep."""
    import trimesh

    P, _ = trimesh.sample.sample_surface(mesh, int(samples), seed=int(seed))
    P = np.asarray(P, dtype=float)
    # centre and axes from the faces, weighted by area (a symmetric face set gives them exactly; samples
    # put them a sampling error off the axis)
    w = np.asarray(mesh.area_faces, dtype=float)
    F = np.asarray(mesh.triangles_center, dtype=float)
    c = w @ F / w.sum()
    _, axes = np.linalg.eigh(((F - c) * w[:, None]).T @ (F - c))
    here = trimesh.proximity.signed_distance(mesh, P)
    found = []
    for a in axes.T:
        radial = (P - c) - np.outer((P - c) @ a, a)
        scale = float(np.sqrt((radial**2).sum(axis=1).mean()))
        if scale <= 0:
            continue
        worst = 0.0
        for deg in (37.0, 83.0, 141.0):
            R = trimesh.transformations.rotation_matrix(np.radians(deg), a, c)
            turned = P @ R[:3, :3].T + R[:3, 3]
            # against each sample's own distance: a sample inside another part (a pen's body in its cap) is
            # not on the surface, and a symmetry keeps it where it was
            worst = max(worst, float(np.percentile(np.abs(trimesh.proximity.signed_distance(mesh, turned) - here), 90)))
            if worst >= tolerance * scale:
                break
        if worst < tolerance * scale:
            found.append(a / np.linalg.norm(a))
        if len(found) == 2:  # two axes: every rotation
            return [found[0], found[1], np.cross(found[0], found[1])]
    return found
