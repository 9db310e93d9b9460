"""Containers as scene objects: a bin is four walls standing on the table (no floor: the table is its
floor, the support a placed object rests on). Built from thin boxes through the object machinery
(mesh = their union, collision parts = the boxes) and named by its size, so a scene file rebuilds it:
``bin:0.220x0.180x0.100`` is a bin 22 x 18 cm inside, 10 cm high.

>>> model = pickplan.objects.model_from_source("bin", "bin:0.220x0.180x0.100")
"""

from __future__ import annotations

import re
from typing import Tuple

import trimesh

BIN_PREFIX = "bin:"
WALL = 0.01  # m thick
BIN_MASS = 5.0  # kg: heavy, so a touch does not push it


def bin_source(inner_x: float, inner_y: float, height: float) -> str:
    return f"{BIN_PREFIX}{inner_x:.3f}x{inner_y:.3f}x{height:.3f}"


def parse_bin(source: str) -> Tuple[float, float, float]:
    m = re.fullmatch(re.escape(BIN_PREFIX) + r"(\d+\.\d+)x(\d+\.\d+)x(\d+\.\d+)", source)
    if not m:
        raise ValueError(f"bin source {source!r}: expected {BIN_PREFIX}<inner x>x<inner y>x<height> in metres")
    x, y, h = (float(v) for v in m.groups())
    if not (0.02 <= x <= 2 and 0.02 <= y <= 2 and 0.01 <= h <= 1):
        raise ValueError(f"bin source {source!r}: sizes out of range (inner 0.02-2 m, height 0.01-1 m)")
    return x, y, h


def bin_parts(inner_x: float, inner_y: float, height: float) -> list:
    """The four walls (object frame: the inside centred on the origin, bottom at z = 0)."""
    ox = inner_x + 2 * WALL  # the long walls span the short ones' ends
    walls = [
        ((ox, WALL), (0.0, (inner_y + WALL) / 2)),
        ((ox, WALL), (0.0, -(inner_y + WALL) / 2)),
        ((WALL, inner_y), ((inner_x + WALL) / 2, 0.0)),
        ((WALL, inner_y), (-(inner_x + WALL) / 2, 0.0)),
    ]
    out = []
    for (sx, sy), (cx, cy) in walls:
        T = trimesh.transformations.translation_matrix((cx, cy, height / 2))
        out.append(trimesh.creation.box(extents=(sx, sy, height), transform=T))
    return out


def bin_geometry(source: str) -> Tuple[trimesh.Trimesh, list]:
    """The mesh (the walls' watertight union) and the collision parts (the walls) a bin source names."""
    parts = bin_parts(*parse_bin(source))
    return trimesh.boolean.union(parts, engine="manifold"), parts
