"""Goal selection policies (OMG Sec. III-D): Fixed, Proj, FTC, FTL, EXP and Mirror Descent.

Each policy sees, at every iteration, the normalized cost vector c_{i+1} of the goal set and
returns the distribution p_{i+1}; the planner moves to the mode of p. Policies record their
history so ``regret()`` gives eq. 9. The goal set may grow (C-Space ISF adds refined goals):
``add_goal`` extends the distribution.
"""

from __future__ import annotations

import abc
import math
from typing import List, Optional, Sequence, Union

import numpy as np

from pickplan.core.settings import Option


class Selection(Option):
    """The goal selection policies (the values are the paper's names, used in JSON and the CLI)."""

    Fixed = "Fixed"
    Proj = "Proj"
    FTC = "FTC"
    FTL = "FTL"
    EXP = "EXP"
    MD = "MD"


class CostKind(Option):
    """What a policy's cost vector measures."""

    objective = "objective"  # goal-cost estimates (eq. 8)
    distance = "distance"  # |xi(1) - g|, the free end point's distance to each goal (Proj)


class SelectionPolicy(abc.ABC):
    """Base: keeps p, the cost history and the regret bookkeeping."""

    name = "base"
    cost_kind = CostKind.objective

    def __init__(self):
        self.p: Optional[np.ndarray] = None
        self.costs: List[np.ndarray] = []
        self.played: List[np.ndarray] = []
        self.horizon = 1

    def reset(self, num_goals: int, horizon: int, initial_costs: Optional[np.ndarray] = None) -> np.ndarray:
        if num_goals < 1:
            raise ValueError("a selection policy needs at least one goal")
        self.horizon = max(1, int(horizon))
        self.p = np.full(num_goals, 1.0 / num_goals)
        self.costs, self.played = [], []
        if initial_costs is not None:
            self._start(np.asarray(initial_costs, dtype=float))
        return self.p

    def _start(self, costs: np.ndarray) -> None:
        """Hook: initial estimates before the first iteration."""

    def add_goal(self) -> None:
        """A new goal joins the set: give it the mass of the current mode's share (then renormalize)."""
        extra = np.array([self.p.max()])
        self.p = np.concatenate([self.p, extra]) / (1.0 + extra[0])
        self.costs = [np.append(c, c.min()) for c in self.costs]
        self.played = [np.append(q, 0.0) for q in self.played]
        self._grow()

    def _grow(self) -> None:
        """Hook for policies with extra per-goal state."""

    def update(self, costs: np.ndarray) -> np.ndarray:
        c = np.asarray(costs, dtype=float)
        if c.shape != self.p.shape:
            raise ValueError(f"costs: expected shape {self.p.shape}, got {c.shape}")
        if not np.all(np.isfinite(c)):
            raise ValueError("costs must be finite")
        self.played.append(self.p.copy())
        self.costs.append(c)
        self.p = self._next(c)
        return self.p

    @abc.abstractmethod
    def _next(self, c: np.ndarray) -> np.ndarray:
        """The rule: p_{i+1} from the new cost vector c_{i+1}."""

    def select(self) -> int:
        """The mode of p (more stable than a sample, as the paper notes); ties: lowest index."""
        return int(np.argmax(self.p))

    def regret(self) -> float:
        """R_N = sum_i <c_i, p_i> - min_g sum_i c_i(g) (eq. 9)."""
        if not self.costs:
            return 0.0
        C = np.array(self.costs)
        P = np.array(self.played)
        return float(np.sum(C * P) - C.sum(axis=0).min())


def _one_hot(n: int, i: int) -> np.ndarray:
    p = np.zeros(n)
    p[i] = 1.0
    return p


class Fixed(SelectionPolicy):
    """The best goal by the initial estimate, kept for the whole optimization."""

    name = Selection.Fixed

    def _start(self, costs):
        self.p = _one_hot(len(costs), int(np.argmin(costs)))

    def _next(self, c):
        return self.p

    def _grow(self):
        self.p = _one_hot(len(self.p), int(np.argmax(self.p[:-1])))


class FTC(SelectionPolicy):
    """Follow the cheapest: all mass on the goal with the lowest current cost."""

    name = Selection.FTC

    def _next(self, c):
        return _one_hot(len(c), int(np.argmin(c)))


class Proj(FTC):
    """Goal-set CHOMP (Dragan et al. [11]): FTC on the distance from the free end point to each goal."""

    name = Selection.Proj
    cost_kind = CostKind.distance


class FTL(SelectionPolicy):
    """Follow the leader: all mass on the goal with the lowest cumulative cost."""

    name = Selection.FTL

    def _next(self, c):
        return _one_hot(len(c), int(np.argmin(np.sum(self.costs, axis=0))))


def _multiplicative(p: np.ndarray, c: np.ndarray, eta: float) -> np.ndarray:
    # p_{i+1} ∝ p_i exp(-eta c), in log space so long horizons cannot underflow.
    logits = np.log(np.maximum(p, 1e-300)) - eta * c
    logits -= logits.max()
    w = np.exp(logits)
    return w / w.sum()


class EXP(SelectionPolicy):
    """Exponential weighting with eta = sqrt(log|G| / N)."""

    name = Selection.EXP

    def __init__(self, eta: Optional[float] = None):
        super().__init__()
        self.fixed_eta = eta

    def eta(self) -> float:
        if self.fixed_eta is not None:
            return self.fixed_eta
        return math.sqrt(max(math.log(len(self.p)), 1e-12) / self.horizon)

    def _next(self, c):
        return _multiplicative(self.p, c, self.eta())


def shifted_kl_step(P: np.ndarray, scaled_costs: np.ndarray, shift: float) -> np.ndarray:
    """Rows of argmin_p <eta c, p> + KL(p + shift || p_k + shift) over the simplex, exactly.

    KKT: p_g = max(0, a_g e^lam - shift) with a_g = (p_k,g + shift) exp(-eta c_g) and lam such that
    sum p = 1; the goals with p_g > 0 are the k largest a_g, so lam follows from sorted partial
    sums. ``shift`` = 0 is the plain KL step p ∝ p_k exp(-eta c). ``scaled_costs`` holds eta_k c.
    """
    P = np.atleast_2d(P)
    logits = np.log(np.maximum(P + shift, 1e-300)) - scaled_costs
    logits -= logits.max(axis=1, keepdims=True)  # a scaled so its largest entry is 1: no overflow
    a = np.exp(logits)
    if shift == 0.0:
        return a / a.sum(axis=1, keepdims=True)
    a_sorted = -np.sort(-a, axis=1)
    k = np.arange(1, a.shape[1] + 1)
    scale = (1.0 + k * shift) / np.cumsum(a_sorted, axis=1)  # e^lam if the top k are the active set
    # The active set is the largest k whose k-th entry stays positive (a_(k) e^lam > shift).
    active = a_sorted * scale > shift
    kstar = a.shape[1] - 1 - np.argmax(active[:, ::-1], axis=1)
    e_lam = scale[np.arange(a.shape[0]), kstar]
    out = np.maximum(a * e_lam[:, None] - shift, 0.0)
    return out / out.sum(axis=1, keepdims=True)  # exact up to round-off


class MirrorDescent(SelectionPolicy):
    """Mirror descent with a (shifted) KL regularizer over an ensemble of learning rates.

    Each expert k solves p = argmin_p eta_k <c, p> + KL(p + delta || p_k + delta), eta_k = 2^k log N,
    k in {-2, -1, 0, 2, 4} (paper Sec. IV-B), exactly (``shifted_kl_step``). The shift delta =
    1 / (4 |G| + 1), as in the authors' implementation, keeps every goal's probability recoverable:
    with delta = 0 the step is p ∝ p_k exp(-eta_k c), whose mode is always the cumulative leader (MD
    then selects exactly as FTL); with the shift MD tracks a goal that has become cheaper (regret
    against a shifting comparator). The experts are combined by exponential weights on their loss
    <c, p_k> plus the switching cost |p_k - p_k,old|_1 (rate sqrt(log K / N)); p is the mixture.
    """

    name = Selection.MD

    def __init__(self, exponents: Sequence[int] = (-2, -1, 0, 2, 4), shift: Optional[float] = None):
        super().__init__()
        self.exponents = tuple(exponents)
        self.shift_setting = shift  # None: 1 / (4 |G| + 1)
        self.experts = np.zeros((len(self.exponents), 0))  # one distribution per row
        self.weights = np.ones(len(self.exponents)) / len(self.exponents)

    def etas(self) -> np.ndarray:
        return np.array([2.0**k * math.log(max(self.horizon, 2)) for k in self.exponents])

    def shift(self) -> float:
        if self.shift_setting is not None:
            return float(self.shift_setting)
        return 1.0 / (4 * self.experts.shape[1] + 1)

    def reset(self, num_goals, horizon, initial_costs=None):
        p = super().reset(num_goals, horizon, None)
        self.experts = np.tile(p, (len(self.exponents), 1))
        self.weights = np.ones(len(self.exponents)) / len(self.exponents)
        if initial_costs is not None:
            self._start(np.asarray(initial_costs, dtype=float))
        return self.p

    def _grow(self):
        top = self.experts.max(axis=1, keepdims=True)
        self.experts = np.hstack([self.experts, top]) / (1 + top)

    def _next(self, c):
        new = shifted_kl_step(self.experts, self.etas()[:, None] * c, self.shift())
        losses = new @ c + np.abs(new - self.experts).sum(axis=1)
        meta_eta = math.sqrt(math.log(len(self.experts)) / self.horizon) if len(self.experts) > 1 else 0.0
        self.weights = _multiplicative(self.weights, losses, meta_eta)
        self.experts = new
        p = self.weights @ self.experts
        return p / p.sum()


POLICIES = {policy.name: policy for policy in (Fixed, Proj, FTC, FTL, EXP, MirrorDescent)}


def make_policy(name: Union[Selection, str]) -> SelectionPolicy:
    """A fresh policy by its ``Selection`` (or that's spelling: "MD")."""
    return POLICIES[Selection.parse(name, "selection policy")]()
