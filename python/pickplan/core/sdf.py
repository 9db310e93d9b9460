"""Signed distance fields: one grid per object mesh (native, cached on disk by mesh content) and
a scene of posed grids plus the table box, queried in batches by CHOMP and the metrics."""
from __future__ import annotations

import hashlib
import os
import warnings
from dataclasses import dataclass
from typing import Iterable, Optional, Sequence, Tuple

import numpy as np

from pickplan import _core
from pickplan.core.io import atomic_open

SDF_FORMAT_VERSION = 1


@dataclass(frozen=True)
class SdfSettings:
    resolution: float = 0.005   # voxel edge (m), the paper-scale default
    margin: float = 0.2         # grid extends beyond the mesh by at least the CHOMP padding epsilon
    cache_dir: Optional[str] = None  # None: $PICKPLAN_CACHE_DIR or ~/.cache/pickplan; "": no cache
    merged: bool = True         # resample the scene (less the target) into one grid for the planners
    merged_resolution: float = 0.01  # resampling the 5 mm grids: < 1 mm off outside thin walls, 5x faster to build
    merged_cutoff: float = 0.2  # >= the CHOMP padding, or the planners fall back to per-object grids


def default_cache_dir() -> str:
    return os.environ.get("PICKPLAN_CACHE_DIR") or os.path.join(os.path.expanduser("~"), ".cache", "pickplan")


def _mesh_arrays(mesh) -> Tuple[np.ndarray, np.ndarray]:
    V = np.ascontiguousarray(np.asarray(mesh.vertices, dtype=np.float64))
    F = np.ascontiguousarray(np.asarray(mesh.faces, dtype=np.int32))
    if V.ndim != 2 or V.shape[1] != 3 or len(V) == 0:
        raise ValueError(f"mesh vertices: expected shape (N, 3) with N > 0, got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0:
        raise ValueError(f"mesh faces: expected shape (M, 3) with M > 0, got {F.shape}")
    return V, F


def mesh_key(vertices: np.ndarray, faces: np.ndarray, settings: SdfSettings) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(faces, dtype=np.int64).tobytes())
    h.update(f"{settings.resolution:.9g}/{settings.margin:.9g}/v{SDF_FORMAT_VERSION}".encode())
    return h.hexdigest()[:32]


def mesh_sdf(mesh, settings: SdfSettings = SdfSettings()) -> "_core.SdfGrid":
    """The SDF grid of a trimesh (mesh frame). Loaded from the disk cache when built before."""
    V, F = _mesh_arrays(mesh)
    if not getattr(mesh, "is_watertight", True):
        warnings.warn("SDF of a mesh that is not watertight: inside/outside comes from a 3-axis ray vote",
                      stacklevel=2)
    cache = default_cache_dir() if settings.cache_dir is None else settings.cache_dir
    path = os.path.join(cache, "sdf", mesh_key(V, F, settings) + ".npz") if cache else None
    if path and os.path.isfile(path):
        try:
            with np.load(path) as z:
                return _core.SdfGrid.from_values(z["origin"], float(z["resolution"]), z["values"])
        except (OSError, ValueError, KeyError) as exc:  # a corrupt cache entry is rebuilt, not fatal
            warnings.warn(f"ignoring unreadable SDF cache file {path}: {exc}", stacklevel=2)
    grid, _report = _core.SdfGrid.build(V, F, settings.resolution, settings.margin)
    if path:
        with atomic_open(path, "wb") as f:
            np.savez(f, origin=grid.origin, resolution=grid.resolution, values=grid.values)
    return grid


class SceneSdf:
    """Named, posed object grids plus an optional table box; batched distance queries.

    ``distance(points, cutoff, exclude=("name", ...))`` returns (d (N,), grad (N, 3)); bodies
    farther than ``cutoff`` are skipped, so use the CHOMP padding as cutoff in cost evaluation.
    """

    def __init__(self, objects: Iterable[Tuple[str, "_core.SdfGrid", np.ndarray]] = (),
                 table: Optional[Tuple[Sequence[float], np.ndarray]] = None):
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

    def merge(self, exclude: Sequence[str] = (), resolution: float = 0.01, cutoff: float = 0.2,
              brick: int = 4) -> None:
        """Resample every object but ``exclude`` into one world-frame grid clamped at ``cutoff``:
        queries with the same exclusion and a cutoff no larger take a single lookup."""
        self._native.merge([self.index(n) for n in exclude], float(resolution), float(cutoff), int(brick))

    @property
    def merged_info(self) -> Optional[dict]:
        return self._native.merged_info

    def lower_bound(self, points, exclude: Sequence[str] = (), exclude_table: bool = False) -> np.ndarray:
        return self._native.lower_bound(points, [self.index(n) for n in exclude], exclude_table)

    def distance(self, points, cutoff: float = np.inf, exclude: Sequence[str] = (),
                 exclude_table: bool = False) -> Tuple[np.ndarray, np.ndarray]:
        return self._native.distance(points, cutoff, [self.index(n) for n in exclude], exclude_table)
