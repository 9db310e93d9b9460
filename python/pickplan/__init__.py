"""pickplan: joint motion and grasp planning (OMG planner) and pick-up on the move.

The public API is the layered modules, imported by their full names; every import points down the
list:

- ``pickplan.core``: robot models, objects and meshes, SDFs, collision, files (shared by both papers),
  e.g. ``from pickplan.core import robots`` (``robots.panda()``, ``robots.load_robot("ur5_2f85")``);
- ``pickplan.sim``: PyBullet scenes, execution of plans, rendering
  (``from pickplan.sim import scenes, execution``);
- ``pickplan.perception``: the planner's world from depth images;
- ``pickplan.omg``: the OMG planner (world, CHOMP, goal sets, grasps, selection, ISF, Algorithm 2;
  ``from pickplan.omg import OMGPlanner, OMGSettings, PlanResult``);
- ``pickplan.pickup``: pick-up on the move (``metamodel``: grasp-success learning; ``nlp``: trajectories);
- ``pickplan.eval``: paper tables (sweeps on a process pool or Ray), baselines, the demo;
- ``pickplan.cli``: the ``pickplan`` command, one module per command group.

>>> from pickplan.core import robots
>>> from pickplan.omg import OMGPlanner, OMGSettings
>>> from pickplan.sim import execution, scenes
>>> scene = scenes.generate_scene(seed=1)
>>> result = OMGPlanner(robots.load_robot("panda"), scene, OMGSettings(grasp_kind="antipodal")).plan()

``pickplan._core`` is the native extension (private). Library code logs to the ``pickplan``
logger hierarchy and prints nothing; the application (the command line: ``pickplan.cli.output``)
decides what is shown.
"""

from __future__ import annotations

import logging

__version__ = "0.1.0"

__all__ = ["__version__"]

logging.getLogger(__name__).addHandler(logging.NullHandler())
