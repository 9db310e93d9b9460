"""A user's part from a closed mesh (`pickplan metamodel build --part mesh.stl`).

The mesh (metres) rests as given on the table: its lowest point moves to z = 0 and its bounding
box is centred on the part frame's origin in x and y. The gripper grasps across the narrower of
the horizontal extents (x or y) at the top, as for the built-in parts (parts.py), approaching
along the other one. In simulation the part is the mesh's convex hull (PyBullet's dynamic meshes
are convex) with the mass and centre of mass of the closed mesh.
"""

from __future__ import annotations

import math
import os
from typing import Optional

import numpy as np

from pickplan.core.errors import InputError
from pickplan.pickup.metamodel.parts import Part, Shape, GraspStrategy, grasp_height
from pickplan.pickup.metamodel.sim import OPEN_WIDTH

MIN_EXTENT, MAX_EXTENT = 0.005, 0.5  # m: smaller or larger is not a part for this gripper (units?)
PAD_MARGIN = 0.005  # m the open fingers must clear on the grasped width


def _number(value, what: str, path: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise InputError(f"expected a positive finite number, got {value!r}", path=path, field=what)
    return v


def load_closed_mesh(path: str):
    """The mesh at ``path`` (STL, OBJ, PLY, ...); InputError unless it is one closed surface with
    positive volume and finite vertices."""
    import trimesh

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"mesh file not found: {path}")
    try:
        mesh = trimesh.load(path, force="mesh", process=True)
    except Exception as exc:  # noqa: BLE001 - trimesh raises many types for bad files
        raise InputError(f"not a readable mesh ({type(exc).__name__}: {exc})", path=path, field="mesh") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise InputError("no triangles", path=path, field="mesh")
    if not np.isfinite(mesh.vertices).all():
        raise InputError("vertices must be finite", path=path, field="mesh")
    if not mesh.is_watertight:
        raise InputError(
            "not closed: the surface has holes or open edges (a closed mesh is needed for a volume and a mass)",
            path=path,
            field="mesh",
        )
    if not mesh.volume > 0:
        raise InputError(
            f"volume {mesh.volume:.3g} m^3 is not positive (inverted normals or a degenerate surface)",
            path=path,
            field="mesh",
        )
    ext = mesh.extents
    if ext.min() < MIN_EXTENT or ext.max() > MAX_EXTENT:
        raise InputError(
            f"extents {np.round(ext, 4).tolist()} m outside [{MIN_EXTENT}, {MAX_EXTENT}] m "
            "(the mesh must be in metres)",
            path=path,
            field="mesh",
        )
    return mesh


def part_from_mesh(
    path: str,
    mass: Optional[float] = None,
    density: Optional[float] = None,
    friction: float = 0.6,
    name: Optional[str] = None,
) -> Part:
    """The Part of a closed mesh with a ``mass`` (kg) or a ``density`` (kg/m^3), not both."""
    path = os.fspath(path)
    if (mass is None) == (density is None):
        raise InputError("give exactly one of mass and density", path=path, field="--mass/--density")
    mesh = load_closed_mesh(path)
    lo, hi = mesh.bounds
    shift = np.array([-(lo[0] + hi[0]) / 2, -(lo[1] + hi[1]) / 2, -lo[2]])
    vertices = mesh.vertices + shift
    com = mesh.center_mass + shift
    kg = _number(mass, "--mass", path) if mass is not None else _number(density, "--density", path) * mesh.volume
    friction = _number(friction, "--friction", path)
    ext = mesh.extents
    across_x = ext[0] <= ext[1]  # grasp across the narrower horizontal extent
    width = float(ext[0] if across_x else ext[1])
    if width > OPEN_WIDTH - PAD_MARGIN:
        raise InputError(
            f"narrowest horizontal extent {width * 1000:.0f} mm does not fit between the open "
            f"fingers ({OPEN_WIDTH * 1000:.0f} mm)",
            path=path,
            field="mesh",
        )
    height = float(ext[2])
    hull = mesh.convex_hull.vertices + shift
    strategy = GraspStrategy((0.0, 0.0, grasp_height(height)), math.pi / 2 if across_x else 0.0, width)
    return Part(
        name=name or os.path.splitext(os.path.basename(path))[0],
        shapes=(Shape("mesh", tuple(tuple(float(c) for c in v) for v in hull), tuple(float(c) for c in com)),),
        mass=float(kg),
        height=height,
        strategy=strategy,
        lateral_friction=friction,
        description=f"mesh {os.path.basename(path)}: {ext[0] * 1000:.0f} x {ext[1] * 1000:.0f} x "
        f"{ext[2] * 1000:.0f} mm, {kg * 1000:.0f} g, grasped across {width * 1000:.0f} mm",
        footprint_radius=float(np.max(np.hypot(vertices[:, 0], vertices[:, 1]))),
    )
