"""A cheap synthetic stand-in for the simulation, with a known success region.

Shaped like the simulated GSBs: an ellipsoid in the normalized pose space, long along the
approach axis x and thin in y and phi, that shrinks as S_g grows and widens as S_c grows.
Used to test and benchmark the active learner and the meta-model against exact truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pickplan.pickup.metamodel.active import PoseDomain


@dataclass(frozen=True)
class EllipsoidOracle:
    s_g: float
    s_c: float

    @property
    def half_axes(self) -> np.ndarray:
        # Tolerance ~ S_c / S_g, as for contact timing: early contact at offset d happens
        # d / S_c before t', when the part is still S_g * d / S_c ahead.
        k = np.clip(0.6 * (self.s_c / 0.1) / (self.s_g / 0.3) ** 0.7, 0.4, 2.0)
        return np.array([0.6, 0.2, 0.25]) * k

    def __call__(self, U) -> np.ndarray:
        U = np.asarray(U, dtype=float).reshape(-1, 3)
        return (((U / self.half_axes) ** 2).sum(axis=1)) < 1.0

    def probability(
        self, sigma_r: float, sigma_phi: float, domain: PoseDomain = PoseDomain(), n: int = 200000, seed: int = 12345
    ) -> float:
        """Monte-Carlo truth of P(success) for poses ~ N(0, sigma) (independent samples)."""
        return _gaussian_mean(self, sigma_r, sigma_phi, domain, n, seed)


def _gaussian_mean(fn, sigma_r, sigma_phi, domain, n, seed) -> float:
    """Mean of fn over n normalized poses from N(0, diag(sigma_r, sigma_r, sigma_phi))."""
    z = np.random.default_rng(seed).standard_normal((n, 3))
    return float(np.mean(fn(domain.to_normalized(z * np.array([sigma_r, sigma_r, sigma_phi])))))


def oracle_factory(s_g: float, s_c: float, seed: int):
    """label_fn_factory for build_metamodel: the oracle itself (seed unused: no noise)."""
    return EllipsoidOracle(s_g, s_c)


@dataclass
class NoisyEllipsoidOracle:
    """The ellipsoid with label noise like the simulation's friction jitter: a pose at
    ellipsoid radius r (r = 1 on the boundary) succeeds with probability
    sigmoid((1 - r) / width). Labels are drawn from a seeded stream (deterministic for a
    given sequence of calls); `probability` is the exact expected success rate."""

    s_g: float
    s_c: float
    width: float = 0.1
    seed: int = 0

    def __post_init__(self):
        self._base = EllipsoidOracle(self.s_g, self.s_c)
        self._rng = np.random.default_rng(self.seed)

    def success_probability(self, U) -> np.ndarray:
        U = np.asarray(U, dtype=float).reshape(-1, 3)
        r = np.sqrt(((U / self._base.half_axes) ** 2).sum(axis=1))
        return 0.5 * (1.0 + np.tanh(0.5 * (1.0 - r) / self.width))

    def __call__(self, U) -> np.ndarray:
        p = self.success_probability(U)
        return self._rng.uniform(size=len(p)) < p

    def probability(
        self, sigma_r: float, sigma_phi: float, domain: PoseDomain = PoseDomain(), n: int = 200000, seed: int = 12345
    ) -> float:
        """Expected success rate for poses ~ N(0, sigma) (Monte-Carlo of the exact p(u);
        standard error < 0.001 at the default n)."""
        return _gaussian_mean(self.success_probability, sigma_r, sigma_phi, domain, n, seed)


def noisy_oracle_factory(width: float = 0.1):
    """label_fn_factory for build_metamodel: a NoisyEllipsoidOracle seeded per pair."""

    def factory(s_g: float, s_c: float, seed: int):
        return NoisyEllipsoidOracle(s_g, s_c, width, seed)

    return factory
