"""The paper's tables and what each of their methods means (Sec. IV): Table I (selection policies),
Table II (grasp sets with and without C-Space ISF), Table III (planners) and Fig. 8 (ablation of N
and lambda). A method's name (a column of its table: "MD", "A+ISF", "RRT-C", "n=30") is parsed once,
into a ``MethodSpec``.

>>> spec = method_spec(Table.refinement, "A+ISF")
>>> spec.grasp_kind, spec.refine
(<GraspKind.approach: 'approach'>, True)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple, Union

from pickplan.core.ik import IkSettings
from pickplan.core.settings import Option
from pickplan.eval.baselines import Baseline
from pickplan.omg.chomp import ChompSettings
from pickplan.omg.goals import GoalSetSettings
from pickplan.omg.grasps import GraspKind
from pickplan.omg.planner import OMGSettings
from pickplan.omg.selection import Selection
from pickplan.omg.world import WorldSettings


class Table(Option):
    """The paper's tables a sweep reproduces."""

    selection = "selection"  # Table I
    refinement = "refinement"  # Table II
    planners = "planners"  # Table III
    ablation = "ablation"  # Fig. 8
    pickplace = "pickplace"  # pick and place (issue 34): OMG's pick, the methods on the place (eval.pickplace)


TABLES = tuple(t.value for t in Table)
SELECTION_METHODS = tuple(s.value for s in Selection)
REFINEMENT_METHODS = ("S", "S+ISF", "G", "G+ISF", "A", "A+ISF")
PLANNER_METHODS = (Baseline.CHOMP.value, Baseline.CHOMP_C.value, Baseline.FMT.value, Baseline.RRT_C.value, "OMG")
PICKPLACE_METHODS = ("OMG", "Fixed", Baseline.CHOMP.value, Baseline.RRT_C.value)
#: Methods a table runs only when ``--methods`` names them (depth: three rendered views).
OPTIONAL_METHODS = {Table.pickplace: ("OMG-3v",)}
ABLATION_N = (10, 20, 30, 40, 50)
ABLATION_LAMBDA = (0.01, 0.05, 0.1, 0.5, 1.0)
#: Table II's grasp sets by the first letter of their method.
GRASP_KINDS = {"S": GraspKind.simulated, "G": GraspKind.graspit, "A": GraspKind.approach}


@dataclass(frozen=True)
class MethodSpec:
    """What a method means: the OMG planner (``baseline`` None) or a baseline, its selection policy,
    C-Space ISF on or off, the grasp set, CHOMP's waypoints ``n`` and smoothness weight ``lambda_``."""

    baseline: Optional[Baseline] = None
    selection: Selection = Selection.MD
    refine: bool = True
    grasp_kind: GraspKind = GraspKind.simulated
    n: int = 30
    lambda_: float = 0.1

    def omg_settings(
        self, grasps: int, grasp_candidates: int, iterations: int, seed: int, world: WorldSettings = WorldSettings()
    ) -> OMGSettings:
        """The OMG settings of a unit of this method: ``grasps`` goals at most, ``grasp_candidates``
        grasps generated when the target has none stored, N = ``iterations``, seeded."""
        chomp = ChompSettings(n=self.n, lambda_=self.lambda_, duration=0.1 * 30)
        return OMGSettings(
            chomp=chomp,
            goals=GoalSetSettings(max_goals=grasps, seed=seed),
            ik=IkSettings(seed=seed),
            selection=self.selection,
            refine=self.refine,
            iterations=iterations,
            grasp_kind=self.grasp_kind,
            grasp_count=grasp_candidates,
            seed=seed,
            world=world,
        )


def all_methods(table: Union[Table, str], quick: bool = False) -> Tuple[str, ...]:
    table = Table.parse(table, "table")
    if table is Table.selection:
        return SELECTION_METHODS
    if table is Table.refinement:
        return REFINEMENT_METHODS
    if table is Table.planners:
        return PLANNER_METHODS
    if table is Table.pickplace:
        return PICKPLACE_METHODS
    ns, lams = ((20, 30), (0.1, 1.0)) if quick else (ABLATION_N, ABLATION_LAMBDA)
    return tuple(f"n={n}" for n in ns) + tuple(f"lambda={x:g}" for x in lams)


def method_spec(table: Union[Table, str], method: str) -> MethodSpec:
    """The ``MethodSpec`` of ``method`` (a column of ``table``); ValueError for an unknown one."""
    table = Table.parse(table, "table")
    if method not in all_methods(table) + OPTIONAL_METHODS.get(table, ()) and not (
        table is Table.ablation and method.startswith(("n=", "lambda="))
    ):
        raise ValueError(f"unknown method {method!r} for table {table.value!r}")
    if table is Table.selection:
        return MethodSpec(selection=Selection.parse(method), refine=False)
    if table is Table.refinement:
        return MethodSpec(grasp_kind=GRASP_KINDS[method[0]], refine=method.endswith("+ISF"))
    if table is Table.planners:
        return MethodSpec(baseline=None if method == "OMG" else Baseline.parse(method))
    if table is Table.pickplace:  # every method picks with OMG; they differ on the place (eval.pickplace)
        return MethodSpec()
    if method.startswith("n="):
        return MethodSpec(n=int(method[2:]))
    return MethodSpec(lambda_=float(method[7:]))
