"""Calibrated success probability of a GSB and its Monte-Carlo rho (Sec. IV-B, made robust
to label noise).

The simulation labels are noisy near the boundary (seeded friction jitter), so a hard
"success depth SD >= D_FT" rule is biased one way or the other depending on how D_FT is
picked. Here the probability of success of a pose is a logistic function of its success depth,

    p(u) = 1 / (1 + exp(-(SD(u) - D_FT) / w)),

with SD the first-order (one Newton step) signed distance f / |grad f| of the SVM decision
function f, D_FT the depth at which success becomes as likely as failure and w the width of
the noisy band. D_FT and w are fitted by maximum likelihood to *out-of-fold* depths of the
simulated samples (k-fold: each sample's depth under a classifier that did not see it), so
they include the classifier's own boundary error, not only the label noise.

The noise band is not the same along the whole boundary: the active learner puts its samples
where labels conflict, which is where the band is widest, so one global (D_FT, w) smears the
probability where the query Gaussians have their mass (too pessimistic when rho is high, too
optimistic when it is low). For a query sigma, (D_FT, w) are therefore refitted with the
samples weighted by the density of N(0, (local_kappa sigma)^2) plus a uniform floor
(`local_floor`, the global fit's share), i.e. the band is measured where rho is decided.

rho for a pose uncertainty sigma is the mean of p over poses from N(0, sigma) (outside the
modelled domain: 0). The k fold classifiers give a delete-a-group jackknife standard error
of rho (boundary uncertainty from the finite sample); the conservative estimate is
rho_hat - z * se.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from sklearn.model_selection import StratifiedKFold

DEPTH_CLIP = 2.0  # normalized units; beyond this p is 0 or 1 anyway
WIDTH_BOUNDS = (0.003, 0.5)


def svm_depth(model, U, chunk: int = 2048) -> np.ndarray:
    """Signed success depth f(u) / |grad_u f(u)| of a kernel.MetricSVC (or a constant
    stand-in) at the normalized poses U (n, 3), clipped to +-DEPTH_CLIP: > 0 inside the
    success region. The gradient is taken in the normalized pose space, whatever the
    kernel's metric, so depths of different metrics are comparable."""
    U = np.asarray(U, dtype=float).reshape(-1, 3)
    if not hasattr(model, "value_and_gradient"):
        label = bool(model.decision_function(U[:1])[0] > 0) if len(U) else False
        return np.full(len(U), DEPTH_CLIP if label else -DEPTH_CLIP)
    out = np.empty(len(U))
    for a in range(0, len(U), chunk):
        f, grad = model.value_and_gradient(U[a:a + chunk])
        g = np.linalg.norm(grad, axis=1)
        out[a:a + chunk] = np.clip(f / np.maximum(g, 1e-12), -DEPTH_CLIP, DEPTH_CLIP)
    return out


def _sigmoid(t):
    return 0.5 * (1.0 + np.tanh(0.5 * t))


def _nll_terms(depth, y, d_ft, width) -> np.ndarray:
    t = (depth - d_ft) / width
    # -log sigmoid(t) = logaddexp(0, -t)
    return np.where(y, np.logaddexp(0, -t), np.logaddexp(0, t))


def fit_depth_sigmoid(depth, y, weights=None) -> tuple:
    """(Weighted) maximum-likelihood (D_FT, w, mean negative log-likelihood) of
    P(success | depth) = sigmoid((depth - D_FT) / w)."""
    depth, y = np.asarray(depth, float), np.asarray(y, bool)
    if y.all() or (~y).all():
        return (-DEPTH_CLIP if y.all() else DEPTH_CLIP), WIDTH_BOUNDS[0], 0.0
    wt = np.ones(len(y)) if weights is None else np.asarray(weights, float)
    wt = wt / wt.mean()

    def nll(th):
        return float(np.sum(wt * _nll_terms(depth, y, th[0], np.exp(th[1]))))

    lo, hi = np.log(WIDTH_BOUNDS[0]), np.log(WIDTH_BOUNDS[1])
    best = None
    for w0 in (0.01, 0.05):  # two starts: the likelihood is flat when classes barely mix
        r = minimize(nll, [0.0, np.log(w0)], method="L-BFGS-B",
                     bounds=[(-DEPTH_CLIP, DEPTH_CLIP), (lo, hi)])
        if best is None or r.fun < best.fun:
            best = r
    return float(best.x[0]), float(np.exp(best.x[1])), float(best.fun) / len(y)


@dataclass
class Calibration:
    """The full-data classifier, its k fold classifiers, the out-of-fold depths and the
    global (D_FT, w) fit; `band(sigma)` gives the one local to a query sigma."""

    model: object
    fold_models: list
    d_ft: float
    width: float
    nll: float  # mean out-of-fold negative log-likelihood of all labels (free ones included)
    X: np.ndarray = None  # samples, their out-of-fold depths, labels and simulated mask
    depth: np.ndarray = None
    y: np.ndarray = None
    simulated: np.ndarray = None
    local_kappa: float = 3.0  # 0: the global (D_FT, w) for every sigma
    local_floor: float = 1.0
    _bands: dict = field(default_factory=dict, repr=False)

    def band(self, sigma=None) -> tuple:
        """(D_FT, w) for queries from N(0, sigma) (normalized (x, y, phi) standard
        deviations): the likelihood fit with each simulated sample weighted by
        exp(-|u / (kappa sigma)|^2 / 2) / sum + floor / n."""
        if sigma is None or self.local_kappa <= 0 or self.depth is None:
            return self.d_ft, self.width
        key = tuple(float(v) for v in np.broadcast_to(np.asarray(sigma, float), 3))
        if key not in self._bands:
            X, sim = self.X[self.simulated], self.simulated
            w = np.exp(-0.5 * ((X / (self.local_kappa * np.asarray(key))) ** 2).sum(axis=1))
            w = w / max(w.sum(), 1e-300) + self.local_floor / len(w)
            self._bands[key] = fit_depth_sigmoid(self.depth[sim], self.y[sim], w)[:2]
        return self._bands[key]

    def probability(self, U, model=None, sigma=None) -> np.ndarray:
        """P(success) of normalized poses U (band local to sigma if given); poses outside
        [-1, 1]^3 get 0."""
        U = np.asarray(U, float).reshape(-1, 3)
        ok = np.all(np.abs(U) <= 1.0, axis=1)
        p = np.zeros(len(U))
        if ok.any():
            d_ft, width = self.band(sigma)
            sd = svm_depth(self.model if model is None else model, U[ok])
            p[ok] = _sigmoid((sd - d_ft) / width)
        return p

    def rho(self, U, sigma=None) -> tuple:
        """(rho_hat, jackknife standard error) for the Monte-Carlo poses U ~ N(0, sigma)."""
        rho_hat = float(self.probability(U, sigma=sigma).mean())
        if not self.fold_models:
            return rho_hat, 0.0
        r = np.array([self.probability(U, m, sigma).mean() for m in self.fold_models])
        k = len(r)
        return rho_hat, float(np.sqrt((k - 1) / k * np.sum((r - r.mean()) ** 2)))


def calibrate(X, y, simulated, fit, folds: int = 5, seed: int = 0,
              fit_full: bool = True, local_kappa: float = 3.0,
              local_floor: float = 1.0) -> Calibration:
    """Fit the full classifier fit(X, y) (unless fit_full is False: hyperparameter
    selection only needs the likelihood) and k fold classifiers; fit (D_FT, w) to the
    out-of-fold depths of the simulated samples (free labels are deep successes by
    construction and say nothing about the noise). The likelihood `nll` scores every label,
    free ones included: a kernel that loses the deep interior of the success region is
    wrong there even though no simulation was spent on it."""
    X, y = np.asarray(X, float), np.asarray(y, bool)
    simulated = np.asarray(simulated, bool)
    model = fit(X, y) if fit_full else None
    n_min = int(min(y.sum(), (~y).sum()))
    if n_min < 2:
        model = fit(X, y) if model is None else model
        return Calibration(model, [], *fit_depth_sigmoid(svm_depth(model, X[simulated]),
                                                         y[simulated]))
    k = min(folds, n_min)
    cv = StratifiedKFold(n_splits=k, shuffle=True, random_state=seed)
    depth = np.empty(len(X))
    fold_models = []
    for tr, te in cv.split(X, y):
        m = fit(X[tr], y[tr])
        fold_models.append(m)
        depth[te] = svm_depth(m, X[te])
    d_ft, width, _ = fit_depth_sigmoid(depth[simulated], y[simulated])
    nll = float(np.mean(_nll_terms(depth, y, d_ft, width)))
    return Calibration(model, fold_models, d_ft, width, nll, X, depth, y, simulated,
                       local_kappa, local_floor)


def gaussian_queries(n: int, seed: int = 0) -> np.ndarray:
    """Standard normal draws (n, 3), scaled per sigma by the caller (common random numbers
    across speeds and sigma levels)."""
    return np.random.default_rng(seed).standard_normal((n, 3))
