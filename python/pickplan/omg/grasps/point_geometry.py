"""The geometry grasps from points stand on: neighbourhoods, patch normals and denoised points, and the
mass and load an observed object's points stand for (its hull down to the support plane)."""

from __future__ import annotations

import numpy as np
from scipy.spatial import ConvexHull, QhullError

from pickplan import _core
from pickplan.omg.grasps.quality import Load
from pickplan.omg.grasps.sets import _perpendicular


def _neighbourhoods(P, radius: float):
    """The points within ``radius`` of each point of ``P``, flattened: owner indices k, neighbour indices j
    (ascending per owner, as a k-d tree's sorted ball query; natively, ``_core.radius_pairs``)."""
    return _core.radius_pairs(P, np.arange(len(P)), radius)


def _means(k, j, X, n: int) -> np.ndarray:
    """Per owner 0..n-1 of the pairs (k, j): the mean of the rows ``X[j]``."""
    total = np.stack([np.bincount(k, X[j, a], minlength=n) for a in range(X.shape[1])], axis=1)
    return total / np.bincount(k, minlength=n)[:, None]


def _unit_means(k, j, N, n: int):
    """The unit mean of the normals ``N`` per owner, and how coherent they are (the mean's length)."""
    mean = _means(k, j, N, n)
    length = np.linalg.norm(mean, axis=1)
    return mean / np.maximum(length, 1e-12)[:, None], length


def patch_normals(P, N, radius: float):
    """Per point: the mean of the normals within ``radius`` (a pad's contact patch), unit, and how
    coherent they are (the mean's length: 1 on a flat patch, about 0.7 across a box's edge)."""
    return _unit_means(*_neighbourhoods(P, radius), N, len(P))


def denoised(P, N, radius: float) -> np.ndarray:
    """The points moved along their patch's normal onto the patch's mean plane (the centroid and mean
    normal within ``radius``): depth noise, mostly along the surface normal, averaged over the patch
    (about 20 points a patch: noise cut about 4x), where the extents and the open-hand check read it.
    On a curved patch the move is the patch's sag, under a millimetre for radius 8 mm on a 3 cm radius."""
    k, j = _neighbourhoods(P, radius)
    n, _ = _unit_means(k, j, N, len(P))
    centre = _means(k, j, P, len(P))
    return P - np.einsum("ij,ij->i", P - centre, n)[:, None] * n


def fitted_normals(P, N, radius: float, near=None) -> np.ndarray:
    """Per point: the normal of the plane fitted to the points within ``radius`` (the covariance's
    least eigenvector), turned to the side of ``N``. Normals from neighbouring pixels carry the depth
    noise divided by a pixel's spacing (tens of degrees at 2 mm); a fit over a few dozen points does
    not, so patches of a noisy flat face stay coherent. The side is the mean of ``N`` over the same
    points. Points with fewer than 8 neighbours keep ``N``. ``near``: ``_neighbourhoods(P, ., radius)``
    if already known."""
    k, j = _neighbourhoods(P, radius) if near is None else near
    count = np.bincount(k, minlength=len(P))
    D = P[j] - _means(k, j, P, len(P))[k]
    C = np.stack(
        [np.bincount(k, D[:, a] * D[:, b], minlength=len(P)) for a in range(3) for b in range(3)], axis=1
    ).reshape(-1, 3, 3)
    normal = np.linalg.eigh(C)[1][:, :, 0]  # eigenvalues ascending: the least one's vector
    side = _means(k, j, N, len(P))  # one noisy normal may be sideways; their mean is not
    normal *= np.where(np.einsum("ij,ij->i", normal, side) < 0, -1.0, 1.0)[:, None]
    return np.where((count >= 8)[:, None], normal, N)  # a fit needs a few points more than a plane


def mass_centre(P: np.ndarray, plane) -> np.ndarray:
    """Where the target's centre of mass is taken to be, from its observed points: over the middle of
    their footprint's bounding box (in the plane's frame; the hidden side widens it less than the
    mean of the points is biased towards the cameras), at half the top's height."""
    n, d = plane
    height = P @ n - d
    e1 = _perpendicular(n)
    E = np.column_stack([e1, np.cross(n, e1)])
    flat = P @ E
    return E @ (0.5 * (flat.min(axis=0) + flat.max(axis=0))) + (d + 0.5 * height.max()) * n


def points_load(P: np.ndarray, plane, density: float) -> Load:
    """The load (``quality.Load``, world frame) of a target known only by its observed points: its
    centre of mass where ``mass_centre`` puts it, its mass ``density`` times the volume of the points'
    hull down to the support plane (the hidden side below what is seen is taken as solid)."""
    n, d = plane
    height = P @ n - d
    base = P - np.outer(height, n)
    try:
        volume = float(ConvexHull(np.vstack([P, base])).volume)
    except (QhullError, ValueError):  # flat or too few points: a sliver
        volume = 0.0
    return Load(density * volume, mass_centre(P, plane), -np.asarray(n, float))


def gravity_lever(G: np.ndarray, P: np.ndarray, plane) -> np.ndarray:
    """Per grasp frame: the lever arm (m) of gravity at the estimated centre of mass about the closing
    axis through the pads' centre. Lifted, the target turns about that axis unless the pads' friction
    holds the torque: a pinch on a bottle's cap beside its body drops where one through the body holds."""
    c = mass_centre(P, plane)
    arm = np.cross(c - G[:, :3, 3], plane[0])
    return np.abs(np.einsum("ij,ij->i", arm, G[:, :3, 1]))


def first_per_voxel(P: np.ndarray, cell: float) -> np.ndarray:
    """Indices, ascending, of the first point of ``P`` in each ``cell``-sized voxel (every index when
    ``P`` is empty or ``cell`` <= 0)."""
    if len(P) == 0 or cell <= 0:
        return np.arange(len(P))
    V = np.floor(P / cell).astype(np.int64)
    V -= V.min(axis=0)
    span = V.max(axis=0) + 1
    # one integer per voxel (row-major over the points' box): a 1-D unique, not a row-wise one
    _, first = np.unique((V[:, 0] * span[1] + V[:, 1]) * span[2] + V[:, 2], return_index=True)
    return np.sort(first)


def thinned(P: np.ndarray, cell: float) -> np.ndarray:
    """One point per ``cell``-sized voxel (the first), order kept: overlapping views' points once."""
    return P[first_per_voxel(P, cell)]


def turned_frames(axis: np.ndarray, centre: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """(M, A, 4, 4) grasp frames closing along each unit ``axis`` (M, 3), the pads' centre at ``centre``
    (M, 3), the approach turned by ``theta`` (M, A) rad about the axis from a perpendicular (as
    ``sets._perpendicular`` picks it, for all axes at once)."""
    ref = np.where((np.abs(axis[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    z0 = np.cross(axis, ref)
    z0 /= np.linalg.norm(z0, axis=1, keepdims=True)
    z1 = np.cross(axis, z0)
    z = np.cos(theta)[..., None] * z0[:, None] + np.sin(theta)[..., None] * z1[:, None]  # (M, A, 3)
    y = np.broadcast_to(axis[:, None], z.shape)
    F = np.zeros(z.shape[:2] + (4, 4))
    F[..., :3, 0], F[..., :3, 1], F[..., :3, 2] = np.cross(y, z), y, z
    F[..., :3, 3], F[..., 3, 3] = centre[:, None], 1.0
    return F
