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
from scipy.special import expit
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
        f, grad = model.value_and_gradient(U[a : a + chunk])
        g = np.linalg.norm(grad, axis=1)
        out[a : a + chunk] = np.clip(f / np.maximum(g, 1e-12), -DEPTH_CLIP, DEPTH_CLIP)
    return out


def _sigmoid(t):
    return 0.5 * (1.0 + np.tanh(0.5 * t))


def _nll_terms(depth, y, d_ft, width) -> np.ndarray:
    t = (depth - d_ft) / width
    # -log sigmoid(t) = logaddexp(0, -t)
    return np.where(y, np.logaddexp(0, -t), np.logaddexp(0, t))


def _nll_ab(a: float, b: float, depth, sign, wt) -> tuple:
    """Weighted negative log-likelihood of P(success) = sigmoid(a depth + b) (sign +1 for a success,
    -1 for a failure), its gradient and Hessian in (a, b): convex, where (D_FT, w) is not."""
    m = sign * (a * depth + b)
    q = expit(-m)  # accurate far in the tails, where 1 - tanh rounds to 0 and the gradient vanishes
    r, h = wt * q * sign, wt * q * (1.0 - q)
    hd = h * depth
    return (
        float(np.sum(wt * np.logaddexp(0.0, -m))),
        -np.array([np.sum(r * depth), np.sum(r)]),
        np.array([[np.sum(hd * depth), np.sum(hd)], [np.sum(hd), np.sum(h)]]),
    )


def _newton_interior(nll, p, iterations: int = 100):
    """Damped Newton (Armijo backtracking) from p: (value, point) at convergence, None when the
    minimum runs to infinity (classes separated: the likelihood only grows as the band narrows)."""
    f, g, H = nll(p)
    for _ in range(iterations):
        try:
            step = -np.linalg.solve(H, g)
        except np.linalg.LinAlgError:
            return None
        t = 1.0
        while True:
            fn, gn, Hn = nll(p + t * step)
            if fn <= f + 1e-4 * t * (g @ step) or t < 1e-10:
                break
            t *= 0.5
        p, f, g, H = p + t * step, fn, gn, Hn
        if abs(g @ step) < 1e-12 * max(1.0, abs(f)):
            return f, p
    return None


def _segment_min(nll, p0, p1, iterations: int = 60) -> tuple:
    """(value, point) minimizing the convex nll on the segment p0-p1 (1-D Newton kept in [0, 1])."""
    d, lam = p1 - p0, 0.5
    f, g, H = nll(p0 + lam * d)
    for _ in range(iterations):
        slope, curv = g @ d, d @ H @ d
        new = min(max(lam - slope / curv if curv > 0 else lam - np.sign(slope), 0.0), 1.0)
        while True:
            fn, gn, Hn = nll(p0 + new * d)
            if fn <= f or abs(new - lam) < 1e-12:
                break
            new = 0.5 * (lam + new)
        done = abs(new - lam) < 1e-10
        lam, f, g, H = new, fn, gn, Hn
        if done:
            break
    return f, p0 + lam * d


def fit_depth_sigmoid(depth, y, weights=None) -> tuple:
    """(Weighted) maximum-likelihood (D_FT, w, mean negative log-likelihood) of
    P(success | depth) = sigmoid((depth - D_FT) / w), |D_FT| <= DEPTH_CLIP, w in WIDTH_BOUNDS.

    Solved as the logistic regression sigmoid(a depth + b), a = 1 / w, b = -D_FT / w, whose
    likelihood is convex on a convex polygon (the bounds): the interior Newton minimum if it lies
    inside, else the best minimum on the polygon's four edges. Separated classes give the
    narrowest band centred in their gap."""
    depth, y = np.asarray(depth, float), np.asarray(y, bool)
    if y.all() or (~y).all():
        return (-DEPTH_CLIP if y.all() else DEPTH_CLIP), WIDTH_BOUNDS[0], 0.0
    wt = np.ones(len(y)) if weights is None else np.asarray(weights, float)
    wt = wt / wt.mean()
    sign = np.where(y, 1.0, -1.0)

    def nll(p):
        return _nll_ab(p[0], p[1], depth, sign, wt)

    a_lo, a_hi, c = 1.0 / WIDTH_BOUNDS[1], 1.0 / WIDTH_BOUNDS[0], DEPTH_CLIP
    corners = [np.array(v) for v in ((a_lo, -c * a_lo), (a_lo, c * a_lo), (a_hi, c * a_hi), (a_hi, -c * a_hi))]
    candidates = [_segment_min(nll, corners[i], corners[(i + 1) % 4]) for i in range(4)]
    inner = _newton_interior(nll, np.array([1.0 / 0.05, 0.0]))
    if inner is not None and a_lo <= inner[1][0] <= a_hi and abs(inner[1][1]) <= c * inner[1][0]:
        candidates.append(inner)
    f, (a, b) = min(candidates, key=lambda cand: cand[0])
    return float(-b / a), float(1.0 / a), f / len(y)


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


def calibrate(
    X,
    y,
    simulated,
    fit,
    folds: int = 5,
    seed: int = 0,
    fit_full: bool = True,
    local_kappa: float = 3.0,
    local_floor: float = 1.0,
) -> Calibration:
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
        return Calibration(model, [], *fit_depth_sigmoid(svm_depth(model, X[simulated]), y[simulated]))
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
    return Calibration(model, fold_models, d_ft, width, nll, X, depth, y, simulated, local_kappa, local_floor)


def gaussian_queries(n: int, seed: int = 0) -> np.ndarray:
    """Standard normal draws (n, 3), scaled per sigma by the caller (common random numbers
    across speeds and sigma levels)."""
    return np.random.default_rng(seed).standard_normal((n, 3))
