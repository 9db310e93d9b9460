"""RBF SVM with a learned linear metric for the GSB classifiers.

The simulated success regions of the thin (high S_g, low S_c) pairs are slabs: long along
the approach axis x and thin across a diagonal of (y, phi) (a lateral offset and a yaw
compensate each other; the success samples' y-phi correlation is 0.7-0.9 there). An
isotropic RBF kernel wide enough for the long axis smears the thin one. The kernel here is
exp(-gamma |L (u - v)|^2) with L = Sigma^(-alpha / 2) / det(...)^(1/3), Sigma the covariance
of the successful samples: alpha = 0 is the isotropic kernel, alpha = 1 whitens the success
region; the determinant is normalized to 1 so that gamma keeps its meaning. alpha is chosen
with (C, gamma) by out-of-fold likelihood (active.select_svm_params).
"""

from __future__ import annotations

import numpy as np
from sklearn.svm import SVC


class Constant:
    """Stand-in classifier while only one label has been seen."""

    def __init__(self, label: bool):
        self.label = bool(label)
        self.support_ = np.zeros(0, dtype=int)

    def decision_function(self, X):
        return np.full(len(X), 1.0 if self.label else -1.0)


class MetricSVC:
    """RBF SVC trained on z = u L^T; decision_function takes normalized poses u."""

    def __init__(self, X, y, c: float, gamma: float, metric=None):
        self.metric = np.eye(3) if metric is None else np.asarray(metric, float).reshape(3, 3)
        self.svc = SVC(kernel="rbf", C=c, gamma=gamma, class_weight="balanced")
        self.svc.fit(np.asarray(X, float) @ self.metric.T, np.asarray(y, bool).astype(int))

    @property
    def support_(self):
        return self.svc.support_

    def decision_function(self, X):
        return self.svc.decision_function(np.asarray(X, float).reshape(-1, 3) @ self.metric.T)

    def value_and_gradient(self, U):
        """f(u) and grad_u f for normalized poses U (n, 3)."""
        m = self.svc
        gamma = float(m._gamma)
        d = (U @ self.metric.T)[:, None, :] - m.support_vectors_[None, :, :]
        K = np.exp(-gamma * np.einsum("nmk,nmk->nm", d, d)) * m.dual_coef_[0]
        f = K.sum(axis=1) + m.intercept_[0]
        grad = (-2.0 * gamma * np.einsum("nm,nmk->nk", K, d)) @ self.metric
        return f, grad


def fit_svm(X, y, c: float, gamma: float, metric=None):
    """RBF SVC on success labels (decision > 0 means success) in the metric L (identity by
    default); deterministic."""
    y = np.asarray(y, dtype=bool)
    if y.all() or (~y).all():
        return Constant(y[0] if len(y) else False)
    return MetricSVC(X, y, c, gamma, metric)


def success_metric(X, y, alpha: float) -> np.ndarray:
    """L = Sigma^(-alpha/2) with determinant 1, Sigma the covariance of the successful
    samples (identity for alpha = 0 or fewer than 6 successes)."""
    S = np.asarray(X, float)[np.asarray(y, bool)]
    if alpha == 0 or len(S) < 6:
        return np.eye(3)
    ev, V = np.linalg.eigh(np.cov(S.T) + 1e-6 * np.eye(3))
    s = ev ** (-0.5 * alpha)
    s /= np.exp(np.mean(np.log(s)))
    return (V * s) @ V.T
