"""How likely an object, dropped at random, comes to rest on each of its resting poses.

The quasi-static estimate (Wiegley, Goldberg, Peshkin and Brokowski, 1996; Moll and Erdmann, 2002):
an object falling in a random orientation first touches the table with the face of its convex hull
that its centre of mass "sees" in the downward direction, so face f is hit with probability
Omega_f / (4 pi), Omega_f the solid angle f subtends at the centre of mass. A face over which the
centre of mass does not project is not a resting face: the object tips over the edge the projection
lies beyond, onto the neighbouring face, and so on until a stable face. A stable face's probability
is the total solid angle that drains into it. Exact for the model; it ignores bouncing and rolling
momentum, which is what the scene generator's settling then decides.
"""

from __future__ import annotations

from typing import List, Sequence

import numpy as np
import trimesh


def triangle_solid_angles(triangles: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """Solid angle of each triangle (N, 3, 3) seen from ``origin`` (Van Oosterom and Strackee, 1983)."""
    r = np.asarray(triangles, float) - np.asarray(origin, float)
    a, b, c = r[:, 0], r[:, 1], r[:, 2]
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    numerator = np.einsum("ij,ij->i", a, np.cross(b, c))
    denominator = (
        la * lb * lc
        + np.einsum("ij,ij->i", a, b) * lc
        + np.einsum("ij,ij->i", a, c) * lb
        + np.einsum("ij,ij->i", b, c) * la
    )
    return np.abs(2.0 * np.arctan2(numerator, denominator))


def _planar_faces(hull: trimesh.Trimesh) -> List[np.ndarray]:
    """The hull's faces grouped into planar polygons (trimesh facets plus lone triangles)."""
    grouped = np.zeros(len(hull.faces), dtype=bool)
    faces = []
    for facet in hull.facets:
        grouped[facet] = True
        faces.append(np.asarray(facet))
    faces += [np.array([i]) for i in np.flatnonzero(~grouped)]
    return faces


def _drain_targets(hull: trimesh.Trimesh, faces: List[np.ndarray], com: np.ndarray) -> np.ndarray:
    """For each planar face, the planar face the object ends on when it first lands on it."""
    owner = np.empty(len(hull.faces), dtype=int)
    for k, f in enumerate(faces):
        owner[f] = k
    normals = hull.face_normals[[f[0] for f in faces]]
    # across each hull edge, the neighbouring planar face
    neighbours = [dict() for _ in faces]
    for (t0, t1), edge in zip(hull.face_adjacency, hull.face_adjacency_edges):
        k0, k1 = owner[t0], owner[t1]
        if k0 != k1:
            key = tuple(sorted(edge))
            neighbours[k0][key] = k1
            neighbours[k1][key] = k0
    verts, tri = np.asarray(hull.vertices), np.asarray(hull.faces)
    centers = np.asarray(hull.triangles_center)  # read once: each trimesh property read checks its cache
    step = np.arange(len(faces))
    for k in range(len(faces)):
        if not neighbours[k]:
            continue
        n = normals[k]
        p = com - np.dot(com - verts[tri[faces[k][0]][0]], n) * n  # COM projected onto the plane
        edges = np.array(list(neighbours[k].keys()))
        a = verts[edges[:, 0]]
        outward = np.cross(verts[edges[:, 1]] - a, n)  # perpendicular to each edge in the face's plane
        outward[np.einsum("ij,ij->i", outward, centers[faces[k][0]] - a) > 0] *= -1.0
        d = np.einsum("ij,ij->i", p - a, outward) / np.linalg.norm(outward, axis=1)
        worst, target = 0.0, k
        for dist, other in zip(d.tolist(), neighbours[k].values()):
            if dist > worst + 1e-12:  # the projection lies beyond this edge: tip over it
                worst, target = dist, other
        step[k] = target
    final = step.copy()
    for k in range(len(faces)):  # follow the tipping chain to a face that keeps the object
        seen, j = {k}, step[k]
        while step[j] != j and j not in seen:
            seen.add(j)
            j = step[j]
        final[k] = j
    return final


def resting_probabilities(mesh: trimesh.Trimesh, com: np.ndarray, resting_poses: Sequence[np.ndarray]) -> List[float]:
    """The probability of each of ``resting_poses`` (object -> world, resting on z = 0) under the
    quasi-static model; they sum to 1 over the poses given (mass draining to a face that is not among
    them, e.g. a pose left out as too easy to tip, is shared in proportion)."""
    if len(resting_poses) == 0:
        return []
    hull = mesh.convex_hull
    com = np.asarray(com, float)
    faces = _planar_faces(hull)
    omega = triangle_solid_angles(hull.triangles, com)
    face_omega = np.array([omega[f].sum() for f in faces])
    final = _drain_targets(hull, faces, com)
    normals = hull.face_normals[[f[0] for f in faces]]
    # the face each pose rests on has its outward normal pointing down: n = R^T (0, 0, -1)
    pose_normals = np.array([np.asarray(T)[:3, :3].T @ [0.0, 0.0, -1.0] for T in resting_poses])
    mass = np.zeros(len(resting_poses))
    for k in np.unique(final):
        j = int(np.argmax(pose_normals @ normals[k]))
        if pose_normals[j] @ normals[k] > np.cos(np.radians(5.0)):
            mass[j] += face_omega[final == k].sum()
    if mass.sum() <= 0:
        return [1.0 / len(resting_poses)] * len(resting_poses)
    return (mass / mass.sum()).tolist()
