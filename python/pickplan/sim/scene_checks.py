"""Checks of scene files at the door (``core.fields.FieldReader``): numbers (not strings)
everywhere, rigid poses, and objects that rest on the table rather than inside or under it."""

from __future__ import annotations

from typing import Optional

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.errors import InputError
from pickplan.core.fields import FieldReader, shown
from pickplan.core.poses import clean_pose
from pickplan.core.shapes import read_obstacles

SCENE_FORMAT = "pickplan.scene"
SCENE_VERSION = 1
MAX_COORDINATE = 1e3  # m: any position in a scene
MAX_JOINT_VALUE = 100.0  # rad or m: the robot's configuration (its limits bound it further)


def _pose(r: FieldReader, value, where: str) -> np.ndarray:
    arr = r.array(value, where, shape=(4, 4))
    if np.abs(arr[:3, 3]).max() > MAX_COORDINATE:
        r.fail(where, f"position {arr[:3, 3].tolist()} is more than {MAX_COORDINATE:g} m from the robot")
    try:
        return clean_pose(arr, where)
    except InputError as exc:
        r.fail(where, exc.detail)


def _seed(r: FieldReader, value) -> Optional[int]:
    return None if value is None else r.integer(value, "seed")


def read_scene(d, path: Optional[str] = None) -> dict:
    """The validated values of a parsed scene file: robot_base, table (size, pose; None for "table":
    null), objects (name, source, pose), obstacles, target, seed, robot_configuration, robot;
    InputError naming every problem."""
    r = FieldReader(path)
    with r:
        r.table(d, "")
        if d.get("format") != SCENE_FORMAT:
            r.fail("format", f"not a scene: expected {SCENE_FORMAT!r}, got {shown(d.get('format'))}")
        if d.get("version") != SCENE_VERSION:
            r.fail(
                "version", f"unsupported scene version {shown(d.get('version'))} (this pickplan reads {SCENE_VERSION})"
            )
        out = {
            "robot_base": r.get(d, "robot_base", "", lambda v, w: _pose(r, v, w)),
            "seed": r.attempt(_seed, r, d.get("seed")),
        }
        out["size"] = out["table_pose"] = None
        if "table" not in d or d["table"] is not None:  # null: no table (shelves, bins, MoveIt scenes)
            table = r.get(d, "table", "", r.table, default={}, known=("size", "pose"))
            out["size"] = r.get(table, "size", "table", r.array, shape=(3,), lo=0.0)
            if out["size"] is not None and not np.all(out["size"] > 0):
                r.note("table.size", f"expected positive extents, got {out['size'].tolist()}")
            out["table_pose"] = r.get(table, "pose", "table", lambda v, w: _pose(r, v, w))
        items = r.get(d, "objects", "", r.items)
        out["objects"] = [r.attempt(_object, r, o, f) for f, o in items or []]
        names = [o[0] for o in out["objects"] if o is not None]
        if len(set(names)) != len(names):
            r.note("objects", f"object names must be unique, got {names}")
        # null: no target (a scene of obstacles to move among, e.g. from MoveIt)
        out["target"] = None if "target" in d and d["target"] is None else r.get(d, "target", "", r.text)
        if (
            out["target"] is not None
            and items is not None
            and None not in out["objects"]
            and out["target"] not in names
        ):
            r.note("target", f"{out['target'][:60]!r} is not one of the objects {names}")
        out["obstacles"] = []
        try:
            out["obstacles"] = read_obstacles(d.get("obstacles", []), names)
        except InputError as exc:
            for problem in exc.problems:
                r.note(problem.field, problem.message)
        out["robot"] = r.get(d, "robot", "", r.text, default="panda", required=False)
        q = d.get("robot_configuration", [])
        if not isinstance(q, (list, tuple)):
            r.fail("robot_configuration", f"expected a list of joint values, got {shown(q)}")
        out["robot_configuration"] = [
            float(x)
            for x in r.array(q, "robot_configuration", shape=(len(q),), lo=-MAX_JOINT_VALUE, hi=MAX_JOINT_VALUE)
        ]
    return out


def _object(r: FieldReader, o, where: str) -> tuple:
    r.table(o, where)
    name, source, pose = (r.key(o, k, where) for k in ("name", "source", "pose"))
    return str(name), str(source), _pose(r, pose, f"{where}.pose")


MAX_TABLE_PENETRATION = 0.01  # m: settled objects sink a few mm into the table in PyBullet; more is a bad pose


def check_placement(scene, library: Optional[objects_mod.ObjectLibrary] = None, path: Optional[str] = None) -> None:
    """InputError naming the object when one over the table reaches more than
    ``MAX_TABLE_PENETRATION`` below its top face (into it, or under it). With other support surfaces
    (obstacles marked ``support``: a shelf's lower boards) an object wholly under the table's bottom face
    stands on one of them, not in the table."""
    if scene.table is None:
        return  # nothing to rest on or pass through
    other_supports = any(getattr(ob, "support", False) for ob in getattr(scene, "obstacles", ()) or ())
    T_table = np.asarray(scene.table.pose, dtype=float)
    half = 0.5 * np.asarray(scene.table.size, dtype=float)
    to_table = np.linalg.inv(T_table)
    for i, o in enumerate(scene.objects):
        try:
            model = library.get(o.name) if library is not None else objects_mod.model_from_source(o.name, o.source)
        except KeyError as exc:  # not an object of that library: bad input, named
            raise InputError(str(exc.args[0] if exc.args else exc), path=path, field=f"objects[{i}].source") from None
        V = np.asarray(model.mesh.vertices, dtype=float)
        local = to_table @ np.asarray(o.pose, dtype=float)
        P = V @ local[:3, :3].T + local[:3, 3]
        centre = P.mean(axis=0)
        if np.any(np.abs(centre[:2]) > half[:2]):
            continue  # beside the table: nothing to pass through
        depth = half[2] - P[:, 2].min()
        if other_supports and P[:, 2].max() <= -half[2]:
            continue  # under the table, on another support
        if depth > MAX_TABLE_PENETRATION:
            raise InputError(
                f"object {o.name!r} reaches {100 * depth:.1f} cm below the table top (into or under the "
                f"table; at most {100 * MAX_TABLE_PENETRATION:.0f} cm)",
                path=path,
                field=f"objects[{i}].pose",
            )
