"""GP classification for rho (pickup/gpc.py) against closed forms and exact oracles."""

import math

import numpy as np
import pytest

from pickplan.pickup.metamodel.sampling import exploit_gp
from pickplan.pickup.metamodel.gpc import CONFIDENT, GPSuccessModel, lapse_rate
from pickplan.pickup.metamodel.model import BoundaryModel
from pickplan.pickup.metamodel.synthetic import NoisyEllipsoidOracle


def _half_space_samples(n, a, seed, width=0.03, s=0.1, lapse=0.0):
    """Success with probability (1 - lapse) sigmoid((a - x) / width) (normalized units),
    like the simulation's nearly deterministic boundary and its rare failures that no pose
    explains. As the active learner places them: a quarter of the samples uniform, a
    quarter from the query Gaussian N(0, s^2), the rest near the boundary."""
    rng = np.random.default_rng(seed)
    k = n // 4
    X = np.vstack(
        [
            rng.uniform(-1, 1, (k, 3)),
            rng.normal(0, s, (k, 3)),
            np.column_stack([a + rng.normal(0, 0.15, n - 2 * k), rng.uniform(-1, 1, (n - 2 * k, 2))]),
        ]
    )
    X = np.clip(X, -1, 1)
    p = (1 - lapse) / (1 + np.exp(-(a - X[:, 0]) / width))
    return X, rng.uniform(size=n) < p


def _rho_truth(a, s, width=0.03):
    """E[sigmoid((a - x) / width)] for x ~ N(0, s^2), by quadrature (the y and phi offsets
    do not matter and s is well inside the domain)."""
    x = np.linspace(-8 * s, 8 * s, 20001)
    pdf = np.exp(-0.5 * (x / s) ** 2) / (s * math.sqrt(2 * math.pi))
    f = pdf / (1 + np.exp(-(a - x) / width))
    return float(np.sum(0.5 * (f[1:] + f[:-1]) * np.diff(x)))


@pytest.mark.parametrize("a, s", [(0.1, 0.2), (-0.15, 0.25), (0.3, 0.15), (0.05, 0.04)])
def test_rho_of_a_noisy_half_space_matches_quadrature(a, s):
    X, y = _half_space_samples(300, a, seed=1, s=s)
    gp = GPSuccessModel(X, y, seed=0)
    U = np.random.default_rng(2).standard_normal((20000, 3)) * s
    rho, se = gp.rho(U)
    truth = _rho_truth(a, s)
    assert abs(rho - truth) < 0.04
    assert abs(rho - truth) < 3 * se + 0.01
    assert 0 < se < 0.05


def test_posterior_spread_shrinks_with_more_labels():
    U = np.random.default_rng(2).standard_normal((5000, 3)) * 0.2
    ses = []
    for n in (40, 400):
        X, y = _half_space_samples(n, 0.1, seed=3)
        ses.append(GPSuccessModel(X, y, seed=0).rho(U)[1])
    assert ses[1] < 0.5 * ses[0]


def test_saved_hyperparameters_reproduce_the_probabilities():
    X, y = _half_space_samples(200, 0.0, seed=4)
    gp = GPSuccessModel(X, y, seed=0)
    again = GPSuccessModel(X, y, theta=gp.theta)
    U = np.random.default_rng(5).uniform(-1, 1, (500, 3))
    np.testing.assert_allclose(again.probability(U), gp.probability(U), atol=1e-12)
    assert set(gp.hyperparameters) == {"amplitude", "length_scales"}
    # x decides, y and phi do not: their length scales come out much longer
    ls = gp.hyperparameters["length_scales"]
    assert ls[0] < ls[1] and ls[0] < ls[2]


def test_outside_the_domain_is_failure_and_one_class_is_constant():
    X, y = _half_space_samples(100, 0.0, seed=6)
    gp = GPSuccessModel(X, y, seed=0)
    assert gp.probability(np.array([[-1.5, 0, 0], [0, 2, 0]])).tolist() == [0.0, 0.0]
    ones = GPSuccessModel(X, np.ones(len(X), bool))
    assert ones.constant is True and ones.theta is None
    assert ones.probability(np.array([[0.0, 0, 0], [3.0, 0, 0]])).tolist() == [1.0, 0.0]
    assert ones.rho(np.zeros((10, 3))) == (1.0, 0.0)


def test_probability_variance_peaks_on_the_boundary():
    X, y = _half_space_samples(300, 0.0, seed=7)
    gp = GPSuccessModel(X, y, seed=0)
    on, inside, outside = gp.probability_variance(np.array([[0.0, 0, 0], [-0.6, 0, 0], [0.6, 0, 0]]))
    assert on > 10 * inside and on > 10 * outside


def test_exploit_gp_samples_the_undecided_stretch_inside_each_gaussian():
    X, y = _half_space_samples(300, 0.05, seed=8)
    gp = GPSuccessModel(X, y, seed=0)
    sigmas = [np.array([0.04, 0.04, 0.08]), np.array([0.2, 0.2, 0.25])]
    P = exploit_gp(np.random.default_rng(0), gp, sigmas, [0.01, 0.03], X, 8, 2000)
    assert len(P) == 8
    # near the boundary x = 0.05, and well inside the wider Gaussian
    assert np.all(np.abs(P[:, 0] - 0.05) < 0.15)
    assert np.all(np.abs(P) <= 1.0)
    assert len(exploit_gp(np.random.default_rng(0), gp, sigmas, [0.01, 0.03], X, 0, 2000)) == 0


def test_boundary_model_gp_rho_tracks_a_noisy_oracle_and_round_trips():
    oracle = NoisyEllipsoidOracle(0.3, 0.1, width=0.05, seed=0)
    rng = np.random.default_rng(9)
    X = np.clip(np.vstack([rng.uniform(-1, 1, (150, 3)), rng.normal(0, 0.25, (150, 3))]), -1, 1)
    y = oracle(X)
    bm = BoundaryModel(0.3, 0.1, X, y, np.ones(len(X), bool), 100.0, 3.0, rho_model="gp")
    sig = np.array([0.14, 0.14, 1 / 6])
    U = np.random.default_rng(10).standard_normal((20000, 3)) * sig
    rho, se = bm.rho(U, sig)
    truth = oracle.probability(0.007, math.radians(10))
    assert abs(rho - truth) < max(0.05, 3 * se)
    again = BoundaryModel.from_dict(bm.to_dict())
    assert again.rho_model == "gp"
    assert again.rho(U, sig) == pytest.approx((rho, se), abs=1e-9)
    with pytest.raises(ValueError, match="rho_model"):
        BoundaryModel(0.3, 0.1, X, y, np.ones(len(X), bool), 100.0, 3.0, rho_model="mlp")


@pytest.mark.parametrize("lapse", [0.0, 0.05])
def test_lapse_rate_recovers_the_failures_no_pose_explains(lapse):
    """Pooled over two boundaries, the share of confidently-successful simulated samples
    that failed is the oracle's lapse, within 3 binomial standard errors; free (not
    simulated) samples do not count."""
    fits, n_confident = [], 0
    for seed, a in ((11, 0.3), (12, 0.1)):
        X, y = _half_space_samples(400, a, seed=seed, lapse=lapse)
        gp = GPSuccessModel(X, y, seed=0)
        simulated = np.arange(len(X)) % 4 != 0
        fits.append((gp, simulated))
        n_confident += int(((gp.probability(X) >= CONFIDENT) & simulated).sum())
    assert n_confident > 200
    est = lapse_rate(fits)
    assert abs(est - lapse) <= 3 * math.sqrt(max(lapse, 0.01) / n_confident) + 1 / n_confident
    # Free samples are successes by construction: counting them would dilute the rate.
    with_free = lapse_rate([(gp, np.ones(len(gp.X), bool)) for gp, _ in fits])
    assert with_free != est


def test_rho_caps_each_probability_at_the_ceiling():
    X, y = _half_space_samples(300, 0.3, seed=13)
    gp = GPSuccessModel(X, y, seed=0)
    U = np.random.default_rng(14).standard_normal((5000, 3)) * 0.1
    p = gp.probability(U)
    assert p.max() > 0.99  # deep inside the success region
    rho, se = gp.rho(U, ceiling=0.97)
    assert rho == pytest.approx(np.minimum(p, 0.97).mean(), abs=1e-12)
    assert rho <= 0.97 and se >= 0
    assert gp.rho(U, ceiling=1.0)[0] == pytest.approx(p.mean(), abs=1e-12)


def test_learning_loop_can_stop_and_sample_on_the_gp_posterior():
    """ActiveConfig(rho_model="gp"): the stopping rule and the rho-directed samples use the
    GP; rho estimates and their posterior errors are recorded per round, the budget holds."""
    from pickplan.pickup.metamodel.active import ActiveConfig, learn_boundary

    oracle = NoisyEllipsoidOracle(0.3, 0.15, width=0.1, seed=0)
    res = learn_boundary(oracle, ActiveConfig(budget=150, rho_model="gp"), seed=0)
    assert res.n_simulations <= 150
    rounds = [h for h in res.history if "rho" in h]
    assert rounds and all(len(h["rho"]) == 3 and all(0 <= s < 0.5 for s in h["rho_se"]) for h in rounds)
    truth = oracle.probability(0.012, math.radians(15))
    assert abs(rounds[-1]["rho"][2] - truth) < 0.1
    with pytest.raises(ValueError, match="rho_model"):
        learn_boundary(oracle, ActiveConfig(budget=150, rho_model="tree"), seed=0)
