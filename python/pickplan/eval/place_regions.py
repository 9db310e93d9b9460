"""Place regions for generated scenes: a free area of the table beside the clutter, a partly cluttered
area among the objects, or the inside of a bin (four walls on the table, ``core.containers``) beside
the clutter. Seeded: a scene and a seed give one region (and one bin).

>>> scene2, request = place_task(scene, RegionKind.bin, seed=3)   # scene2 holds the bin
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Tuple

import numpy as np
from scipy.ndimage import binary_erosion, distance_transform_edt
from scipy.spatial import ConvexHull

from pickplan.core import objects as objects_mod
from pickplan.core.containers import WALL, bin_source
from pickplan.core.settings import Option
from pickplan.omg.place import Orientation, PlaceRequest
from pickplan.sim.scenes import Scene, SceneObject

BIN_NAME = "bin"


class RegionKind(Option):
    free = "free"  # beside the clutter: nothing in it
    cluttered = "cluttered"  # among the objects: some of them in it
    bin = "bin"  # inside a bin's walls, beside the clutter


@dataclass(frozen=True)
class RegionSettings:
    size: Tuple[float, float] = (0.24, 0.20)  # m, a table region's x, y
    x_range: Tuple[float, float] = (0.40, 0.55)  # region centres' x (reachable by every shipped robot)
    side_y: Tuple[float, float] = (0.50, 0.56)  # |y| of a region beside the clutter (objects reach ~0.42)
    clutter_x: Tuple[float, float] = (0.45, 0.60)  # a partly cluttered region's centre: across the clutter's
    clutter_y: Tuple[float, float] = (0.24, 0.32)  # edge (|y|; objects stand at |y| <= 0.35), either side
    bin_inner: Tuple[float, float] = (0.26, 0.22)  # m inside the walls
    clutter_share: float = 0.25  # share of a partly cluttered region's floor objects cover
    clutter_margin: float = 0.01  # m of free floor around the target where it would fit
    clutter_batches: int = 8  # batches of 12 candidate regions drawn until the target fits
    bin_height: float = 0.08
    # m a region keeps on each side of the target turned to fit it (the set-down's clearance): a region
    # (or bin) smaller than that grows (a 28 cm hammer and a 24 cm region make no place task, only a
    # "too small" answer); every YCB and built-in object fits the default sizes
    fit_margin: float = 0.01
    height: float = 0.40  # m of the region above its floor
    orientation: Orientation = Orientation.upright


def _hulls_xy(scene: Scene) -> list:
    out = []
    for o in scene.objects:
        V = np.asarray(objects_mod.model_from_source(o.name, o.source).mesh.convex_hull.vertices)
        T = np.asarray(o.pose, float)
        out.append((o.name, (V @ T[:3, :3].T + T[:3, 3])[:, :2]))
    return out


def _fitted(scene: Scene, half: np.ndarray, margin: float) -> np.ndarray:
    """``half`` (a region's half size), grown where the target's footprint, along its principal axes
    and turned so its longer side lies along the region's longer side, would not fit with ``margin``."""
    xy = dict(_hulls_xy(scene))[scene.target]
    _, axes = np.linalg.eigh(np.cov((xy - xy.mean(axis=0)).T))
    along = xy @ axes
    need = np.sort(0.5 * (along.max(axis=0) - along.min(axis=0)))[::-1] + margin  # longer first
    order = np.argsort(-half, kind="stable")
    out = np.array(half, dtype=float)
    out[order] = np.maximum(out[order], need)
    return out


def _box_clear(scene: Scene, lo: np.ndarray, hi: np.ndarray) -> bool:
    """No object's hull reaches into the xy box [lo, hi]."""
    for _, xy in _hulls_xy(scene):
        if np.all(xy.max(axis=0) > lo) and np.all(xy.min(axis=0) < hi):
            return False
    return True


def _footprints(scene: Scene, skip: str) -> list:
    """The objects' footprints from above (but ``skip``'s) as half-planes ``A xy + b <= 0``."""
    return [ConvexHull(xy).equations for name, xy in _hulls_xy(scene) if name != skip]


def _cells(footprints: list, lo: np.ndarray, hi: np.ndarray, step: float) -> np.ndarray:
    """Which cells (about ``step`` wide) of the xy box [lo, hi] the footprints cover, by their centres."""
    n = np.maximum(np.ceil((hi - lo) / step).astype(int), 1)
    xs, ys = [lo[k] + (np.arange(n[k]) + 0.5) * (hi[k] - lo[k]) / n[k] for k in (0, 1)]
    g = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)
    covered = np.zeros(n, bool)
    for eq in footprints:
        covered |= np.all(g @ eq[:, :2].T + eq[:, 2] <= 0.0, axis=-1)
    return covered


def _cover(footprints: list, lo: np.ndarray, hi: np.ndarray, step: float = 0.01) -> float:
    """The share of the xy box [lo, hi] the footprints cover."""
    return float(_cells(footprints, lo, hi, step).mean())


def _free_disc(footprints: list, lo: np.ndarray, hi: np.ndarray, step: float = 0.01) -> float:
    """The radius of the largest disc inside the xy box [lo, hi] that the footprints leave free."""
    free = np.pad(~_cells(footprints, lo, hi, step), 1)  # the box's edge bounds a disc as an object does
    return float(distance_transform_edt(free).max() * step) - 0.5 * step


def _room(footprints: list, lo: np.ndarray, hi: np.ndarray, target_xy: np.ndarray, margin: float) -> int:
    """How well the target could stand in the box [lo, hi] among the footprints: 2, turned any way (a
    free disc of its reach from its centre, plus ``margin``: room for a hand around a round object); 1,
    turned to fit (``_fits``: a hammer, longer than any such disc the region holds); 0, not at all."""
    P = np.asarray(target_xy, float)
    reach = float(np.linalg.norm(P - 0.5 * (P.min(axis=0) + P.max(axis=0)), axis=1).max())
    if _free_disc(footprints, lo, hi) >= reach + margin:
        return 2
    return int(_fits(footprints, lo, hi, P, margin))


def _fits(
    footprints: list,
    lo: np.ndarray,
    hi: np.ndarray,
    target_xy: np.ndarray,
    margin: float,
    step: float = 0.01,
    yaws: int = 12,
) -> bool:
    """Whether the target's footprint (``target_xy``, its hull from above), grown by ``margin`` and turned by
    one of ``yaws`` headings over a half turn, stands somewhere in the box [lo, hi] clear of the
    footprints: the free cells (the box's edge bounds it as an object does) eroded by its shape."""
    free = np.pad(~_cells(footprints, lo, hi, step), 1)
    P = np.asarray(target_xy, float)
    P = P - 0.5 * (P.min(axis=0) + P.max(axis=0))
    for angle in np.pi * np.arange(yaws) / yaws:
        c, s = np.cos(angle), np.sin(angle)
        eq = ConvexHull(P @ np.array([[c, s], [-s, c]])).equations
        k = int(np.ceil((np.abs(P).max() * np.sqrt(2) + margin) / step))
        o = step * np.arange(-k, k + 1)
        g = np.stack(np.meshgrid(o, o, indexing="ij"), axis=-1)
        shape = np.all(g @ eq[:, :2].T + eq[:, 2] <= margin, axis=-1)
        if binary_erosion(free, structure=shape, border_value=0).any():
            return True
    return False


def place_task(
    scene: Scene, kind: RegionKind, seed: int, settings: RegionSettings = RegionSettings()
) -> Tuple[Scene, PlaceRequest]:
    """A scene (with a bin for ``RegionKind.bin``) and a place request of that kind, seeded."""
    kind = RegionKind.parse(kind, "region kind")
    rng = np.random.default_rng([int(seed), 34])
    half = _fitted(
        scene, np.asarray(settings.bin_inner if kind is RegionKind.bin else settings.size) / 2, settings.fit_margin
    )
    if kind is RegionKind.cluttered:  # of candidates with the most room for the target, the share nearest the aim
        footprints, target = _footprints(scene, scene.target), dict(_hulls_xy(scene))[scene.target]
        centres, cover, room = np.zeros((0, 2)), [], []
        # 12 candidates at a time until one leaves the target room turned any way: a region it cannot
        # stand in is no place task (a big target among clutter), only the best of the last resort
        for _ in range(settings.clutter_batches):
            batch = np.column_stack(
                [
                    rng.uniform(*settings.clutter_x, 12),
                    np.where(rng.uniform(size=12) < 0.5, -1.0, 1.0) * rng.uniform(*settings.clutter_y, 12),
                ]
            )
            centres = np.vstack([centres, batch])
            cover += [_cover(footprints, c - half, c + half) for c in batch]
            room += [_room(footprints, c - half, c + half, target, settings.clutter_margin) for c in batch]
            if max(room) == 2:
                break
        miss = np.abs(np.asarray(cover) - settings.clutter_share) + (2 - np.asarray(room))  # room first
        centre = centres[int(np.argmin(miss))]
    else:  # beside the clutter, on the side farther from the target, moved out until it is clear
        target_y = float(np.asarray(scene.object(scene.target).pose)[1, 3])
        sign = -1.0 if target_y > 0 else 1.0
        centre = np.array([rng.uniform(*settings.x_range), sign * rng.uniform(*settings.side_y)])
        outer = half + (WALL if kind is RegionKind.bin else 0.0)
        for _ in range(10):
            if _box_clear(scene, centre - outer - 0.01, centre + outer + 0.01):
                break
            centre[1] += sign * 0.02
    floor = float(np.asarray(scene.table.pose)[2, 3] + 0.5 * np.asarray(scene.table.size)[2])
    lo = np.array([*(centre - half), floor])
    hi = np.array([*(centre + half), floor + settings.height])
    request = PlaceRequest(tuple(lo), tuple(hi), settings.orientation)
    if kind is not RegionKind.bin:
        return scene, request
    pose = np.eye(4)
    pose[:3, 3] = [centre[0], centre[1], floor]
    wall = SceneObject(BIN_NAME, bin_source(2 * half[0], 2 * half[1], settings.bin_height), pose)
    return replace(scene, objects=list(scene.objects) + [wall]), request
