"""Procedural object families: objects nobody tuned for, generated from a seed.

Beside the built-in YCB stand-ins (``objects_builtin``), these families cover what a user puts on a
table and the paper's objects do not: thin and flat things (pens, dishes, flat boxes, scissor- and
clamp-like tools), small things (under 3 cm), things wider than a parallel gripper in some
directions (long boxes, pots, bowls held by the wall, short cans), non-convex things (handles, loops,
lids) and tools whose mass sits at one end (hammers).

Every object is a union of simple solids: its mesh is that union (watertight, by manifold3d through
trimesh) and its collision parts are the solids themselves (convex), so no decomposition is needed.
Dimensions are drawn from each family's ranges with a seed derived from the library seed, the family
and the variant index, so ``procedural:scissors_01`` is the same object in every process.

>>> from pickplan.core import objects
>>> lib = objects.library("procedural")
>>> model = lib.get("pen_00")        # an ObjectModel, like the built-ins
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Callable, Dict, List, Tuple

import numpy as np
import trimesh

PROCEDURAL_PREFIX = "procedural:"
VARIANTS = 3  # variants per family in the library
LIBRARY_SEED = 0  # the library's seed: names map to the same objects everywhere
SECTIONS = 24  # facets of round solids (enough for stable resting faces on a side)

Parts = List[trimesh.Trimesh]


@dataclass(frozen=True)
class Generated:
    """What a family builder returns: the solids (object frame, bottom at z = 0), mass and friction."""

    parts: Parts
    mass: float  # kg
    friction: float  # Coulomb coefficient against the table and the fingers
    family: str


def _box(size, at=(0.0, 0.0, 0.0), yaw: float = 0.0) -> trimesh.Trimesh:
    T = trimesh.transformations.rotation_matrix(yaw, [0, 0, 1])
    T[:3, 3] = at
    return trimesh.creation.box(extents=size, transform=T)


def _cylinder(radius: float, height: float, at=(0.0, 0.0, 0.0), axis: str = "z") -> trimesh.Trimesh:
    T = np.eye(4)
    if axis == "x":
        T[:3, :3] = trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0])[:3, :3]
    elif axis == "y":
        T[:3, :3] = trimesh.transformations.rotation_matrix(np.pi / 2, [1, 0, 0])[:3, :3]
    T[:3, 3] = at
    return trimesh.creation.cylinder(radius=radius, height=height, sections=SECTIONS, transform=T)


def _ring_segments(centre, r_in: float, r_out: float, height: float, segments: int = 8) -> Parts:
    """A flat ring (a loop handle) as ``segments`` convex blocks around ``centre`` (z up)."""
    parts = []
    mid, width = 0.5 * (r_in + r_out), r_out - r_in
    chord = 2 * r_out * np.tan(np.pi / segments) * 1.02  # overlap so the union is one solid
    for k in range(segments):
        a = 2 * np.pi * k / segments
        at = np.asarray(centre) + mid * np.array([np.cos(a), np.sin(a), 0.0])
        parts.append(_box((width, chord, height), at, yaw=a))
    return parts


# --- families: rng -> Generated ------------------------------------------------------------------------
def _pen(rng) -> Generated:
    r, length = rng.uniform(0.004, 0.0065), rng.uniform(0.12, 0.16)
    axis_z = 1.25 * r  # the cap's radius: the lowest point is at z = 0
    body = _cylinder(r, length, (0.0, 0.0, axis_z), axis="x")
    cap = _cylinder(1.25 * r, 0.05, (-length / 2 + 0.025, 0.0, axis_z), axis="x")  # a clip-cap: a wider end
    return Generated([body, cap], rng.uniform(0.01, 0.025), rng.uniform(0.4, 0.7), "pen")


def _dish(rng) -> Generated:
    """A plate with a raised rim: only the rim is thin enough to pinch."""
    R, rim, wall, base = rng.uniform(0.08, 0.11), rng.uniform(0.015, 0.025), rng.uniform(0.004, 0.006), 0.004
    parts = [_cylinder(R - wall * 0.5, base, (0.0, 0.0, base / 2))]
    parts += _ring_segments((0.0, 0.0, rim / 2), R - wall, R, rim, segments=16)
    return Generated(parts, rng.uniform(0.15, 0.35), rng.uniform(0.4, 0.8), "dish")


def _flat_box(rng) -> Generated:
    size = (rng.uniform(0.06, 0.11), rng.uniform(0.04, 0.075), rng.uniform(0.012, 0.025))
    return Generated([_box(size, (0.0, 0.0, size[2] / 2))], rng.uniform(0.05, 0.2), rng.uniform(0.4, 0.9), "flat_box")


def _scissors(rng) -> Generated:
    t, blade, spread = rng.uniform(0.006, 0.009), rng.uniform(0.08, 0.11), rng.uniform(0.08, 0.2)
    z = t / 2
    parts = []
    for side in (-1, 1):  # two blades from the pivot, slightly apart
        a = side * spread / 2
        c = 0.5 * blade * np.array([np.cos(a), np.sin(a), 0.0])
        parts.append(_box((blade, rng.uniform(0.008, 0.012), t), (c[0], c[1], z), yaw=a))
    parts.append(_cylinder(0.008, t * 1.2, (0.0, 0.0, t * 0.6)))  # the pivot
    loop_in, loop_out = rng.uniform(0.01, 0.014), rng.uniform(0.017, 0.021)
    for side in (-1, 1):  # two loop handles behind the pivot
        centre = np.array([-0.035, side * 0.022, z])
        parts += _ring_segments(centre, loop_in, loop_out, t)
        arm = 0.5 * centre[:2]
        parts.append(
            _box(
                (np.linalg.norm(centre[:2]), 0.008, t), (arm[0], arm[1], z), yaw=float(np.arctan2(centre[1], centre[0]))
            )
        )
    return Generated(parts, rng.uniform(0.05, 0.1), rng.uniform(0.3, 0.6), "scissors")


def _clamp(rng) -> Generated:
    """A C-clamp lying flat: a spine, two jaws and the screw through one jaw."""
    h, span, reach, bar = (
        rng.uniform(0.015, 0.03),
        rng.uniform(0.08, 0.14),
        rng.uniform(0.05, 0.08),
        rng.uniform(0.012, 0.018),
    )
    z = h / 2
    parts = [
        _box((bar, span, h), (0.0, 0.0, z)),
        _box((reach, bar, h), (reach / 2, span / 2 - bar / 2, z)),
        _box((reach, bar, h), (reach / 2, -span / 2 + bar / 2, z)),
        _cylinder(0.004, span * 0.45, (reach * 0.8, span / 2 - span * 0.2, min(z, 0.006)), axis="y"),
    ]
    return Generated(parts, rng.uniform(0.2, 0.5), rng.uniform(0.3, 0.6), "clamp")


def _small(rng) -> Generated:
    shape = int(rng.integers(3))
    if shape == 0:
        s = rng.uniform(0.015, 0.028)
        part = _box((s, s, s), (0.0, 0.0, s / 2))
    elif shape == 1:
        r, h = rng.uniform(0.008, 0.013), rng.uniform(0.015, 0.028)
        part = _cylinder(r, h, (0.0, 0.0, h / 2))
    else:
        r = rng.uniform(0.009, 0.014)
        part = trimesh.creation.icosphere(subdivisions=2, radius=r)
        part.apply_translation((0.0, 0.0, r))
    return Generated([part], rng.uniform(0.005, 0.03), rng.uniform(0.5, 0.9), "small")


def _long_box(rng) -> Generated:
    """Longer than the gripper opens, narrow enough across to grasp."""
    size = (rng.uniform(0.15, 0.25), rng.uniform(0.04, 0.07), rng.uniform(0.04, 0.08))
    return Generated([_box(size, (0.0, 0.0, size[2] / 2))], rng.uniform(0.15, 0.5), rng.uniform(0.4, 0.9), "long_box")


def _pot(rng) -> Generated:
    """A pot too wide to grasp around, with two loop handles that are not."""
    R, H, wall = rng.uniform(0.05, 0.07), rng.uniform(0.07, 0.11), 0.004
    parts = [_cylinder(R - wall * 0.5, 0.005, (0.0, 0.0, 0.0025))]
    parts += _ring_segments((0.0, 0.0, H / 2), R - wall, R, H, segments=16)
    for side in (-1, 1):
        c = np.array([side * (R + 0.018), 0.0, H * 0.75])
        loop = _ring_segments(c, 0.012, 0.02, 0.012, segments=8)
        parts += [p for p in loop if side * (p.centroid[0] - c[0]) > -0.012]  # the outer part of the loop
    return Generated(parts, rng.uniform(0.3, 0.8), rng.uniform(0.4, 0.8), "pot")


def _jar(rng) -> Generated:
    """A jar with a wider lid and a knob: non-convex along its axis."""
    r, h = rng.uniform(0.028, 0.036), rng.uniform(0.07, 0.12)
    lid_r, lid_h = r * rng.uniform(1.1, 1.2), rng.uniform(0.012, 0.02)
    parts = [
        _cylinder(r, h, (0.0, 0.0, h / 2)),
        _cylinder(lid_r, lid_h, (0.0, 0.0, h + lid_h / 2)),
        _cylinder(0.01, 0.015, (0.0, 0.0, h + lid_h + 0.0075)),
    ]
    return Generated(parts, rng.uniform(0.15, 0.45), rng.uniform(0.4, 0.8), "jar")


def _bowl(rng) -> Generated:
    """An open bowl wider than the gripper opens: a thin wall flaring out in steps (a ledge between
    tiers) from a foot, so only its wall or rim can be pinched, one pad inside."""
    R, wall, tiers = rng.uniform(0.045, 0.06), rng.uniform(0.004, 0.006), int(rng.integers(2, 4))
    tier_h, flare = rng.uniform(0.018, 0.025), rng.uniform(0.008, 0.014)
    parts = [_cylinder(R - wall * 0.5, 0.005, (0.0, 0.0, 0.0025))]
    for k in range(tiers):
        r = R + k * flare
        parts += _ring_segments((0.0, 0.0, (k + 0.5) * tier_h), r - wall, r, tier_h, segments=16)
        if k:  # the ledge from the tier under it out to this one
            parts += _ring_segments((0.0, 0.0, k * tier_h + wall / 2), r - flare - wall, r, wall, segments=16)
    return Generated(parts, rng.uniform(0.12, 0.4), rng.uniform(0.4, 0.8), "bowl")


def _tin(rng) -> Generated:
    """A short can (tuna, polish): wider than tall, a rolled rim at each end; lying on its side, its
    flat ends are the only pair a gripper can close on."""
    r, h, rim = rng.uniform(0.03, 0.045), rng.uniform(0.025, 0.045), rng.uniform(0.001, 0.002)
    parts = [
        _cylinder(r, h, (0.0, 0.0, h / 2)),
        _cylinder(r + rim, 0.004, (0.0, 0.0, 0.002)),
        _cylinder(r + rim, 0.004, (0.0, 0.0, h - 0.002)),
    ]
    return Generated(parts, rng.uniform(0.08, 0.25), rng.uniform(0.3, 0.6), "tin")


def _hammer(rng) -> Generated:
    """A hammer-like tool lying flat: a long handle and a bulky head at one end, so its centre of mass
    sits far from the handle's middle; heavy for its size."""
    length, width, thick = rng.uniform(0.2, 0.3), rng.uniform(0.022, 0.03), rng.uniform(0.016, 0.022)
    head = (rng.uniform(0.025, 0.035), rng.uniform(0.085, 0.11), rng.uniform(0.024, 0.03))
    parts = [
        _box((length, width, thick), (0.0, 0.0, head[2] / 2)),
        _box(head, (length / 2 - head[0] / 2, 0.0, head[2] / 2)),
    ]
    return Generated(parts, rng.uniform(0.35, 0.7), rng.uniform(0.3, 0.6), "hammer")


FAMILIES: Dict[str, Callable[[np.random.Generator], Generated]] = {
    "pen": _pen,
    "dish": _dish,
    "flat_box": _flat_box,
    "scissors": _scissors,
    "clamp": _clamp,
    "small": _small,
    "long_box": _long_box,
    "pot": _pot,
    "jar": _jar,
    "bowl": _bowl,
    "tin": _tin,
    "hammer": _hammer,
}


def names(variants: int = VARIANTS) -> List[str]:
    """The library's object names: ``<family>_<index>``."""
    return [f"{family}_{k:02d}" for family in FAMILIES for k in range(variants)]


def parse_name(name: str) -> Tuple[str, int]:
    family, _, index = name.rpartition("_")
    if family not in FAMILIES or not index.isdigit():
        raise KeyError(
            f"unknown procedural object {name!r}; expected <family>_<NN> with a family in {sorted(FAMILIES)}"
        )
    return family, int(index)


def generate(name: str, seed: int = LIBRARY_SEED) -> Tuple[trimesh.Trimesh, Parts, Generated]:
    """Mesh (the watertight union), convex collision parts and the generation record of ``name``."""
    family, index = parse_name(name)
    # crc32, not hash(): Python salts string hashes per process
    rng = np.random.default_rng([int(seed), zlib.crc32(family.encode()), index])
    gen = FAMILIES[family](rng)
    mesh = gen.parts[0].copy() if len(gen.parts) == 1 else trimesh.boolean.union(gen.parts, engine="manifold")
    if not mesh.is_watertight:
        raise RuntimeError(f"procedural object {name!r}: the union of its solids is not watertight")
    return mesh, list(gen.parts), gen
