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
from typing import Callable, Optional

import numpy as np

from pickplan.pickup.metamodel.calibration import calibrate, gaussian_queries
from pickplan.pickup.metamodel.gpc import GPConfig, GPSuccessModel
from pickplan.pickup.metamodel.kernel import fit_svm, success_metric


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
    rho_model: str = "svm"
    gp_se_queries: int = 500


def select_svm_params(X, y, c_grid, gamma_grid, seed: int = 0, folds: int = 5,
                      simulated=None, metric_powers=(0.0,)):
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
                cal = calibrate(X, y, sim, lambda A, b: fit_svm(A, b, c, gamma, L), folds,
                                seed, fit_full=False)
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


def _nearest_dist(P, X) -> np.ndarray:
    if len(X) == 0:
        return np.full(len(P), np.inf)
    d2 = ((P[:, None, :] - X[None, :, :]) ** 2).sum(-1)
    return np.sqrt(d2.min(axis=1))


def _greedy_farthest(cands, existing, k) -> np.ndarray:
    """Pick k candidates one by one, each farthest from existing + already picked points."""
    if k <= 0 or len(cands) == 0:
        return np.zeros((0, 3))
    d = _nearest_dist(cands, existing)
    picked = []
    for _ in range(min(k, len(cands))):
        i = int(np.argmax(d))
        picked.append(cands[i])
        d = np.minimum(d, np.sqrt(((cands - cands[i]) ** 2).sum(-1)))
    return np.asarray(picked)


def sample_focus(rng, n, focus_scale, focus_fraction) -> np.ndarray:
    """Mixture of N(0, focus_scale^2) (clipped to the domain) and uniform points."""
    n_f = int(round(focus_fraction * n))
    g = np.clip(rng.normal(0.0, focus_scale, size=(n_f, 3)), -1.0, 1.0)
    u = rng.uniform(-1.0, 1.0, size=(n - n_f, 3))
    return np.vstack([g, u])


def explore(rng, X, k, n_candidates, focus_scale=0.25, focus_fraction=0.0, query_sigmas=(),
            query_fraction=0.0) -> np.ndarray:
    """Random samples biased toward regions with few samples (farthest-point selection
    among random candidates drawn from the focus mixture). A share query_fraction of them
    comes from the query Gaussians N(0, query_sigma), farthest-point in that Gaussian's own
    scale: the interior of a success region is rarely sampled otherwise, and an RBF
    classifier falls back to its bias (failure) in unsampled space."""
    picked = []
    n_q = int(round(query_fraction * k)) if len(query_sigmas) else 0
    for i, sig in enumerate(query_sigmas):
        k_i = n_q // len(query_sigmas) + (i < n_q % len(query_sigmas))
        sig = np.asarray(sig, dtype=float)
        cands = np.clip(rng.standard_normal((max(n_candidates // 4, k_i), 3)) * sig, -1.0, 1.0)
        existing = np.vstack([X, *picked]) if picked else X
        picked.append(_greedy_farthest(cands / sig, existing / sig, k_i).reshape(-1, 3) * sig)
    cands = sample_focus(rng, max(n_candidates, k), focus_scale, focus_fraction)
    existing = np.vstack([X, *picked]) if picked else X
    picked.append(_greedy_farthest(cands, existing, k - n_q).reshape(-1, 3))
    return np.vstack(picked)


def exploit(rng, model, X, y, k, n_candidates, min_spacing: float = 0.02,
            query_sigmas=()) -> np.ndarray:
    """Midpoints of pairs of support vectors with opposite labels (each SV with its nearest
    opposite SV). Shortest pairs first, since they straddle the boundary most tightly; with
    query_sigmas, the length is divided by (0.05 + the largest unnormalized query-Gaussian
    density at the midpoint), so the boundary where rho is decided comes first;
    midpoints closer than min_spacing to a sample are skipped; jittered midpoints (spread
    ~ a quarter of the pair length) fill up when there are too few."""
    if k <= 0:
        return np.zeros((0, 3))
    sv = np.asarray(getattr(model, "support_", []), dtype=int)
    pos, neg = sv[y[sv]], sv[~y[sv]]
    if len(pos) == 0 or len(neg) == 0:
        return explore(rng, X, k, n_candidates, 0.25, 0.5)
    P, N = X[pos], X[neg]
    d2 = ((P[:, None, :] - N[None, :, :]) ** 2).sum(-1)
    pairs = {(i, int(np.argmin(d2[i]))) for i in range(len(P))}
    pairs |= {(int(np.argmin(d2[:, j])), j) for j in range(len(N))}
    pairs = sorted(pairs)
    mids = np.array([(P[i] + N[j]) / 2 for i, j in pairs])
    key = np.sqrt(np.array([d2[ij] for ij in pairs]))
    if len(query_sigmas):
        dens = np.max([np.exp(-0.5 * ((mids / np.asarray(sg)) ** 2).sum(1))
                       for sg in query_sigmas], axis=0)
        key = key / (0.05 + dens)
    order = np.argsort(key, kind="stable")
    pairs, mids = [pairs[o] for o in order], mids[order]
    lens = np.sqrt(np.array([d2[ij] for ij in pairs]))
    picked = []
    existing = X
    for m in mids:
        if _nearest_dist(m[None], existing)[0] >= min_spacing:
            picked.append(m)
            existing = np.vstack([existing, m])
            if len(picked) == k:
                return np.asarray(picked)
    need = k - len(picked)
    src = rng.integers(0, len(mids), size=need)
    jit = mids[src] + rng.normal(size=(need, 3)) * (0.25 * lens[src] + 0.01)[:, None]
    return np.vstack([np.asarray(picked).reshape(-1, 3), np.clip(jit, -1.0, 1.0)])


def _allocate(k: int, weights) -> np.ndarray:
    """k samples split across the query levels in proportion to weights (+ 1e-3, so a
    settled level still gets a share), remainders to the largest weights."""
    w = np.asarray(weights, float) + 1e-3
    alloc = np.floor(k * w / w.sum()).astype(int)
    for i in np.argsort(-w, kind="stable")[:k - alloc.sum()]:
        alloc[i] += 1
    return alloc


def _pick_spaced(C, score, sg, existing, k, min_spacing, keep_zero=False) -> list:
    """Greedy, best score first: up to k candidates C, no two picks (or a pick and an
    existing sample) closer than min_spacing in the Gaussian's sigma units sg; stops at a
    non-positive score (a zero score is still taken with keep_zero)."""
    score = np.array(score, float)
    score[_nearest_dist(C / sg, existing / sg) < min_spacing] = -1.0
    picked = []
    for _ in range(k):
        i = int(np.argmax(score))
        if score[i] < 0 or (score[i] == 0 and not keep_zero):
            break
        picked.append(C[i][None])
        score[np.sqrt((((C - C[i]) / sg) ** 2).sum(axis=1)) < min_spacing] = -1.0
    return picked


def _candidates(rng, sg, n) -> np.ndarray:
    return np.clip(rng.standard_normal((n, 3)) * sg, -1.0, 1.0)


def exploit_rho(rng, cal, query_sigmas, se, X, k, n_candidates,
                min_spacing: float = 0.5) -> np.ndarray:
    """Query-by-committee for rho: candidates from each query Gaussian N(0, sigma), scored by
    the spread (standard deviation) of P(success) over the k fold classifiers of the
    calibration, i.e. by their share of rho's jackknife variance; the levels get samples in
    proportion to their jackknife se. Greedy: best score first, no two picks (or a pick and
    an existing sample) closer than min_spacing in that Gaussian's sigma units. The SV
    midpoints refine the boundary everywhere; these refine it where rho is undecided."""
    if k <= 0 or not cal.fold_models or not len(query_sigmas):
        return np.zeros((0, 3))
    picked = []
    for sg, k_l in zip(query_sigmas, _allocate(k, se)):
        if k_l <= 0:
            continue
        sg = np.asarray(sg, float)
        C = _candidates(rng, sg, max(n_candidates // 2, k_l))
        score = np.std([cal.probability(C, m, sg) for m in cal.fold_models], axis=0)
        picked += _pick_spaced(C, score, sg, np.vstack([X, *picked]), k_l, min_spacing,
                               keep_zero=True)
    return np.vstack(picked) if picked else np.zeros((0, 3))


def exploit_band(rng, cal, query_sigmas, X, k, n_candidates,
                 min_spacing: float = 0.5) -> np.ndarray:
    """Uncertainty sampling weighted by each query Gaussian: candidates from N(0, sigma),
    scored by p (1 - p) of the calibrated success probability, so the picks lie on the
    stretch of the GSB that carries that Gaussian's mass. A small sigma's Gaussian covers a
    region a few millimetres wide where rho moves by tens of percent per millimetre of
    boundary shift; the boundary-wide exploitation rarely lands there. The levels get
    samples in proportion to their band mass E[p (1 - p)]; greedy picks as in exploit_rho."""
    if k <= 0 or cal is None or not len(query_sigmas):
        return np.zeros((0, 3))
    sigmas = [np.asarray(sg, float) for sg in query_sigmas]
    cands = [_candidates(rng, sg, max(n_candidates // 2, k)) for sg in sigmas]
    scores = []
    for sg, C in zip(sigmas, cands):
        p = cal.probability(C, sigma=sg)
        scores.append(p * (1.0 - p))
    picked = []
    for sg, C, score, k_l in zip(sigmas, cands, scores,
                                 _allocate(k, [s.mean() for s in scores])):
        if k_l > 0:
            picked += _pick_spaced(C, score, sg, np.vstack([X, *picked]), k_l, min_spacing)
    return np.vstack(picked) if picked else np.zeros((0, 3))


def exploit_gp(rng, gp, query_sigmas, se, X, k, n_candidates,
               min_spacing: float = 0.5) -> np.ndarray:
    """Samples where rho is undecided on the GP (gpc.GPSuccessModel): candidates from each
    query Gaussian N(0, sigma), scored by the posterior variance of P(success), so they land
    on the stretch of the boundary that carries the Gaussian's mass and is least pinned
    down. The levels get samples in proportion to their rho posterior standard deviation;
    greedy picks as in exploit_rho."""
    if k <= 0 or gp is None or gp.constant is not None or not len(query_sigmas):
        return np.zeros((0, 3))
    picked = []
    for sg, k_l in zip(query_sigmas, _allocate(k, se)):
        if k_l <= 0:
            continue
        sg = np.asarray(sg, float)
        C = _candidates(rng, sg, max(n_candidates // 2, k_l))
        picked += _pick_spaced(C, gp.probability_variance(C), sg, np.vstack([X, *picked]),
                               k_l, min_spacing)
    return np.vstack(picked) if picked else np.zeros((0, 3))


KnownFn = Callable[[np.ndarray], tuple]


def known_from_lower_sc(model, margin: float) -> KnownFn:
    """Monotonicity in S_c (Sec. IV): a grasp that succeeds at some S_c also succeeds at a
    higher S_c. Points deep inside the lower-S_c success region (decision >= margin) are
    labelled success without a simulation."""

    def known(X):
        mask = model.decision_function(np.asarray(X, dtype=float)) >= margin
        return mask, np.ones(len(X), dtype=bool)

    return known


def learn_boundary(label_fn: Callable[[np.ndarray], np.ndarray], config: ActiveConfig = ActiveConfig(),
                   seed: int = 0, known_fn: Optional[KnownFn] = None) -> BoundaryResult:
    """Actively learn a GSB. label_fn maps normalized poses (n, 3) to bool successes."""
    if config.budget < config.n_init + config.n_holdout + 1:
        raise ValueError(f"budget {config.budget} must exceed n_init + n_holdout "
                         f"({config.n_init + config.n_holdout})")
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

    fs, ff = config.focus_scale, config.focus_fraction
    # Initial samples: the nominal pose, a stratified (Latin hypercube) design over the
    # domain and points from the focus Gaussian.
    qs = [np.asarray(sg, float) for sg in config.query_sigmas]
    n_g = int(round(ff * (config.n_init - 1)))
    n = config.n_init - 1 - n_g
    n_q = min(config.query_init, n_g // max(len(qs), 1))  # taken from the focus share
    n_g -= n_q * len(qs)
    lhs = (np.stack([rng.permutation(n) for _ in range(3)], 1) + rng.uniform(size=(n, 3))) / n
    Q0 = [np.clip(rng.standard_normal((n_q, 3)) * sg, -1, 1) for sg in qs]
    X = np.vstack([np.zeros((1, 3)), 2 * lhs - 1, sample_focus(rng, n_g, fs, 1.0), *Q0])
    y, sim = query(X)
    H = sample_focus(rng, config.n_holdout, fs, ff)
    yh, simh = query(H)
    Z = gaussian_queries(config.n_rho_queries, seed + 1)
    queries = [Z * sg for sg in qs]
    params = (config.svm_c, config.svm_gamma, np.eye(3))

    def refit(rnd):
        nonlocal params
        if rnd % config.select_every == 0:
            params = select_svm_params(X, y, config.c_grid, config.gamma_grid, seed,
                                       config.calib_folds, sim, config.metric_powers) or params
        return fit_svm(X, y, *params)

    model = refit(0)
    w = config.exploit_weight
    prev_acc = balanced_accuracy(predict(model, H), yh)
    history, streak, converged, prev_rho = [], 0, False, None
    cal, rho_se = None, None  # the latest calibration, for exploit_rho
    if config.rho_model not in ("svm", "gp"):
        raise ValueError(f"rho_model must be 'svm' or 'gp', got {config.rho_model!r}")
    use_gp, gp, gp_theta = config.rho_model == "gp", None, None
    gp_config = GPConfig(restarts=0, n_se_queries=config.gp_se_queries)
    max_rounds = 4 * config.budget // config.batch_size  # free labels do not spend budget
    for rnd in range(max_rounds):
        k = min(config.batch_size, config.budget - n_sims)
        if k <= 0:
            break
        n_exploit = int(round(w * k))
        Pq = np.zeros((0, 3))
        if gp is not None:
            Pq = exploit_gp(rng, gp, qs, rho_se, X,
                            int(round((config.rho_share + config.band_share) * n_exploit)),
                            config.n_candidates)
        elif cal is not None:
            Pq = exploit_rho(rng, cal, qs, rho_se, X, int(round(config.rho_share * n_exploit)),
                             config.n_candidates)
            Pb = exploit_band(rng, cal, qs, np.vstack([X, Pq]),
                              int(round(config.band_share * n_exploit)), config.n_candidates)
            Pq = np.vstack([Pq, Pb])
        Pe = exploit(rng, model, np.vstack([X, Pq]), y, n_exploit - len(Pq),
                     config.n_candidates, query_sigmas=qs)
        Pe = np.vstack([Pq, Pe])
        Pr = explore(rng, np.vstack([X, Pe]) if len(Pe) else X, k - len(Pe),
                     config.n_candidates, fs, ff, qs, config.query_fraction)
        P = np.vstack([Pe, Pr])
        before = predict(model, P)
        yp, simp = query(P)
        X, y, sim = np.vstack([X, P]), np.concatenate([y, yp]), np.concatenate([sim, simp])
        model = refit(rnd + 1)
        acc_hold = balanced_accuracy(predict(model, H), yh)
        acc_batch = float(np.mean(before == yp))
        acc = 0.5 * (acc_hold + acc_batch)
        if acc > prev_acc:
            w = min(w + config.weight_step, config.weight_bounds[1])
        elif acc < prev_acc:
            w = max(w - config.weight_step, config.weight_bounds[0])
        prev_acc = acc
        h = {"round": rnd, "n_simulations": n_sims, "n_samples": len(X),
             "accuracy_holdout": acc_hold, "accuracy_batch": acc_batch, "exploit_weight": w}
        ok, est = False, None
        # The stopping rule judges the GSB of every sample, held-out ones included (the
        # returned one; the final hyperparameter re-selection may still change it).
        XA, yA, simA = np.vstack([X, H]), np.concatenate([y, yh]), np.concatenate([sim, simh])
        if rnd + 1 >= config.min_rounds and yA.any() and (~yA).any() and use_gp:
            gp = GPSuccessModel(XA, yA, theta=None if gp_theta is None or rnd % config.select_every == 0
                                else gp_theta, seed=seed, config=gp_config)
            gp_theta = gp.theta
            est = np.array([gp.rho(Q, seed) for Q in queries])
        elif rnd + 1 >= config.min_rounds and yA.any() and (~yA).any():
            cal = calibrate(XA, yA, simA, lambda A, b: fit_svm(A, b, *params),
                            config.calib_folds, seed, local_kappa=config.local_kappa,
                            local_floor=config.local_floor)
            est = np.array([cal.rho(Q, sg) for Q, sg in zip(queries, qs)])
        if est is not None:
            change = None if prev_rho is None else float(np.abs(est[:, 0] - prev_rho).max())
            prev_rho, rho_se = est[:, 0], est[:, 1]
            h.update(rho=est[:, 0].tolist(), rho_se=est[:, 1].tolist(), rho_change=change)
            ok = bool(change is not None and est[:, 1].max() <= config.se_target
                      and change <= config.rho_tol)
        history.append(h)
        streak = streak + 1 if ok else 0
        if streak >= config.patience:
            converged = True
            break
    # The final GSB uses every labelled sample, held-out ones included.
    X, y, sim = np.vstack([X, H]), np.concatenate([y, yh]), np.concatenate([sim, simh])
    model = refit(0)
    return BoundaryResult(X=X, y=y, simulated=sim, model=model, n_simulations=n_sims,
                          converged=converged, history=history, svm_c=params[0],
                          svm_gamma=params[1], svm_metric=params[2])


def learn_random(label_fn, n_samples: int, config: ActiveConfig = ActiveConfig(),
                 seed: int = 0) -> BoundaryResult:
    """Baseline: uniform random samples, same classifier, same budget."""
    rng = np.random.default_rng(seed)
    X = rng.uniform(-1.0, 1.0, size=(n_samples, 3))
    y = np.asarray(label_fn(X), dtype=bool)
    params = select_svm_params(X, y, config.c_grid, config.gamma_grid, seed,
                               metric_powers=config.metric_powers)
    params = params or (config.svm_c, config.svm_gamma, np.eye(3))
    model = fit_svm(X, y, *params)
    return BoundaryResult(X=X, y=y, simulated=np.ones(n_samples, dtype=bool), model=model,
                          n_simulations=n_samples, converged=False, svm_c=params[0],
                          svm_gamma=params[1], svm_metric=params[2])
