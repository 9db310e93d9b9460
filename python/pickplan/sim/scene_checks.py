"""Checks of scene files at the door: numbers (not strings) everywhere, rigid poses, and objects
that rest on the table rather than inside or under it."""
from __future__ import annotations

from typing import Optional

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.poses import clean_pose


def numbers_only(value, what) -> None:
    """Strings ("1.0") and booleans convert to floats silently in numpy: refuse them."""
    stack = [value]
    while stack:  # iterative: a deeply nested list must not exhaust the stack
        v = stack.pop()
        if isinstance(v, (list, tuple)):
            stack.extend(v)
        elif isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)):
            raise ValueError(f"{what}: expected numbers, got {type(v).__name__} {v!r:.40}")


def array(value, shape, what) -> np.ndarray:
    numbers_only(value, what)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ValueError(f"{what}: expected numbers, got {value!r:.80}") from exc
    if arr.shape != shape:
        raise ValueError(f"{what}: expected shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what}: contains NaN or infinity")
    return arr


def pose(value, what) -> np.ndarray:
    return clean_pose(array(value, (4, 4), what), what)


def seed(value) -> Optional[int]:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"seed: expected an integer or null, got {value!r:.40}")
    return value


MAX_TABLE_PENETRATION = 0.01  # m: settled objects sink a few mm into the table in PyBullet; more is a bad pose


def check_placement(scene, library: Optional[objects_mod.ObjectLibrary] = None) -> None:
    """ValueError naming the object when one over the table reaches more than
    ``MAX_TABLE_PENETRATION`` below its top face (into it, or under it)."""
    if scene.table is None:
        return  # nothing to rest on or pass through
    T_table = np.asarray(scene.table.pose, dtype=float)
    half = 0.5 * np.asarray(scene.table.size, dtype=float)
    to_table = np.linalg.inv(T_table)
    for i, o in enumerate(scene.objects):
        try:
            model = library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)
        except KeyError as exc:  # not an object of that library: bad input, named
            raise ValueError(f"objects[{i}].source: {exc.args[0] if exc.args else exc}") from None
        V = np.asarray(model.mesh.vertices, dtype=float)
        local = (to_table @ np.asarray(o.pose, dtype=float))
        P = V @ local[:3, :3].T + local[:3, 3]
        centre = P.mean(axis=0)
        if np.any(np.abs(centre[:2]) > half[:2]):
            continue  # beside the table: nothing to pass through
        depth = half[2] - P[:, 2].min()
        if depth > MAX_TABLE_PENETRATION:
            raise ValueError(f"objects[{i}].pose: object {o.name!r} reaches {100 * depth:.1f} cm below the "
                             f"table top (into or under the table; at most {100 * MAX_TABLE_PENETRATION:.0f} cm)")
