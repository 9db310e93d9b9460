"""Signed distance fields: one grid per object mesh (native, cached on disk by mesh content) and
a scene of posed grids plus the table box, queried in batches by CHOMP and the metrics."""

from __future__ import annotations

import hashlib
import os
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Iterable, Optional, Sequence, Tuple

import numpy as np

from pickplan import _core
from pickplan.core.caches import BoundedCache, mesh_content_key
from pickplan.core.errors import InputError
from pickplan.core.io import atomic_open, cache_dir
from pickplan.core.meshes import check_mesh_arrays
from pickplan.core.runner import progress_bar

SDF_FORMAT_VERSION = 2  # 2: entries carry a checksum and the writer's code and format versions


def _code_version() -> str:
    try:
        from importlib.metadata import version

        return version("pickplan")
    except Exception:  # running from a source tree without installed metadata
        return "source"


@dataclass(frozen=True)
class SdfSettings:
    resolution: float = 0.005  # voxel edge (m), the paper-scale default
    margin: float = 0.2  # grid extends beyond the mesh by at least the CHOMP padding epsilon
    cache_dir: Optional[str] = None  # None: $PICKPLAN_CACHE_DIR or ~/.cache/pickplan; "": no cache
    merged: bool = True  # resample the scene (less the target) into one grid for the planners
    merged_resolution: float = 0.01  # resampling the 5 mm grids: < 1 mm off outside thin walls, 5x faster to build
    merged_cutoff: float = 0.2  # >= the CHOMP padding, or the planners fall back to per-object grids


def _mesh_arrays(mesh) -> Tuple[np.ndarray, np.ndarray]:
    return check_mesh_arrays(mesh.vertices, mesh.faces, "mesh")


MAX_GRID_CELLS = 30_000_000  # 240 MB of distances; a 30 cm object at 5 mm with a 20 cm margin is 2.7 million


def _check_grid_size(V: np.ndarray, settings: SdfSettings) -> None:
    """InputError before building a grid that would not fit: a mesh 43 km across (one corrupt vertex)
    otherwise keeps the native builder busy for minutes or exhausts memory."""
    if not (
        np.isfinite(settings.resolution)
        and settings.resolution > 0
        and np.isfinite(settings.margin)
        and settings.margin >= 0
    ):
        raise InputError(f"SDF resolution must be > 0 and margin >= 0, got {settings.resolution}, {settings.margin}")
    cells = np.prod(np.ceil((np.ptp(V, axis=0) + 2 * settings.margin) / settings.resolution) + 1)
    if cells > MAX_GRID_CELLS:
        raise InputError(
            f"mesh is {np.round(np.ptp(V, axis=0), 3).tolist()} m across: its SDF grid at "
            f"{settings.resolution} m would have {cells:.2g} cells (at most {MAX_GRID_CELLS:.0e})",
            field="mesh",
        )


def _checksum(origin, resolution, values) -> str:
    h = hashlib.sha256()
    for a in (origin, resolution, values):
        a = np.ascontiguousarray(a, dtype=np.float64)
        h.update(str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _read_cache(path: str):
    """The grid stored at ``path``, or None (with a warning) when the entry is unreadable, written by
    another code or format version, fails its checksum or holds NaN or infinity: never used then."""
    try:
        with np.load(path, allow_pickle=False) as z:
            origin, resolution, values = z["origin"], z["resolution"], z["values"]
            written = (int(z["format_version"]), str(z["code_version"]), str(z["checksum"]))
    except Exception as exc:  # noqa: BLE001 - any damage to a cache file means: rebuild it
        warnings.warn(f"rebuilding SDF cache entry {path}: unreadable ({type(exc).__name__}: {exc})", stacklevel=3)
        return None
    problem = None
    if written[:2] != (SDF_FORMAT_VERSION, _code_version()):
        problem = f"written by format {written[0]} / pickplan {written[1]}"
    elif written[2] != _checksum(origin, resolution, values):
        problem = "checksum mismatch (corrupt)"
    elif not (
        np.all(np.isfinite(values))
        and np.all(np.isfinite(origin))
        and np.isfinite(resolution)
        and float(resolution) > 0
    ):
        problem = "NaN, infinite or non-positive values"
    if problem:
        warnings.warn(f"rebuilding SDF cache entry {path}: {problem}", stacklevel=3)
        return None
    try:
        return _core.SdfGrid.from_values(origin, float(resolution), values)
    except ValueError as exc:
        warnings.warn(f"rebuilding SDF cache entry {path}: {exc}", stacklevel=3)
        return None


def _write_cache(path: str, grid) -> None:
    origin, resolution, values = np.asarray(grid.origin), float(grid.resolution), np.asarray(grid.values)
    with atomic_open(path, "wb") as f:
        np.savez(
            f,
            origin=origin,
            resolution=resolution,
            values=values,
            format_version=SDF_FORMAT_VERSION,
            code_version=_code_version(),
            checksum=_checksum(origin, resolution, values),
        )


def mesh_key(vertices: np.ndarray, faces: np.ndarray, settings: SdfSettings) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    h.update(f"{settings.resolution:.9g}/{settings.margin:.9g}/v{SDF_FORMAT_VERSION}".encode())
    return h.hexdigest()[:32]


class GridCache(BoundedCache):
    """SDF grids by mesh content and grid settings, kept in memory: a scene of known objects reads
    no file and hashes no grid. Grids are immutable, so scenes share them."""

    def grid(self, mesh, settings: SdfSettings) -> "_core.SdfGrid":
        key = (mesh_content_key(mesh), float(settings.resolution), float(settings.margin))
        return self.get(key, lambda: mesh_sdf(mesh, settings))


def mesh_sdf(mesh, settings: SdfSettings = SdfSettings(), cache: Optional[GridCache] = None) -> "_core.SdfGrid":
    """The SDF grid of a trimesh (mesh frame): from ``cache`` when given and it holds it, else
    loaded from the disk cache when built before, else built."""
    if cache is not None:
        return cache.grid(mesh, settings)
    V, F = _mesh_arrays(mesh)
    if not getattr(mesh, "is_watertight", True):
        warnings.warn("SDF of a mesh that is not watertight: inside/outside comes from a 3-axis ray vote", stacklevel=2)
    cache = cache_dir() if settings.cache_dir is None else settings.cache_dir
    path = os.path.join(cache, "sdf", mesh_key(V, F, settings) + ".npz") if cache else None
    if path and os.path.isfile(path):
        cached = _read_cache(path)
        if cached is not None:
            return cached
    _check_grid_size(V, settings)
    grid, _report = _core.SdfGrid.build(V, F, settings.resolution, settings.margin)
    if path:
        _write_cache(path, grid)
    return grid


def mesh_sdfs(
    meshes: Sequence,
    settings: SdfSettings,
    cache: Optional[GridCache] = None,
    progress: Optional[bool] = None,
    threads: Optional[int] = None,
) -> list:
    """``mesh_sdf`` of each mesh (through ``cache`` when given), the grids not in memory built side by side on
    ``threads`` threads (default: one per core; the native build releases the GIL). On first use (no
    grid on disk yet) a bar with the time left appears after 2 s (``progress`` as ``runner.progress_bar``)."""
    keys = [mesh_content_key(m) for m in meshes]  # here, not on the threads: trimesh fills its hash cache
    first = {}
    for i, k in enumerate(keys):
        first.setdefault(k, meshes[i])
    threads = min(len(first), threads or os.cpu_count() or 1)
    if threads <= 1:
        grids = {k: mesh_sdf(m, settings, cache) for k, m in first.items()}
        return [grids[k] for k in keys]
    with progress_bar(len(first), "SDF grids", progress, unit="grid", delay=2.0) as bar:

        def build(mesh):
            grid = mesh_sdf(mesh, settings, cache)
            bar.update(1)
            return grid

        with ThreadPoolExecutor(threads) as pool:
            grids = dict(zip(first, pool.map(build, first.values())))
    return [grids[k] for k in keys]


class SceneSdf:
    """Named, posed object grids plus an optional table box; batched distance queries.

    ``distance(points, cutoff, exclude=("name", ...))`` returns (d (N,), grad (N, 3)); bodies
    farther than ``cutoff`` are skipped, so use the CHOMP padding as cutoff in cost evaluation.
    """

    def __init__(
        self,
        objects: Iterable[Tuple[str, "_core.SdfGrid", np.ndarray]] = (),
        table: Optional[Tuple[Sequence[float], np.ndarray]] = None,
    ):
        self._native = _core.SceneSdf()
        self._names: list = []
        for name, grid, pose in objects:
            self.add_object(name, grid, pose)
        if table is not None:
            self._native.set_table(np.asarray(table[0], dtype=float), np.asarray(table[1], dtype=float))

    def add_object(self, name: str, grid: "_core.SdfGrid", pose: np.ndarray) -> int:
        if name in self._names:
            raise ValueError(f"object name {name!r} is already in the scene SDF")
        index = self._native.add_object(grid, np.asarray(pose, dtype=float))
        self._names.append(name)
        return index

    def add_primitive(self, name: str, shape, pose: np.ndarray) -> int:
        """A solid primitive (a ``shapes.Shape`` or ``_core.Primitive``) at ``pose``, queried in closed form."""
        if name in self._names:
            raise ValueError(f"object name {name!r} is already in the scene SDF")
        native = shape if isinstance(shape, _core.Primitive) else shape.native()
        index = self._native.add_primitive(native, np.asarray(pose, dtype=float))
        self._names.append(name)
        return index

    def set_pose(self, name: str, pose: np.ndarray) -> None:
        """Move object ``name`` to ``pose``. A moved object is left out of the merged grids from then on
        and queried on its own grid beside them (moving it again costs nothing)."""
        self._native.set_pose(self.index(name), np.asarray(pose, dtype=float))

    @property
    def native(self) -> "_core.SceneSdf":
        return self._native

    @property
    def names(self) -> list:
        return list(self._names)

    def index(self, name: str) -> int:
        try:
            return self._names.index(name)
        except ValueError:
            raise ValueError(f"unknown object {name!r}; objects are: {', '.join(self._names)}") from None

    def merge(self, exclude: Sequence[str] = (), resolution: float = 0.01, cutoff: float = 0.2, brick: int = 4) -> None:
        """Resample every object but ``exclude`` into one world-frame grid clamped at ``cutoff``:
        queries with the same exclusion and a cutoff no larger take a single lookup. A scene keeps one
        merged grid per exclusion (at most 4; merging an exclusion again replaces its grid);
        ``merged_info`` describes the first."""
        self._native.merge([self.index(n) for n in exclude], float(resolution), float(cutoff), int(brick))

    @property
    def merged_excludes(self) -> list:
        """The object names each merged grid leaves out, one tuple per grid, in the order merged."""
        return [tuple(n for i, n in enumerate(self._names) if mask >> i & 1) for mask in self._native.merged_masks]

    @property
    def merged_info(self) -> Optional["_core.MergedSdfInfo"]:
        return self._native.merged_info

    def lower_bound(self, points, exclude: Sequence[str] = (), exclude_table: bool = False) -> np.ndarray:
        return self._native.lower_bound(points, [self.index(n) for n in exclude], exclude_table)

    def distance(
        self,
        points,
        cutoff: float = np.inf,
        exclude: Sequence[str] = (),
        exclude_table: bool = False,
        reference: bool = False,
    ) -> Tuple[np.ndarray, np.ndarray]:
        """``reference``: by the per-object grids, as the success test measures (a merged grid's
        resampling differs by a fraction of a millimetre: a decision the test will judge takes these)."""
        return self._native.distance(points, cutoff, [self.index(n) for n in exclude], exclude_table, reference)

    def clear_in_frames(
        self,
        frames,
        points,
        threshold: float,
        cutoff: float = np.inf,
        exclude: Sequence[str] = (),
        exclude_table: bool = False,
        inverse: bool = False,
        reach: float = np.inf,
    ) -> np.ndarray:
        """(K,) bool per pose of ``frames`` (K, 4, 4): every one of ``points`` (N, 3) farther than
        ``threshold`` from the bodies (``distance`` with ``cutoff``). The points are in the frame and
        go to the world; ``inverse``: they are world points taken into the frame (the field in the
        frame's coordinates, as a hand's), only those within ``reach`` of its origin read. Natively, a
        pose's test stopping at its first point too close."""
        return self._native.clear_in_frames(
            np.asarray(frames, float),
            np.asarray(points, float),
            bool(inverse),
            float(reach),
            float(threshold),
            float(cutoff),
            [self.index(n) for n in exclude],
            bool(exclude_table),
        )


@dataclass(frozen=True)
class SdfQuery:
    """A scene's distance with fixed options, as a function of (M, 3) points; ``clear_in_frames`` asks
    it of sample points in many poses at once (``SceneSdf.clear_in_frames``)."""

    sdf: SceneSdf
    cutoff: float = np.inf
    exclude: Tuple[str, ...] = ()
    exclude_table: bool = False

    def __call__(self, points: np.ndarray) -> np.ndarray:
        return self.sdf.distance(points, cutoff=self.cutoff, exclude=self.exclude, exclude_table=self.exclude_table)[0]

    def clear_in_frames(self, frames: np.ndarray, points: np.ndarray, threshold: float) -> np.ndarray:
        """(K,) bool per pose: ``points`` (frame coordinates) taken to the world all farther than ``threshold``."""
        return self.sdf.clear_in_frames(frames, points, threshold, self.cutoff, self.exclude, self.exclude_table)
