"""pickplan: joint motion and grasp planning (OMG planner) and pick-up on the move.

The package is layered; every import points down the list:

- ``pickplan.core``: robot models, objects and meshes, SDFs, collision, files (shared by both papers);
- ``pickplan.sim``: PyBullet scenes, execution of plans, rendering;
- ``pickplan.omg``: the OMG planner (world, CHOMP, goal sets, grasps, selection, ISF, Algorithm 2);
- ``pickplan.pickup``: pick-up on the move (``metamodel``: grasp-success learning; ``nlp``: trajectories);
- ``pickplan.eval``: paper tables (sweeps on a process pool or Ray), baselines, the demo;
- ``pickplan.cli``: the ``pickplan`` command, one module per command group.

``pickplan._core`` is the native extension (private). Subpackages load on first use, and the
flat names of earlier releases (``pickplan.scenes``, ``pickplan.robots``, ``pickplan.execution``, ...)
still import, as aliases of their modules in the layers.
"""
from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys

__version__ = "0.1.0"

_PACKAGES = ("core", "sim", "omg", "pickup", "eval", "cli")

#: Flat module names of earlier releases -> their module in the layered tree.
_ALIASES = {
    "robots": "pickplan.core.robots",
    "objects": "pickplan.core.objects",
    "sdf": "pickplan.core.sdf",
    "collision": "pickplan.core.collision",
    "scenes": "pickplan.sim.scenes",
    "execution": "pickplan.sim.execution",
    "viz": "pickplan.sim.render",
    "chomp": "pickplan.omg.chomp",
    "grasps": "pickplan.omg.grasps",
    "goals": "pickplan.omg.goals",
    "selection": "pickplan.omg.selection",
    "isf": "pickplan.omg.isf",
    "world": "pickplan.omg.world",
    "experiments": "pickplan.eval.experiments",
    "baselines": "pickplan.eval.baselines",
}

__all__ = sorted(_PACKAGES + tuple(_ALIASES) + ("OMGPlanner", "__version__"))


class _AliasLoader(importlib.abc.Loader):
    """Makes ``import pickplan.scenes`` give the module ``pickplan.sim.scenes`` itself."""

    def __init__(self, target: str):
        self.target = target

    def create_module(self, spec):
        module = importlib.import_module(self.target)
        self._own_spec = module.__spec__
        return module

    def exec_module(self, module):
        module.__spec__ = self._own_spec  # the import system set the alias's spec: restore the module's own


class _AliasFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        prefix, _, leaf = fullname.rpartition(".")
        if prefix != __name__ or leaf not in _ALIASES:
            return None
        return importlib.util.spec_from_loader(fullname, _AliasLoader(_ALIASES[leaf]))


if not any(isinstance(f, _AliasFinder) for f in sys.meta_path):
    sys.meta_path.append(_AliasFinder())


def __getattr__(name: str):
    if name in _PACKAGES:
        return importlib.import_module(f"{__name__}.{name}")
    if name in _ALIASES:
        return importlib.import_module(_ALIASES[name])
    if name == "OMGPlanner":
        return importlib.import_module(f"{__name__}.omg.planner").OMGPlanner
    raise AttributeError(f"module 'pickplan' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
