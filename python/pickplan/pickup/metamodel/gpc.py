"""Gaussian-process classification of the GSB samples, for rho (Sec. IV-B, estimated with a
calibrated probability model).

The SVM learns the GSB and drives the sampling (active.py); its success depth with a fitted
logistic band (calibration.py) is a heuristic probability: the band is symmetric and one
width serves the whole boundary, while the simulated success is nearly deterministic in the
pose and the classifier's own error is not the same on both sides. Measured against 2,000
direct simulations per pair, that smears rho toward the value of a wider Gaussian (too low
where rho is high, too high where it is low).

A Gaussian-process classifier on the same labelled samples (free ones included) models
P(success | pose) = sigmoid(f(pose)) with f ~ GP(0, a^2 RBF(l_x, l_y, l_phi)), fitted by the
Laplace approximation with the amplitude and length scales chosen by marginal likelihood.
rho for N(0, sigma) is the Monte-Carlo mean of the predictive probability (the expectation
of rho over the posterior of f); its standard error is the posterior standard deviation of
rho, from joint draws of f at a subset of the query poses. Poses outside the modelled
domain count as failures, as in calibration.py.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_triangular
from threadpoolctl import threadpool_limits

AMPLITUDE_BOUNDS = (1e-2, 1e4)  # a^2
LENGTH_BOUNDS = (1e-3, 10.0)  # normalized pose units; 10 ~ "does not matter" (a round part's phi)
MODE_TOLERANCE = 0.05  # GPSuccessModel.mode_error above this: the fit failed
CONFIDENT = 0.9  # lapse_rate: samples the GP predicts at least this likely to succeed


@dataclass(frozen=True)
class GPConfig:
    restarts: int = 1  # extra optimizer starts (log-uniform in the bounds, seeded)
    n_se_queries: int = 1000  # query poses for the posterior standard deviation of rho
    n_posterior: int = 200  # joint posterior draws of f at those poses
    max_iter: int = 60  # L-BFGS-B iterations of the marginal-likelihood fit


def _kernel(theta=None, amplitude_cap: float = AMPLITUDE_BOUNDS[1]):
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel

    k = ConstantKernel(min(10.0, amplitude_cap), (AMPLITUDE_BOUNDS[0], amplitude_cap)) * RBF(
        [0.5, 0.5, 0.5], LENGTH_BOUNDS
    )
    return k if theta is None else k.clone_with_theta(np.asarray(theta, float))


def _optimizer(max_iter: int):
    """L-BFGS-B on the negative log marginal likelihood with an iteration cap: separable
    labels push the amplitude to its bound along a long flat ridge."""
    from scipy.optimize import minimize

    def run(obj_func, initial_theta, bounds):
        r = minimize(obj_func, initial_theta, method="L-BFGS-B", jac=True, bounds=bounds, options={"maxiter": max_iter})
        return r.x, r.fun

    return run


class GPSuccessModel:
    """P(success) of normalized poses from a Laplace GP classifier on (X, y). With theta
    (log hyperparameters of a previous fit) the hyperparameters are reused, not optimized:
    a saved model reloads in milliseconds and reproduces its probabilities."""

    def __init__(self, X, y, theta=None, seed: int = 0, config: GPConfig = GPConfig()):
        self.X = np.asarray(X, float).reshape(-1, 3)
        self.y = np.asarray(y, bool)
        self.config = config
        self.constant = None
        self._gpc = None
        if self.y.all() or (~self.y).all():
            self.constant = bool(self.y.all()) if len(self.y) else False
            self.theta = None
            return
        from sklearn.gaussian_process import GaussianProcessClassifier

        # Nearly separable labels push the amplitude to its cap, where the Laplace mode
        # search can stop short of the mode (f != K (y - pi)) and the predictions go wild.
        # Each fit is checked and, if it failed, redone with a 10x lower cap.
        caps = [AMPLITUDE_BOUNDS[1] / 10**k for k in range(4)] if theta is None else [None]
        for cap in caps:
            kernel = _kernel(theta) if cap is None else _kernel(None, cap)
            # One BLAS thread: the matrices are a few hundred wide, and threads that spin
            # while simulation workers hold the cores slow the fit down by orders of magnitude.
            with warnings.catch_warnings(), threadpool_limits(1):
                # Hyperparameters at a bound (e.g. a length scale that does not matter)
                # are expected and harmless here.
                warnings.simplefilter("ignore")
                self._gpc = GaussianProcessClassifier(
                    kernel,
                    optimizer=None if cap is None else _optimizer(config.max_iter),
                    n_restarts_optimizer=config.restarts,
                    random_state=seed,
                ).fit(self.X, self.y)
            if cap is None or self.mode_error() <= MODE_TOLERANCE:
                break
        self.theta = [float(v) for v in self._gpc.kernel_.theta]

    def mode_error(self) -> float:
        """Largest |sigmoid(f) - pi| over the training poses, f the predictive latent mean
        K (y - pi) and pi the Laplace mode's probabilities: 0 at a true mode."""
        if self._gpc is None:
            return 0.0
        b = self._gpc.base_estimator_
        with threadpool_limits(1):
            f = b.kernel_(b.X_train_) @ (b.y_train_ - b.pi_)
        return float(np.max(np.abs(0.5 * (1.0 + np.tanh(0.5 * f)) - b.pi_)))

    @property
    def hyperparameters(self) -> dict:
        """Amplitude a^2 and length scales (x, y, phi), normalized units."""
        if self.theta is None:
            return {}
        t = np.exp(self.theta)
        return {"amplitude": float(t[0]), "length_scales": [float(v) for v in t[1:]]}

    def probability(self, U) -> np.ndarray:
        """Predictive P(success) of normalized poses U (n, 3); 0 outside [-1, 1]^3."""
        U = np.asarray(U, float).reshape(-1, 3)
        ok = np.all(np.abs(U) <= 1.0, axis=1)
        p = np.zeros(len(U))
        if ok.any():
            p[ok] = float(self.constant) if self.constant is not None else self._gpc.predict_proba(U[ok])[:, 1]
        return p

    def _latent_posterior(self, U):
        """Joint Laplace posterior (mean, covariance) of f at the poses U (GPML Alg. 3.2)."""
        b = self._gpc.base_estimator_
        Ks = b.kernel_(b.X_train_, U)
        mean = Ks.T @ (b.y_train_ - b.pi_)
        V = solve_triangular(b.L_, b.W_sr_[:, None] * Ks, lower=True)
        return mean, b.kernel_(U) - V.T @ V

    def probability_variance(self, U) -> np.ndarray:
        """Posterior variance of P(success) at the poses U (delta method:
        (p (1 - p))^2 var f), 0 outside the domain or for a constant model: large where the
        boundary passes and is not yet pinned down."""
        U = np.asarray(U, float).reshape(-1, 3)
        ok = np.all(np.abs(U) <= 1.0, axis=1)
        out = np.zeros(len(U))
        if self.constant is None and ok.any():
            b = self._gpc.base_estimator_
            Ks = b.kernel_(b.X_train_, U[ok])
            f = Ks.T @ (b.y_train_ - b.pi_)
            V = solve_triangular(b.L_, b.W_sr_[:, None] * Ks, lower=True)
            var_f = np.clip(b.kernel_.diag(U[ok]) - np.einsum("ij,ij->j", V, V), 0.0, None)
            p = 0.5 * (1.0 + np.tanh(0.5 * f))
            out[ok] = (p * (1.0 - p)) ** 2 * var_f
        return out

    def rho(self, U, seed: int = 0, ceiling: float = 1.0) -> tuple:
        """(rho_hat, posterior standard deviation of rho) for the Monte-Carlo poses U, with
        the probability of each pose capped at ceiling (1 - the part's lapse rate)."""
        U = np.asarray(U, float).reshape(-1, 3)
        rho_hat = float(np.minimum(self.probability(U), ceiling).mean())
        if self.constant is not None or not len(U):
            return rho_hat, 0.0
        ok = np.all(np.abs(U) <= 1.0, axis=1)
        sub = np.flatnonzero(ok)[: self.config.n_se_queries]
        if len(sub) == 0:
            return rho_hat, 0.0
        with threadpool_limits(1):
            mean, cov = self._latent_posterior(U[sub])
            # Draws of f at the subset (eigen-decomposition: the covariance of close poses
            # is numerically singular); each draw gives P(success | inside the domain).
            evals, evecs = np.linalg.eigh(cov)
        root = evecs * np.sqrt(np.clip(evals, 0.0, None))
        z = np.random.default_rng(seed).standard_normal((len(sub), self.config.n_posterior))
        f = mean[:, None] + root @ z
        draws = np.minimum(0.5 * (1.0 + np.tanh(0.5 * f)), ceiling).mean(axis=0)
        return rho_hat, float(ok.mean() * draws.std(ddof=1))


def lapse_rate(fits) -> float:
    """Rate of failures that no pose explains, pooled over a part's boundaries: among the
    simulated samples whose GP predicts success with probability >= CONFIDENT, the share
    that failed, as the posterior mean under a uniform prior ((failed + 1) / (n + 2)).
    fits: (GPSuccessModel, simulated mask) pairs; free samples (labelled by monotonicity,
    not simulated) do not count. Measured: cylinder 1.2-2.0 %, box 0.3-0.5 %, L-bracket
    0.2 %; CONFIDENT = 0.95 gives the same counts on the cylinder."""
    failed = n = 0
    for gp, simulated in fits:
        confident = (gp.probability(gp.X) >= CONFIDENT) & np.asarray(simulated, bool)
        failed += int((~gp.y[confident]).sum())
        n += int(confident.sum())
    return (failed + 1) / (n + 2)
