"""Procedural stand-ins for the ten YCB objects of the OMG paper (no data folder needed).

Each builder returns ``(mesh, collision_parts)`` in the object frame (metres, z up, the bottom at
z = 0, the axis of revolution on z). Meshes are watertight; collision parts are convex and built
analytically (frustums per profile segment, wedges per angular sector), not by a decomposition.
Dimensions are the extents of the real YCB scans (``../shared/data/ycb``) rounded to millimetres;
masses are the YCB paper's (Calli et al., 2015).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Dict, List, Tuple

import numpy as np
import trimesh

SECTIONS = 48  # facets around the axis: volume error of the inscribed polygon is 0.3 %


@dataclass(frozen=True)
class BuiltinSpec:
    """What the built-in stands for: outer extents (x, y, z) in metres and the YCB mass in kg."""

    extents: Tuple[float, float, float]
    mass: float
    kind: str  # "can", "box", "bottle", "bowl", "mug"


# Outer extents of the procedural shapes (the mug's x extent includes its handle).
BUILTIN_SPECS: Dict[str, BuiltinSpec] = {
    "002_master_chef_can": BuiltinSpec((0.102, 0.102, 0.140), 0.414, "can"),
    "003_cracker_box": BuiltinSpec((0.071, 0.164, 0.213), 0.411, "box"),
    "004_sugar_box": BuiltinSpec((0.049, 0.094, 0.176), 0.514, "box"),
    "005_tomato_soup_can": BuiltinSpec((0.068, 0.068, 0.102), 0.349, "can"),
    "006_mustard_bottle": BuiltinSpec((0.097, 0.067, 0.191), 0.603, "bottle"),
    "010_potted_meat_can": BuiltinSpec((0.102, 0.060, 0.084), 0.370, "box"),
    "019_pitcher_base": BuiltinSpec((0.145, 0.145, 0.243), 0.178, "can"),
    "021_bleach_cleanser": BuiltinSpec((0.102, 0.068, 0.251), 1.131, "bottle"),
    "024_bowl": BuiltinSpec((0.161, 0.161, 0.055), 0.147, "bowl"),
    "025_mug": BuiltinSpec((0.117, 0.093, 0.081), 0.118, "mug"),
}

Parts = List[trimesh.Trimesh]


def _revolve(profile, scale_xy=(1.0, 1.0)) -> trimesh.Trimesh:
    """Revolve an (r, z) polyline that starts and ends on the axis (so the result is closed)."""
    mesh = trimesh.creation.revolve(np.asarray(profile, dtype=float), sections=SECTIONS)
    mesh.merge_vertices()
    if scale_xy != (1.0, 1.0):
        mesh.apply_transform(np.diag([scale_xy[0], scale_xy[1], 1.0, 1.0]))
    return mesh


def _ring(r: float, z: float, theta: np.ndarray, scale_xy=(1.0, 1.0)) -> np.ndarray:
    return np.column_stack([r * np.cos(theta) * scale_xy[0], r * np.sin(theta) * scale_xy[1], np.full(len(theta), z)])


def _frustum_parts(side, scale_xy=(1.0, 1.0)) -> Parts:
    """One convex frustum per segment of the side of a solid of revolution (z increasing)."""
    theta = np.linspace(0.0, 2 * np.pi, SECTIONS, endpoint=False)
    parts = []
    for (r0, z0), (r1, z1) in zip(side[:-1], side[1:]):
        if z1 - z0 < 1e-9:
            continue
        pts = np.vstack([_ring(max(r0, 1e-4), z0, theta, scale_xy), _ring(max(r1, 1e-4), z1, theta, scale_xy)])
        parts.append(trimesh.convex.convex_hull(pts))
    return parts


def _shell_wedges(outer, inner, sectors: int, groups: List[Tuple[int, int]]) -> Parts:
    """Convex wedges of a revolved shell: angular sectors x groups of profile segments.

    ``outer[i]`` and ``inner[i]`` are paired (r, z) points across the wall; a group (i, j) makes one
    wedge from the points i..j, so only the wall between them is covered.
    """
    theta = np.linspace(0.0, 2 * np.pi, sectors + 1)
    parts = []
    for k in range(sectors):
        sub = np.linspace(theta[k], theta[k + 1], 3)  # a middle ray keeps the wedge on the curved wall
        for i, j in groups:
            pts = [_ring(max(r, 1e-4), z, sub) for r, z in list(outer[i : j + 1]) + list(inner[i : j + 1])]
            parts.append(trimesh.convex.convex_hull(np.vstack(pts)))
    return parts


def _can(spec: BuiltinSpec) -> Tuple[trimesh.Trimesh, Parts]:
    """A can (or the pitcher body): a cylinder with chamfered rims, solid, one or more frustums."""
    r, h = spec.extents[0] / 2, spec.extents[2]
    c = min(0.004, 0.05 * h)  # rim chamfer: cans stand on a ring, not a sharp edge
    if spec.extents[2] > 0.2:  # the pitcher: wider belly, narrower top
        side = [(0.80 * r, 0.0), (r, 0.35 * h), (0.92 * r, 0.8 * h), (0.85 * r, h)]
    else:
        side = [(r - c, 0.0), (r, c), (r, h - c), (r - c, h)]
    mesh = _revolve([(0.0, 0.0)] + side + [(0.0, h)])
    return mesh, _frustum_parts(side)


def _bottle(spec: BuiltinSpec) -> Tuple[trimesh.Trimesh, Parts]:
    """A bottle with an oval body: a revolved unit-radius profile scaled to the x/y extents."""
    ax, ay, h = spec.extents[0] / 2, spec.extents[1] / 2, spec.extents[2]
    if spec.mass > 1.0:  # bleach: tall body, short shoulder, cap
        rz = [(0.92, 0.0), (1.0, 0.02), (1.0, 0.74), (0.55, 0.84), (0.33, 0.86), (0.33, 0.96), (0.28, 1.0)]
    else:  # mustard: body, shoulder, cap, nozzle
        rz = [(0.9, 0.0), (1.0, 0.03), (1.0, 0.68), (0.45, 0.80), (0.45, 0.90), (0.12, 0.93), (0.08, 1.0)]
    side = [(r, z * h) for r, z in rz]
    mesh = _revolve([(0.0, 0.0)] + side + [(0.0, h)], scale_xy=(ax, ay))
    return mesh, _frustum_parts(side, scale_xy=(ax, ay))


def _box(spec: BuiltinSpec) -> Tuple[trimesh.Trimesh, Parts]:
    ex = np.asarray(spec.extents, dtype=float)
    mesh = trimesh.creation.box(extents=ex)
    mesh.apply_translation([0.0, 0.0, ex[2] / 2])
    return mesh, [mesh.copy()]


def _bowl(spec: BuiltinSpec) -> Tuple[trimesh.Trimesh, Parts]:
    """A bowl: a revolved shell 3 mm thick, flat foot, walls rising as a quarter ellipse to the rim."""
    R, H, t = spec.extents[0] / 2, spec.extents[2], 0.003
    foot = 0.45 * R
    s = np.linspace(0.0, np.pi / 2, 9)
    outer = [(0.0, 0.0)] + [(foot + (R - foot) * np.sin(a), H * (1 - np.cos(a))) for a in s]
    outer = np.array(outer)
    # inner wall: the outer one offset by t along its inward normal (pointing up and in)
    tang = np.gradient(outer, axis=0)
    normal = np.column_stack([-tang[:, 1], tang[:, 0]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    inner = outer + t * normal
    inner[0] = (0.0, t)
    inner[-1] = (R - t, H)  # flat rim of width t at the top
    profile = list(map(tuple, outer)) + list(map(tuple, inner[::-1]))
    mesh = _revolve(profile)
    groups = [(0, 1), (1, 4), (4, 7), (7, 9)]
    return mesh, _shell_wedges(outer, inner, sectors=12, groups=groups)


def _handle_tube(x0: float, z0: float, a: float, b: float, tube: float, n_arc: int = 16, n_ring: int = 12):
    """A half-elliptical tube in the xz plane (arc from -90 to 90 degrees), capped at both ends."""
    t = np.linspace(-np.pi / 2, np.pi / 2, n_arc + 1)
    centres = np.column_stack([x0 + a * np.cos(t), np.zeros_like(t), z0 + b * np.sin(t)])
    tangents = np.column_stack([-a * np.sin(t), np.zeros_like(t), b * np.cos(t)])
    tangents /= np.linalg.norm(tangents, axis=1, keepdims=True)
    side = np.array([0.0, 1.0, 0.0])
    phi = np.linspace(0.0, 2 * np.pi, n_ring, endpoint=False)
    rings = []
    for c, tg in zip(centres, tangents):
        nrm = np.cross(side, tg)
        rings.append(c + tube * (np.outer(np.cos(phi), nrm) + np.outer(np.sin(phi), side)))
    verts = np.vstack(rings + [centres[:1], centres[-1:]])
    faces = []
    for i in range(n_arc):
        for j in range(n_ring):
            a0, a1 = i * n_ring + j, i * n_ring + (j + 1) % n_ring
            b0, b1 = a0 + n_ring, a1 + n_ring
            faces += [(a0, b0, b1), (a0, b1, a1)]
    first, last = len(verts) - 2, len(verts) - 1
    for j in range(n_ring):
        faces.append((first, j, (j + 1) % n_ring))  # opposite to the side faces' shared edges
        faces.append((last, n_arc * n_ring + (j + 1) % n_ring, n_arc * n_ring + j))
    mesh = trimesh.Trimesh(verts, np.array(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh, rings


def _mug(spec: BuiltinSpec) -> Tuple[trimesh.Trimesh, Parts]:
    """A mug: a revolved cup (4 mm wall, 6 mm bottom) plus a tube handle on +x.

    A true boolean union needs a mesh-boolean engine pickplan does not depend on, so ``mesh`` is the
    concatenation of the two watertight parts; the handle's end caps sit inside the cup wall (2 mm
    deep), so the surface seen from outside is right, winding-number inside tests are right, and the
    doubly counted overlap is about 0.2 % of the volume.
    """
    R, H = spec.extents[1] / 2, spec.extents[2]
    wall, bottom, tube = 0.004, 0.006, 0.006
    cup_profile = [(0.0, 0.0), (R - 0.002, 0.0), (R, 0.002), (R, H), (R - wall, H), (R - wall, bottom), (0.0, bottom)]
    cup = _revolve(cup_profile)
    reach = spec.extents[0] - 2 * R  # how far the handle sticks out beyond the wall
    x0 = R - 0.002
    a = R + reach - tube - x0
    handle, rings = _handle_tube(x0, 0.52 * H, a, 0.30 * H, tube)
    mesh = trimesh.util.concatenate([cup, handle])
    outer = np.array([(0.0, 0.0), (R, 0.0), (R, H)])
    inner = np.array([(0.0, bottom), (R - wall, bottom), (R - wall, H)])
    parts = _shell_wedges(outer, inner, sectors=16, groups=[(1, 2)])
    parts.append(
        trimesh.convex.convex_hull(
            np.vstack(
                [
                    _ring(R, 0.0, np.linspace(0, 2 * np.pi, SECTIONS)),
                    _ring(R, bottom, np.linspace(0, 2 * np.pi, SECTIONS)),
                ]
            )
        )
    )
    for i in range(0, len(rings) - 1, 4):  # the handle in 4 convex tube segments
        parts.append(trimesh.convex.convex_hull(np.vstack(rings[i : i + 5])))
    return mesh, parts


_BUILDERS: Dict[str, Callable[[BuiltinSpec], Tuple[trimesh.Trimesh, Parts]]] = {
    "can": _can,
    "box": _box,
    "bottle": _bottle,
    "bowl": _bowl,
    "mug": _mug,
}


def build(name: str) -> Tuple[trimesh.Trimesh, Parts, BuiltinSpec]:
    """Mesh, convex collision parts and spec of the built-in object ``name``."""
    if name not in BUILTIN_SPECS:
        raise KeyError(f"unknown built-in object {name!r}; expected one of {sorted(BUILTIN_SPECS)}")
    spec = BUILTIN_SPECS[name]
    mesh, parts = _BUILDERS[spec.kind](spec)
    return mesh, parts, spec
