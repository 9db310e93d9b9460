"""Kernel metric, local noise band and query-by-committee sampling of the rho estimator."""

import numpy as np
import pytest
from sklearn.svm import SVC

from pickplan.pickup.metamodel.active import select_svm_params
from pickplan.pickup.metamodel.sampling import exploit_band, exploit_rho
from pickplan.pickup.metamodel.calibration import calibrate, svm_depth
from pickplan.pickup.metamodel.kernel import fit_svm, success_metric


def _slab(n, seed):
    """Thin slab across the (y, phi) diagonal, long in x: the shape of the high-S_g GSBs."""
    X = np.random.default_rng(seed).uniform(-1, 1, (n, 3))
    return X, np.abs(X[:, 1] - X[:, 2]) / np.sqrt(2) < 0.08


def test_identity_metric_is_the_plain_rbf_svc():
    X, y = _slab(300, 0)
    m = fit_svm(X, y, 100.0, 3.0)
    ref = SVC(kernel="rbf", C=100.0, gamma=3.0, class_weight="balanced").fit(X, y.astype(int))
    U = np.random.default_rng(1).uniform(-1, 1, (200, 3))
    np.testing.assert_allclose(m.decision_function(U), ref.decision_function(U), atol=1e-9)


def test_success_metric_whitens_with_unit_determinant():
    X, y = _slab(2000, 2)
    assert np.allclose(success_metric(X, y, 0.0), np.eye(3))
    L = success_metric(X, y, 1.0)
    assert np.linalg.det(L) == pytest.approx(1.0, rel=1e-9)
    np.testing.assert_allclose(L, L.T)
    # The thin direction (y - phi) is stretched most.
    w, V = np.linalg.eigh(L)
    thin = np.array([0.0, 1.0, -1.0]) / np.sqrt(2)
    assert abs(V[:, -1] @ thin) > 0.95


def test_depth_gradient_is_in_pose_space_for_any_metric():
    """f / |grad_u f| with the chain rule through L: matches finite differences of f."""
    X, y = _slab(400, 3)
    m = fit_svm(X, y, 100.0, 3.0, success_metric(X, y, 1.0))
    U = np.random.default_rng(4).uniform(-0.5, 0.5, (20, 3))
    f, g = m.value_and_gradient(U)
    np.testing.assert_allclose(f, m.decision_function(U), atol=1e-9)
    h = 1e-6
    fd = np.stack(
        [(m.decision_function(U + h * e) - m.decision_function(U - h * e)) / (2 * h) for e in np.eye(3)], axis=1
    )
    np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(svm_depth(m, U), np.clip(f / np.linalg.norm(g, axis=1), -2, 2), atol=1e-12)


def test_selection_prefers_the_whitened_metric_on_a_thin_slab():
    X, y = _slab(300, 5)
    c, gamma, L = select_svm_params(X, y, (100.0,), (1.0, 3.0, 10.0), metric_powers=(0.0, 1.0))
    assert not np.allclose(L, np.eye(3))


def test_local_band_follows_the_local_noise():
    """Label noise wide near x = -0.8 and sharp near x = 0: the band local to a small
    Gaussian at the origin is narrower than the global one."""
    rng = np.random.default_rng(6)
    X = rng.uniform(-1, 1, (800, 3))
    r = np.linalg.norm(X[:, 1:], axis=1)
    width = np.where(X[:, 0] < -0.4, 0.15, 0.01)
    y = rng.uniform(size=len(X)) < 1 / (1 + np.exp(-(0.4 - r) / width))
    cal = calibrate(X, y, np.ones(len(y), bool), lambda A, b: fit_svm(A, b, 100.0, 3.0))
    d_loc, w_loc = cal.band((0.1, 0.1, 0.1))
    assert w_loc < cal.width
    assert cal.band(None) == (cal.d_ft, cal.width)


def test_exploit_rho_samples_inside_the_query_gaussians_where_folds_disagree():
    X, y = _slab(300, 7)
    cal = calibrate(X, y, np.ones(len(y), bool), lambda A, b: fit_svm(A, b, 100.0, 3.0))
    sigmas = [(0.04, 0.04, 0.08), (0.24, 0.24, 0.25)]
    P = exploit_rho(np.random.default_rng(0), cal, sigmas, [0.0, 0.05], X, 10, 2000)
    assert P.shape == (10, 3)
    # Allocation follows the jackknife se: all from the wide level, near its boundary.
    assert np.all(np.abs(P) <= 1.0)
    assert np.max(np.abs(P / np.asarray(sigmas[1])).max(axis=1)) < 5
    spread = lambda Q: np.std([cal.probability(Q, m, sigmas[1]) for m in cal.fold_models], 0)
    R = np.clip(np.random.default_rng(1).standard_normal((2000, 3)) * sigmas[1], -1, 1)
    assert spread(P).mean() > 3 * spread(R).mean()
    P2 = exploit_rho(np.random.default_rng(0), cal, sigmas, [0.0, 0.05], X, 10, 2000)
    np.testing.assert_array_equal(P, P2)  # deterministic by seed


def test_exploit_band_samples_each_gaussians_stretch_of_the_boundary():
    """Half-space boundary x = 0.03 through a small Gaussian (rho undecided there) and a
    wide one: picks lie on the boundary, inside their Gaussian, spaced, and the small
    Gaussian gets its share although its region is a few millimetres wide."""
    rng = np.random.default_rng(8)
    X = np.clip(np.vstack([rng.uniform(-1, 1, (200, 3)), rng.normal(0, 0.1, (100, 3))]), -1, 1)
    y = X[:, 0] < 0.03
    cal = calibrate(X, y, np.ones(len(y), bool), lambda A, b: fit_svm(A, b, 100.0, 3.0))
    small, wide = np.array([0.04, 0.04, 0.08]), np.array([0.24, 0.24, 0.25])
    P = exploit_band(np.random.default_rng(0), cal, [small, wide], X, 12, 2000)
    assert 6 <= len(P) <= 12
    p = cal.probability(P)
    assert np.all(p * (1 - p) > 0.05)  # undecided: on the boundary band
    in_small = np.all(np.abs(P / small) < 4, axis=1)
    assert in_small.sum() >= 2
    d = np.sqrt((((P[:, None] - P[None]) / wide) ** 2).sum(-1)) + np.eye(len(P))
    assert d[~in_small][:, ~in_small].min() >= 0.5 - 1e-9
    np.testing.assert_array_equal(P, exploit_band(np.random.default_rng(0), cal, [small, wide], X, 12, 2000))
    assert len(exploit_band(np.random.default_rng(0), None, [small], X, 5, 100)) == 0
