"""The OMG planner (Wang, Xiang, Fox): CHOMP with a goal set, online grasp selection, C-Space ISF.

- ``world``: one scene as the planner sees it (robot, SDF, collision, target);
- ``chomp``: CHOMP / CHOMP-Proj (Sec. III-A, native) and the paper's metrics;
- ``grasps``: grasp sets (stored, generated: approach, antipodal; physics-verified) and the hand model;
- ``goals``: goal sets by IK (Sec. III-B);
- ``selection``: Fixed, Proj, FTC, FTL, EXP and Mirror Descent (Sec. III-C, Eq. 7-9);
- ``isf``: C-Space ISF grasp refinement (Sec. III-D);
- ``planner``: Algorithm 2, ``OMGPlanner``;
- ``native_loop``: Algorithm 2's loop in C++ and the native policies (the loop in Python, its test
  oracle, is tests/python/omg_reference_loop.py);
- ``model_cache``: what depends only on objects and robot, shared by worlds (``ModelCache``);
- ``batch``: many plans on parallel threads (``plan_many``).
"""

import importlib

__all__ = ["OMGPlanner", "OMGSettings", "PlanResult"]


def __getattr__(name: str):
    # lazily, so that importing one module of the planner does not load all of them
    if name in __all__:
        return getattr(importlib.import_module(f"{__name__}.planner"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
