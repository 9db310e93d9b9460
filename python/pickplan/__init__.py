"""pickplan: joint motion and grasp planning (OMG planner) and pick-up on the move.

Submodules are imported lazily so that pure-Python parts (e.g. ``pickplan.pickup``)
work even where only they are needed; ``pickplan._core`` is the native extension.
"""
from __future__ import annotations

import importlib

__version__ = "0.1.0"

_SUBMODULES = (
    "robots",
    "objects",
    "scenes",
    "sdf",
    "collision",
    "chomp",
    "grasps",
    "goals",
    "selection",
    "isf",
    "omg",
    "execution",
    "metrics",
    "experiments",
    "pickup",
    "viz",
    "cli",
)


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    if name == "OMGPlanner":
        return importlib.import_module(f"{__name__}.omg").OMGPlanner
    raise AttributeError(f"module 'pickplan' has no attribute {name!r}")


def __dir__():
    return sorted(list(globals()) + list(_SUBMODULES) + ["OMGPlanner"])
