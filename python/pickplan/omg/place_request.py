"""A place request: where the held object should go (``omg.place`` builds its goal set).

A region, an axis-aligned box whose floor lies on a support surface (an area of the table, the inside of
a bin), and an orientation rule: ``upright`` (the pose the object was in, yaw free), ``stable`` (any stable
resting pose of the object) or ``pose`` (a given rotation, within ``tolerance_deg``). Yaw is free unless
``yaw_deg`` is given. Read from JSON and checked at the door (``PlaceRequest.load``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple

import numpy as np

from pickplan.core.fields import FieldReader
from pickplan.core.io import read_json
from pickplan.core.settings import Option


class Orientation(Option):
    """How the placed object must be turned."""

    upright = "upright"  # as it stood before the pick (yaw free unless asked)
    stable = "stable"  # any stable resting pose of the object
    pose = "pose"  # a given rotation, within tolerance_deg


@dataclass(frozen=True)
class PlaceRequest:
    """Where to put the held object: the box [``region_min``, ``region_max``] (world, metres) the whole
    object must end inside, its floor on a support (the table top); the orientation rule; yaw."""

    region_min: Tuple[float, float, float]
    region_max: Tuple[float, float, float]
    orientation: Orientation = Orientation.upright
    rotation: Optional[Tuple[Tuple[float, ...], ...]] = None  # (3, 3) object -> world, for Orientation.pose
    tolerance_deg: float = 10.0  # the placed object's up axis within this of the planned one
    yaw_deg: Optional[float] = None  # a fixed yaw about the world's z (None: free)
    yaw_tolerance_deg: float = 15.0

    def __post_init__(self):
        lo, hi = np.asarray(self.region_min, float), np.asarray(self.region_max, float)
        if lo.shape != (3,) or hi.shape != (3,) or not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
            raise ValueError("place region: region_min and region_max must be 3 finite numbers each")
        if not np.all(hi > lo):
            raise ValueError(
                f"place region: region_max {hi.tolist()} must exceed region_min {lo.tolist()} on every axis"
            )
        object.__setattr__(self, "region_min", tuple(float(v) for v in lo))
        object.__setattr__(self, "region_max", tuple(float(v) for v in hi))
        object.__setattr__(self, "orientation", Orientation.parse(self.orientation, "place orientation"))
        if self.orientation is Orientation.pose:
            R = np.asarray(self.rotation if self.rotation is not None else np.zeros((0,)), float)
            if R.shape != (3, 3) or not np.allclose(R @ R.T, np.eye(3), atol=1e-4) or np.linalg.det(R) < 0:
                raise ValueError("place rotation: orientation 'pose' needs a (3, 3) rotation matrix")
            object.__setattr__(self, "rotation", tuple(tuple(float(v) for v in row) for row in R))
        for name in ("tolerance_deg", "yaw_tolerance_deg"):
            if not 0 < getattr(self, name) <= 180:
                raise ValueError(f"{name}: expected degrees in (0, 180], got {getattr(self, name)}")
        if self.yaw_deg is not None and not math.isfinite(self.yaw_deg):
            raise ValueError(f"yaw_deg: expected a number or null, got {self.yaw_deg}")

    @property
    def floor(self) -> float:
        return self.region_min[2]

    def to_dict(self) -> dict:
        return {
            "region": {"min": list(self.region_min), "max": list(self.region_max)},
            "orientation": self.orientation.value,
            **({"rotation": [list(r) for r in self.rotation]} if self.rotation is not None else {}),
            "tolerance_deg": self.tolerance_deg,
            "yaw_deg": self.yaw_deg,
            "yaw_tolerance_deg": self.yaw_tolerance_deg,
        }

    @classmethod
    def from_dict(cls, d: dict, path: Optional[str] = None) -> "PlaceRequest":
        """A request from its JSON form; ``InputError`` naming (the file ``path`` and) every wrong field."""
        r = FieldReader(path)
        with r:
            d = r.table(
                d, "", known=("region", "orientation", "rotation", "tolerance_deg", "yaw_deg", "yaw_tolerance_deg")
            )
            lo = hi = rotation = yaw = None
            with r.part():
                region = r.table(r.key(d, "region"), "region", known=("min", "max"))
                lo = r.get(region, "min", "region", r.vector, n=3)
                hi = r.get(region, "max", "region", r.vector, n=3)
                if lo is not None and hi is not None and not all(b > a for a, b in zip(lo, hi)):
                    r.note("region.max", f"must exceed region.min {list(lo)} on every axis, got {list(hi)}")
            orientation = r.get(
                d,
                "orientation",
                "",
                r.choice,
                default="upright",
                required=False,
                options=[o.value for o in Orientation],
            )
            if d.get("rotation") is not None:
                rotation = r.get(d, "rotation", "", r.array, shape=(3, 3))
                if rotation is not None and (
                    not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-4) or np.linalg.det(rotation) < 0
                ):
                    r.note("rotation", "not a rotation matrix (orthonormal, determinant 1)")
            elif orientation == Orientation.pose.value:
                r.note("rotation", "missing: orientation 'pose' needs a (3, 3) rotation matrix")
            angle = {"lo": 0.0, "hi": 180.0, "low_open": True, "unit": "deg"}
            tolerance = r.get(d, "tolerance_deg", "", r.number, default=10.0, required=False, **angle)
            if d.get("yaw_deg") is not None:
                yaw = r.get(d, "yaw_deg", "", r.number, unit="deg")
            yaw_tolerance = r.get(d, "yaw_tolerance_deg", "", r.number, default=15.0, required=False, **angle)
        return cls(lo, hi, orientation, None if rotation is None else rotation.tolist(), tolerance, yaw, yaw_tolerance)

    @classmethod
    def load(cls, path: str) -> "PlaceRequest":
        """A request from a JSON file; ``InputError`` naming the file and the field when it is wrong."""
        return cls.from_dict(read_json(path, "place request file"), path=str(path))
