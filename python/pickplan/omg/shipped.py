"""The cache entries pickplan ships (``assets/cache``): what depends only on the built-in objects and
the shipped robots, computed once by ``make builtin-cache`` (``tools/build_builtin_cache.py``) instead
of on a user's first plan. They are read through ``core.io.cache_entry``, which checks each file's
SHA-256 against ``assets/cache/manifest.json`` and falls back to computing (with a warning) when a file
is damaged or was made by another version of its generator (its name is the hash of its inputs).

Shipped: the planner's default grasp set (``OMGSettings``: "simulated", its count and seed) of every
built-in object for each shipped robot's gripper: the minute-long part of a first plan. Not shipped:
SDF grids (the native build takes 0.2-0.6 s an object, less than reading back a losslessly compressed
grid of about 1 MB) and what a plan builds in well under a second.
"""

from __future__ import annotations

import os
from typing import Iterable, List, Optional, Sequence, Tuple

from pickplan.core import io, objects
from pickplan.core.description import RobotInfo
from pickplan.core.objects_builtin import BUILTIN_SPECS
from pickplan.core.robots import load_robot
from pickplan.omg.grasps import simulated
from pickplan.omg.grasps.sets import GraspKind
from pickplan.omg.planner import OMGSettings

SHIPPED_ROBOTS = ("panda",)  # whose grippers' grasp sets ship; another robot's are computed on first use


def grippers(robot_names: Sequence[str] = SHIPPED_ROBOTS) -> List[RobotInfo]:
    return [load_robot(name).info for name in robot_names]


def grasp_entries(
    names: Optional[Iterable[str]] = None,
    robot_names: Sequence[str] = SHIPPED_ROBOTS,
    settings: OMGSettings = OMGSettings(),
) -> List[Tuple[str, str, str, RobotInfo]]:
    """(object name, entry path relative to the cache folder, entry label, gripper) of each shipped grasp
    set: where the planner's default grasp set is cached by this version (``simulated.cache_name``)."""
    if settings.grasp_kind not in (GraspKind.simulated, GraspKind.simulated.value):
        raise ValueError(f"only the simulated grasp set ships, got {settings.grasp_kind!r}")
    library = objects.library("builtin")
    out = []
    for gripper in grippers(robot_names):
        for name in sorted(BUILTIN_SPECS) if names is None else names:
            request = (library.get(name), settings.grasp_count, settings.seed)
            file = simulated.cache_name(*request, gripper=gripper)
            out.append(
                (name, f"{simulated.CACHE_FOLDER}/{file}", simulated.entry_label(*request, gripper=gripper), gripper)
            )
    return out


def _owner(label: str) -> Tuple[str, ...]:
    """An entry label's object and gripper (``simulated.entry_label``: "object / gripper / request")."""
    return tuple(label.split(" / ")[:2])


def build(
    folder: Optional[str] = None,
    names: Optional[Iterable[str]] = None,
    workers: int = 1,
    progress: Optional[bool] = None,
) -> dict:
    """Compute the shipped entries (``names``: the built-in objects to redo, default all) into ``folder``
    (default ``io.shipped_dir()``) and rewrite its manifest; an older entry of the same object and gripper
    (another version, or the default request before its settings changed) is removed: only the default
    request ships. Returns the manifest's entries."""
    folder = io.shipped_dir() if folder is None else folder
    settings = OMGSettings()
    library = objects.library("builtin")
    entries = io.read_manifest(folder)
    for name, rel, label, gripper in grasp_entries(names, settings=settings):
        for old in [r for r, e in entries.items() if _owner(e.get("label", "")) == _owner(label)]:
            entries.pop(old)
            if os.path.isfile(os.path.join(folder, old)):
                os.unlink(os.path.join(folder, old))
        gs = simulated.simulated_grasps(
            library.get(name),
            settings.grasp_count,
            settings.seed,
            workers=workers,
            progress=progress,
            cache=False,
            gripper=gripper,
        )
        path = os.path.join(folder, rel)
        simulated.write_grasp_file(path, gs)
        entries[rel] = {"sha256": io.file_sha256(path), "label": label, "grasps": int(len(gs.poses))}
        # after each object: an interrupted build keeps what it finished
        io.write_json(os.path.join(folder, io.SHIPPED_MANIFEST), {"format": io.SHIPPED_FORMAT, "entries": entries})
    return entries
