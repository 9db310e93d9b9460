"""SVM active learning of the grasping success boundary (GSB) for one (S_g, S_c) pair
(Sec. IV-A of Thakar et al.).

The learner works in the normalized pose space [-1, 1]^3 (see PoseDomain) and only needs a
labelling function, so it runs the same on the physics simulation and on cheap synthetic
oracles. Loop: a few initial samples and a uniform held-out set; then rounds that mix
exploration (random candidates, keeping those farthest from every existing sample) and
exploitation (midpoints of nearest pairs of support vectors with opposite labels, which lie
near the boundary by the maximal-margin property). The share of exploitation rises when the
accuracy improves and falls when it drops. Once rho is estimated, a quarter of the
exploitation samples go where the fold classifiers disagree most inside the query Gaussians
(exploit_rho: query-by-committee on rho's jackknife variance) and half on the stretch of the
boundary inside each query Gaussian (exploit_band: uncertainty sampling weighted by that
Gaussian, which puts samples within the few millimetres that decide the low level's rho). The SVM's kernel metric is
chosen with (C, gamma) (kernel.py).

Stopping (label-noise aware): near the boundary the simulated labels are noisy, so no
classifier reaches a high held-out accuracy there and an accuracy threshold never stops. The
learner instead stops when what the meta-model needs is settled: the calibrated success
probabilities rho for the query uncertainties (calibration.py) have a jackknife standard
error <= se_target and moved by <= rho_tol since the previous round, for `patience` rounds;
or when the simulation budget is spent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, List, Optional

import numpy as np

from pickplan.core.settings import Option
from pickplan.pickup.metamodel.calibration import calibrate, gaussian_queries
from pickplan.pickup.metamodel.gpc import GPConfig, GPSuccessModel
from pickplan.pickup.metamodel.kernel import fit_svm, success_metric
from pickplan.pickup.metamodel.sampling import exploit, exploit_band, exploit_gp, exploit_rho, explore, sample_focus


@dataclass(frozen=True)
class PoseDomain:
    """Pose offsets (x, y [m], phi [rad]) mapped to [-1, 1]^3 by dividing by the bounds.
    Offsets beyond the bounds are outside the model; queries there count as failures."""

    r_max: float = 0.05
    phi_max: float = math.pi / 3

    @property
    def scale(self) -> np.ndarray:
        return np.array([self.r_max, self.r_max, self.phi_max])

    def to_offsets(self, u) -> np.ndarray:
        return np.asarray(u, dtype=float) * self.scale

    def to_normalized(self, offsets) -> np.ndarray:
        return np.asarray(offsets, dtype=float) / self.scale


class RhoModel(Option):
    """What estimates rho, the success probability of a boundary, from its labelled samples. Two
    places choose one, with different defaults: the meta-model's rho per boundary
    (``BuildConfig.rho_model``, default ``gp``: the more accurate against direct simulation) and the
    learning loop's stopping rule and rho-directed samples (``ActiveConfig.rho_model``, default
    ``svm``: the GP there was measured and not adopted, bench/PICKUP.md)."""

    svm = "svm"  # the calibrated SVM success depth (calibration.py)
    gp = "gp"  # GP classification of the samples (gpc.py)


@dataclass(frozen=True)
class ActiveConfig:
    n_init: int = 30
    n_holdout: int = 40
    batch_size: int = 20
    budget: int = 300  # simulations per boundary, held-out set included
    # Stopping rule: rho for each query sigma (normalized (x, y, phi) standard deviations;
    # default: the low / medium / high levels of metamodel.DEFAULT_LEVELS in the default
    # PoseDomain) estimated on n_rho_queries poses.
    query_sigmas: tuple = ((0.04, 0.04, 1 / 12), (0.14, 0.14, 1 / 6), (0.24, 0.24, 0.25))
    n_rho_queries: int = 2000
    se_target: float = 0.02  # the conservative margin is z * se: stop when it is small
    rho_tol: float = 0.02
    calib_folds: int = 5
    patience: int = 2
    min_rounds: int = 3
    exploit_weight: float = 0.5  # start with equal exploration and exploitation
    weight_step: float = 0.1
    weight_bounds: tuple = (0.2, 0.9)
    svm_c: float = 100.0  # initial hyperparameters; re-selected by cross-validation
    svm_gamma: float = 2.0
    c_grid: tuple = (10.0, 100.0, 1000.0)
    gamma_grid: tuple = (1.0, 3.0, 10.0, 30.0, 100.0)
    # Kernel metric Sigma_success^(-alpha/2) (kernel.py), alpha chosen with (C, gamma).
    metric_powers: tuple = (0.0, 0.5, 1.0)
    # Noise band fitted locally to each query sigma (calibration.Calibration.band).
    local_kappa: float = 3.0
    local_floor: float = 1.0
    select_every: int = 3  # rounds between hyperparameter selections
    n_candidates: int = 2000
    known_margin: float = 1.0  # decision value beyond which a lower-S_c success is trusted
    # Where the meta-model is queried: poses ~ N(0, focus_scale^2) in normalized units
    # (0.25 ~ the highest modelled uncertainty). The held-out set, the probe points and part
    # of the initial and exploration samples come from it, so accuracy is measured where it
    # matters rather than in far corners of the domain that are plain failures.
    focus_scale: float = 0.25
    focus_fraction: float = 0.5
    query_init: int = 3  # initial samples (of n_init) from each query Gaussian
    query_fraction: float = 0.3  # share of exploration samples from the query Gaussians
    # Share of the exploitation samples placed where the fold classifiers disagree most
    # about P(success) inside the query Gaussians (exploit_rho), once rho is estimated.
    rho_share: float = 0.25
    # Share placed on each query Gaussian's stretch of the boundary (exploit_band).
    band_share: float = 0.5
    # What estimates rho inside the loop (stopping rule, rho-directed samples): "svm" (the
    # calibrated SVM depth, calibration.py) or "gp" (GP classification, gpc.py: its
    # posterior standard deviation of rho is calibrated against direct simulation). The GP's
    # hyperparameters are re-optimized every select_every rounds.
    rho_model: RhoModel = RhoModel.svm
    gp_se_queries: int = 500


def select_svm_params(X, y, c_grid, gamma_grid, seed: int = 0, folds: int = 5, simulated=None, metric_powers=(0.0,)):
    """(C, gamma, metric) with the best calibrated out-of-fold likelihood
    (calibration.calibrate: k-fold depths through the logistic in depth fitted to the
    simulated samples, scored on every label); ties go to the smoother model (isotropic
    metric first, then smaller gamma, then smaller C). The GSB's scale and shape vary a lot
    with the speeds (a thin slab at high S_g, a wide region at low S_g), so one fixed kernel
    does not fit every pair; plain accuracy is a poor criterion with noisy labels near the
    boundary (it cannot tell a well-placed boundary from a lucky one)."""
    y = np.asarray(y, dtype=bool)
    if min(y.sum(), (~y).sum()) < 2:
        return None
    sim = np.ones(len(y), bool) if simulated is None else np.asarray(simulated, bool)
    best, best_nll = None, np.inf
    for alpha in sorted(metric_powers):
        L = success_metric(X, y, alpha)
        for gamma in sorted(gamma_grid):
            for c in sorted(c_grid):
                cal = calibrate(X, y, sim, lambda A, b: fit_svm(A, b, c, gamma, L), folds, seed, fit_full=False)
                if cal.nll < best_nll - 1e-6:
                    best, best_nll = (float(c), float(gamma), L), cal.nll
    return best


def balanced_accuracy(pred, y) -> float:
    """Mean recall over the classes present: a tiny success region cannot be 'learned' by
    predicting failure everywhere."""
    pred, y = np.asarray(pred, bool), np.asarray(y, bool)
    recalls = [float(np.mean(pred[y == c] == c)) for c in (True, False) if np.any(y == c)]
    return float(np.mean(recalls)) if recalls else 1.0


def predict(model, X) -> np.ndarray:
    return model.decision_function(np.asarray(X, dtype=float)) > 0


@dataclass
class BoundaryResult:
    """Samples and classifier of one GSB. `simulated` marks samples that cost a simulation
    (the others were labelled free from S_c monotonicity)."""

    X: np.ndarray
    y: np.ndarray
    simulated: np.ndarray
    model: object
    n_simulations: int
    converged: bool
    history: list = field(default_factory=list)
    svm_c: float = 100.0
    svm_gamma: float = 2.0
    svm_metric: np.ndarray = field(default_factory=lambda: np.eye(3))

    @property
    def n_free(self) -> int:
        return int((~self.simulated).sum())


KnownFn = Callable[[np.ndarray], tuple]


def known_from_lower_sc(model, margin: float) -> KnownFn:
    """Monotonicity in S_c (Sec. IV): a grasp that succeeds at some S_c also succeeds at a
    higher S_c. Points deep inside the lower-S_c success region (decision >= margin) are
    labelled success without a simulation."""

    def known(X):
        mask = model.decision_function(np.asarray(X, dtype=float)) >= margin
        return mask, np.ones(len(X), dtype=bool)

    return known


def _initial_design(rng: np.random.Generator, config: ActiveConfig, qs: List[np.ndarray]) -> np.ndarray:
    """The first samples: the nominal pose, a stratified (Latin hypercube) design over the domain and
    points from the focus Gaussian and from each query distribution."""
    fs, ff = config.focus_scale, config.focus_fraction
    n_g = int(round(ff * (config.n_init - 1)))
    n = config.n_init - 1 - n_g
    n_q = min(config.query_init, n_g // max(len(qs), 1))  # taken from the focus share
    n_g -= n_q * len(qs)
    lhs = (np.stack([rng.permutation(n) for _ in range(3)], 1) + rng.uniform(size=(n, 3))) / n
    Q0 = [np.clip(rng.standard_normal((n_q, 3)) * sg, -1, 1) for sg in qs]
    return np.vstack([np.zeros((1, 3)), 2 * lhs - 1, sample_focus(rng, n_g, fs, 1.0), *Q0])


def _next_batch(
    rng: np.random.Generator,
    config: ActiveConfig,
    k: int,
    w: float,
    model,
    cal,
    gp,
    rho_se,
    qs: List[np.ndarray],
    X: np.ndarray,
    y: np.ndarray,
) -> np.ndarray:
    """A batch of k poses to label: a share w exploits (where rho is uncertain, the band of the
    calibration, then the SVM's boundary), the rest explores."""
    n_exploit = int(round(w * k))
    Pq = np.zeros((0, 3))
    if gp is not None:
        Pq = exploit_gp(
            rng, gp, qs, rho_se, X, int(round((config.rho_share + config.band_share) * n_exploit)), config.n_candidates
        )
    elif cal is not None:
        Pq = exploit_rho(rng, cal, qs, rho_se, X, int(round(config.rho_share * n_exploit)), config.n_candidates)
        Pb = exploit_band(
            rng, cal, qs, np.vstack([X, Pq]), int(round(config.band_share * n_exploit)), config.n_candidates
        )
        Pq = np.vstack([Pq, Pb])
    Pe = exploit(rng, model, np.vstack([X, Pq]), y, n_exploit - len(Pq), config.n_candidates, query_sigmas=qs)
    Pe = np.vstack([Pq, Pe])
    Pr = explore(
        rng,
        np.vstack([X, Pe]) if len(Pe) else X,
        k - len(Pe),
        config.n_candidates,
        config.focus_scale,
        config.focus_fraction,
        qs,
        config.query_fraction,
    )
    return np.vstack([Pe, Pr])


def _adapted_weight(w: float, acc: float, prev_acc: float, config: ActiveConfig) -> float:
    """The exploit share: up a step when the accuracy rose, down when it fell."""
    if acc > prev_acc:
        return min(w + config.weight_step, config.weight_bounds[1])
    if acc < prev_acc:
        return max(w - config.weight_step, config.weight_bounds[0])
    return w


class _RhoEstimator:
    """The stopping rule's rho estimates (each query distribution's rho and its standard error), from a
    Gaussian process (``RhoModel.gp``) or the SVM's calibration; keeps what the next batch reads."""

    def __init__(self, config: ActiveConfig, seed: int, qs: List[np.ndarray]):
        self.config, self.seed, self.qs = config, seed, qs
        self.queries = [gaussian_queries(config.n_rho_queries, seed + 1) * sg for sg in qs]
        self.use_gp = RhoModel.parse(config.rho_model, "rho_model") is RhoModel.gp
        self.gp_config = GPConfig(restarts=0, n_se_queries=config.gp_se_queries)
        self.cal, self.gp, self.gp_theta = None, None, None

    def estimate(self, rnd: int, XA: np.ndarray, yA: np.ndarray, simA: np.ndarray, params) -> Optional[np.ndarray]:
        """(queries, 2) rho and standard error after round ``rnd``, or None before ``min_rounds`` or
        while one class is missing."""
        c = self.config
        if rnd + 1 < c.min_rounds or not yA.any() or yA.all():
            return None
        if self.use_gp:
            theta = None if self.gp_theta is None or rnd % c.select_every == 0 else self.gp_theta
            self.gp = GPSuccessModel(XA, yA, theta=theta, seed=self.seed, config=self.gp_config)
            self.gp_theta = self.gp.theta
            return np.array([self.gp.rho(Q, self.seed) for Q in self.queries])
        self.cal = calibrate(
            XA,
            yA,
            simA,
            lambda A, b: fit_svm(A, b, *params),
            c.calib_folds,
            self.seed,
            local_kappa=c.local_kappa,
            local_floor=c.local_floor,
        )
        return np.array([self.cal.rho(Q, sg) for Q, sg in zip(self.queries, self.qs)])


def learn_boundary(
    label_fn: Callable[[np.ndarray], np.ndarray],
    config: ActiveConfig = ActiveConfig(),
    seed: int = 0,
    known_fn: Optional[KnownFn] = None,
) -> BoundaryResult:
    """Actively learn a GSB. label_fn maps normalized poses (n, 3) to bool successes."""
    if config.budget < config.n_init + config.n_holdout + 1:
        raise ValueError(f"budget {config.budget} must exceed n_init + n_holdout ({config.n_init + config.n_holdout})")
    rng = np.random.default_rng(seed)
    n_sims = 0

    def query(P):
        nonlocal n_sims
        labels = np.zeros(len(P), dtype=bool)
        known = np.zeros(len(P), dtype=bool)
        if known_fn is not None and len(P):
            known, kl = known_fn(P)
            labels[known] = kl[known]
        todo = ~known
        if todo.any():
            labels[todo] = np.asarray(label_fn(P[todo]), dtype=bool)
            n_sims += int(todo.sum())
        return labels, todo

    qs = [np.asarray(sg, float) for sg in config.query_sigmas]
    X = _initial_design(rng, config, qs)
    y, sim = query(X)
    H = sample_focus(rng, config.n_holdout, config.focus_scale, config.focus_fraction)
    yh, simh = query(H)
    rho = _RhoEstimator(config, seed, qs)
    params = (config.svm_c, config.svm_gamma, np.eye(3))

    def refit(rnd):
        nonlocal params
        if rnd % config.select_every == 0:
            params = (
                select_svm_params(
                    X, y, config.c_grid, config.gamma_grid, seed, config.calib_folds, sim, config.metric_powers
                )
                or params
            )
        return fit_svm(X, y, *params)

    model = refit(0)
    w = config.exploit_weight
    prev_acc = balanced_accuracy(predict(model, H), yh)
    history, streak, converged, prev_rho, rho_se = [], 0, False, None, None
    max_rounds = 4 * config.budget // config.batch_size  # free labels do not spend budget
    for rnd in range(max_rounds):
        k = min(config.batch_size, config.budget - n_sims)
        if k <= 0:
            break
        P = _next_batch(rng, config, k, w, model, rho.cal, rho.gp, rho_se, qs, X, y)
        before = predict(model, P)
        yp, simp = query(P)
        X, y, sim = np.vstack([X, P]), np.concatenate([y, yp]), np.concatenate([sim, simp])
        model = refit(rnd + 1)
        acc_hold = balanced_accuracy(predict(model, H), yh)
        acc_batch = float(np.mean(before == yp))
        acc = 0.5 * (acc_hold + acc_batch)
        w, prev_acc = _adapted_weight(w, acc, prev_acc, config), acc
        h = {
            "round": rnd,
            "n_simulations": n_sims,
            "n_samples": len(X),
            "accuracy_holdout": acc_hold,
            "accuracy_batch": acc_batch,
            "exploit_weight": w,
        }
        # The stopping rule judges the GSB of every sample, held-out ones included (the
        # returned one; the final hyperparameter re-selection may still change it).
        est = rho.estimate(rnd, np.vstack([X, H]), np.concatenate([y, yh]), np.concatenate([sim, simh]), params)
        ok = False
        if est is not None:
            change = None if prev_rho is None else float(np.abs(est[:, 0] - prev_rho).max())
            prev_rho, rho_se = est[:, 0], est[:, 1]
            h.update(rho=est[:, 0].tolist(), rho_se=est[:, 1].tolist(), rho_change=change)
            ok = bool(change is not None and est[:, 1].max() <= config.se_target and change <= config.rho_tol)
        history.append(h)
        streak = streak + 1 if ok else 0
        if streak >= config.patience:
            converged = True
            break
    # The final GSB uses every labelled sample, held-out ones included.
    X, y, sim = np.vstack([X, H]), np.concatenate([y, yh]), np.concatenate([sim, simh])
    model = refit(0)
    return BoundaryResult(
        X=X,
        y=y,
        simulated=sim,
        model=model,
        n_simulations=n_sims,
        converged=converged,
        history=history,
        svm_c=params[0],
        svm_gamma=params[1],
        svm_metric=params[2],
    )


def learn_random(label_fn, n_samples: int, config: ActiveConfig = ActiveConfig(), seed: int = 0) -> BoundaryResult:
    """Baseline: uniform random samples, same classifier, same budget."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.0, 1.0, size=(n_samples, 3))
    y = np.asarray(label_fn(X), dtype=bool)
    params = select_svm_params(X, y, config.c_grid, config.gamma_grid, seed, metric_powers=config.metric_powers)
    params = params or (config.svm_c, config.svm_gamma, np.eye(3))
    model = fit_svm(X, y, *params)
    return BoundaryResult(
        X=X,
        y=y,
        simulated=np.ones(n_samples, dtype=bool),
        model=model,
        n_simulations=n_samples,
        converged=False,
        svm_c=params[0],
        svm_gamma=params[1],
        svm_metric=params[2],
    )
