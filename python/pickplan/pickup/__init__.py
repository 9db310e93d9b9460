"""Pick-up on the move (Thakar et al.).

- ``metamodel`` (Sec. IV): moving-gripper grasp simulation, SVM active learning of the grasping
  success boundary and the success-probability meta-model rho_sigma(S_g, S_c). Pure Python (numpy,
  pybullet, scikit-learn, scipy): it never imports pickplan._core; matplotlib only for plots.
- ``nlp`` (Sec. V): the mobile-manipulator polynomial NLP (native Ipopt through pickplan._core),
  successive refinement, the paper's cases and their PyBullet replay.

This package's own names are part 1's, importable without the native module.
"""

from pickplan.pickup.metamodel.active import ActiveConfig, BoundaryResult, PoseDomain, learn_boundary, learn_random
from pickplan.pickup.metamodel.build import build_metamodel
from pickplan.pickup.metamodel.model import (
    DEFAULT_LEVELS,
    BoundaryModel,
    BuildConfig,
    MetaModel,
    SigmaLevel,
    success_probability,
)
from pickplan.pickup.metamodel.parallel import SimRunner, run_batch
from pickplan.pickup.metamodel.parts import PARTS, GraspStrategy, Part, get_part
from pickplan.pickup.metamodel.sim import GraspOutcome, SimConfig, simulate_grasp
from pickplan.pickup.metamodel.surface import RhoSurface, fit_rho_surface

__all__ = [
    "ActiveConfig",
    "BoundaryResult",
    "PoseDomain",
    "learn_boundary",
    "learn_random",
    "DEFAULT_LEVELS",
    "BoundaryModel",
    "BuildConfig",
    "MetaModel",
    "SigmaLevel",
    "build_metamodel",
    "success_probability",
    "SimRunner",
    "run_batch",
    "PARTS",
    "GraspStrategy",
    "Part",
    "get_part",
    "GraspOutcome",
    "SimConfig",
    "simulate_grasp",
    "RhoSurface",
    "fit_rho_surface",
]
