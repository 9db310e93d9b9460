"""Place regions for generated scenes: a free area of the table beside the clutter, a partly cluttered
area among the objects, or the inside of a bin (four walls on the table, ``core.containers``) beside
the clutter. Seeded: a scene and a seed give one region (and one bin).

>>> scene2, request = place_task(scene, RegionKind.bin, seed=3)   # scene2 holds the bin
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional, Tuple

import numpy as np
from scipy.signal import fftconvolve
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
    clutter_margin: float = 0.01  # m from a partly cluttered region's sides the target would stand
    # m of free floor between it and the clutter on two opposite sides (any heading): the hand sets it down
    # and lets go there, its fingers beside it (the shipped hands' are 2-2.6 cm thick) opening. With 1 cm
    # all round, 5 such regions of YCB stable and dense (100 scenes each) held the target clear of the
    # clutter but no hand of any of its 100 grasp candidates
    clutter_clearance: float = 0.03
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
    return _covered(footprints, xs, ys)


def _covered(footprints: list, xs: np.ndarray, ys: np.ndarray) -> np.ndarray:
    g = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)
    covered = np.zeros((len(xs), len(ys)), bool)
    for eq in footprints:
        covered |= np.all(g @ eq[:, :2].T + eq[:, 2] < -1e-9, axis=-1)  # touching is free
    return covered


def _cover(footprints: list, lo: np.ndarray, hi: np.ndarray, step: float = 0.01) -> float:
    """The share of the xy box [lo, hi] the footprints cover."""
    return float(_cells(footprints, lo, hi, step).mean())


def _disc(radius: float, sides: int = 32) -> np.ndarray:
    a = 2 * np.pi * np.arange(sides) / sides
    return radius / np.cos(np.pi / sides) * np.column_stack([np.cos(a), np.sin(a)])  # circumscribed


def _room(
    footprints: list,
    lo: np.ndarray,
    hi: np.ndarray,
    target_xy: np.ndarray,
    margin: float,
    clearance: Optional[float] = None,
) -> int:
    """How well the target could stand in the box [lo, hi] (``margin`` from its sides) with ``clearance``
    (default ``margin``) to the footprints: 2, turned any way (a disc of its reach from its centre: a
    round object); 1, turned to fit (``_fits``: a hammer, longer than any such disc the region holds); 0,
    not at all."""
    P = np.asarray(target_xy, float)
    reach = float(np.linalg.norm(P - 0.5 * (P.min(axis=0) + P.max(axis=0)), axis=1).max())
    if _fits(footprints, lo, hi, _disc(reach), margin, clearance, yaws=1):
        return 2
    return int(_fits(footprints, lo, hi, P, margin, clearance))


def _region_room(footprints: list, lo: np.ndarray, hi: np.ndarray, target_xy: np.ndarray, s: RegionSettings) -> int:
    """A candidate region's room for the target, 0-6: ``_room`` with the hand's clearance (5-6), else with
    the margin alone (3-4), else touching the sides and the clutter (1-2: the place grid's last resort)."""
    for tier, (margin, clearance) in enumerate(
        ((s.clutter_margin, s.clutter_clearance), (s.clutter_margin, s.clutter_margin), (0.0, 0.0))
    ):
        room = _room(footprints, lo, hi, target_xy, margin, clearance)
        if room:
            return room + 2 * (2 - tier)
    return 0


def _fits(
    footprints: list,
    lo: np.ndarray,
    hi: np.ndarray,
    target_xy: np.ndarray,
    margin: float,
    clearance: Optional[float] = None,
    step: float = 0.01,
    yaws: int = 24,
    axes: int = 6,
) -> bool:
    """Whether the target's footprint (``target_xy``, its hull from above), turned by one of ``yaws``
    headings over a half turn, stands somewhere in the box [lo, hi] ``margin`` from its sides and from
    the footprints (those beyond the box too: a hand reaches past a region's side), and ``clearance``
    (default ``margin``) from them along one of ``axes`` headings: the fingers' sides. Its centre on a
    ``step`` grid: the free points eroded by its grown shape, then by the sweep along the axis."""
    clearance = margin if clearance is None else float(clearance)
    # the grid's points from the box's centre (a region grown to fit the target holds it there alone)
    # out past its sides by the grown shape's reach
    half = np.ceil((0.5 * (np.asarray(hi, float) - lo) + clearance) / step).astype(int) + 2
    xs, ys = (0.5 * (lo[k] + hi[k]) + np.arange(-half[k], half[k] + 1) * step for k in (0, 1))
    free = ~_covered(footprints, xs, ys)
    P = np.asarray(target_xy, float)
    if len(P) > 2:  # headings from its principal axes (``_fitted`` grows a region along them)
        P = P @ np.linalg.eigh(np.cov((P - P.mean(axis=0)).T))[1]
    P = P - 0.5 * (P.min(axis=0) + P.max(axis=0))
    hull = ConvexHull(P).equations  # turned with it: the normals turn, the offsets stay
    k = int(np.ceil((np.linalg.norm(P, axis=1).max() + margin) / step))
    o = step * np.arange(-k, k + 1)
    g = np.stack(np.meshgrid(o, o, indexing="ij"), axis=-1)
    sweeps = _sweeps(clearance - margin, step, axes)
    for angle in np.pi * np.arange(yaws) / yaws:
        c, s = np.cos(angle), np.sin(angle)
        R = np.array([[c, s], [-s, c]])
        turned = P @ R
        vmin, vmax = turned.min(axis=0), turned.max(axis=0)
        inside = np.outer(  # (to rounding: an exact fit fits)
            (xs + vmin[0] >= lo[0] + margin - 1e-9) & (xs + vmax[0] <= hi[0] - margin + 1e-9),
            (ys + vmin[1] >= lo[1] + margin - 1e-9) & (ys + vmax[1] <= hi[1] - margin + 1e-9),
        )
        if not inside.any():
            continue
        if free.all():
            return True
        shape = np.all(g @ (hull[:, :2] @ R).T + hull[:, 2] <= margin + 1e-9, axis=-1)
        clear = _eroded(free, shape)
        if not (clear & inside).any():
            continue
        if not sweeps:
            return True
        # then swept along the fingers' axis (any of ``axes``): erosion by a sum is one erosion after the other
        if any((_eroded(clear, sweep) & inside).any() for sweep in sweeps):
            return True
    return False


def _eroded(free: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """The points of ``free`` whose neighbourhood ``shape`` (odd-sized, centred) is all free, beyond the grid
    too (a binary erosion, by FFT: its structures are up to 60 cells wide)."""
    return fftconvolve((~free).astype(float), shape[::-1, ::-1].astype(float), mode="same") < 0.5


def _sweeps(length: float, step: float, axes: int) -> list:
    """Line structures (on ``step`` cells) ``length`` each way along each of ``axes`` headings over a half
    turn; none when ``length`` is 0."""
    m = int(np.ceil(length / step - 1e-9))
    if m <= 0:
        return []
    out = []
    for angle in np.pi * np.arange(axes) / axes:
        t = np.linspace(-m, m, 4 * m + 1)
        line = np.zeros((2 * m + 1, 2 * m + 1), bool)
        line[np.rint(m + t * np.cos(angle)).astype(int), np.rint(m + t * np.sin(angle)).astype(int)] = True
        out.append(line)
    return out


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
        # 12 candidates at a time until one with an object in it leaves the target room turned any way with
        # a hand's clearance: a region it cannot stand in is no place task (a big target among clutter), only
        # the best of the last resort (room without the hand's clearance before none)
        for _ in range(settings.clutter_batches):
            batch = np.column_stack(
                [
                    rng.uniform(*settings.clutter_x, 12),
                    np.where(rng.uniform(size=12) < 0.5, -1.0, 1.0) * rng.uniform(*settings.clutter_y, 12),
                ]
            )
            centres = np.vstack([centres, batch])
            cover += [_cover(footprints, c - half, c + half) for c in batch]
            room += [_region_room(footprints, c - half, c + half, target, settings) for c in batch]
            if any(r == 6 and c > 0 for r, c in zip(room, cover)):
                break
        # room first, among regions some object reaches into (else they are free regions)
        miss = (
            np.abs(np.asarray(cover) - settings.clutter_share) + (6 - np.asarray(room)) + 6 * (np.asarray(cover) == 0)
        )
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
