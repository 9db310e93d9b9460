"""Meta-model on the synthetic oracle (exact truth): rho bounds, monotonicity, gradient,
conservatism vs the true probability, save / load, bad input."""

import math
import os

import numpy as np
import pytest

from pickplan.pickup.metamodel.active import ActiveConfig
from pickplan.pickup.metamodel.build import build_metamodel
from pickplan.pickup.metamodel.model import DEFAULT_LEVELS, BuildConfig, MetaModel
from pickplan.pickup.metamodel.synthetic import EllipsoidOracle, oracle_factory

CFG = BuildConfig(
    sg_grid=(0.1, 0.3, 0.5),
    sc_grid=(0.05, 0.15),
    active=ActiveConfig(n_init=20, n_holdout=20, batch_size=15, budget=90, select_every=100),
    n_queries=6000,
    surface_degree=(2, 1),
    rho_model="svm",
)  # the GP: test_pickup_rho.py


@pytest.fixture(scope="module")
def model():
    return build_metamodel("box", CFG, seed=0, label_fn_factory=oracle_factory)


def test_rho_in_unit_interval_and_monotone(model):
    sg = np.linspace(0.1, 0.5, 21)
    sc = np.linspace(0.05, 0.15, 11)
    G, C = np.meshgrid(sg, sc, indexing="ij")
    for lv in model.levels:
        R = model.rho(G, C, lv.sigma_r, lv.sigma_phi)
        assert R.min() >= 0.0 and R.max() <= 1.0
        assert np.all(np.diff(R, axis=0) <= 1e-9)  # non-increasing in S_g
    # The high-uncertainty level is never more likely to succeed than the low one.
    lo, hi = DEFAULT_LEVELS[0], DEFAULT_LEVELS[2]
    assert np.all(model.rho(G, C, hi.sigma_r, hi.sigma_phi) <= model.rho(G, C, lo.sigma_r, lo.sigma_phi) + 1e-9)


def test_rho_near_truth_and_surface_below_grid(model):
    """At only 90 labels per boundary rho is coarse (the issue's accuracy target is asserted
    at the real budget on a noisy oracle in test_pickup_rho.py); it must still be in the
    right range, and the fitted surface is a lower bound of the grid."""
    errors = []
    for lv in model.levels:
        for (i, j), bm in model.boundaries.items():
            truth = EllipsoidOracle(bm.s_g, bm.s_c).probability(lv.sigma_r, lv.sigma_phi)
            got = model.rho_grids[lv.name][i, j]
            errors.append(got - truth)
            assert model.rho(bm.s_g, bm.s_c, lv.sigma_r, lv.sigma_phi) <= got + 1e-9
    assert np.mean(np.abs(errors)) < 0.1
    assert -0.35 < min(errors) and max(errors) < 0.1, errors


def test_gradient_matches_finite_differences(model):
    lv = DEFAULT_LEVELS[1]
    h = 1e-6
    for sg, sc in [(0.2, 0.08), (0.37, 0.12)]:
        g = model.rho_gradient(sg, sc, lv.sigma_r, lv.sigma_phi)
        f = lambda a, b: model.rho(a, b, lv.sigma_r, lv.sigma_phi)
        fd = [(f(sg + h, sc) - f(sg - h, sc)) / (2 * h), (f(sg, sc + h) - f(sg, sc - h)) / (2 * h)]
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7)
    assert model.rho_gradient(0.3, 0.1, lv.sigma_r, lv.sigma_phi)[0] < 0


def test_success_depth_sign_and_dft(model):
    bm = model.boundaries[(1, 0)]
    oracle = EllipsoidOracle(bm.s_g, bm.s_c)
    U = np.random.default_rng(3).uniform(-1, 1, (2000, 3))
    sd = bm.success_depth(U)
    far = np.abs(sd) > 0.05  # away from the boundary the sign is the truth
    assert np.mean((sd[far] > 0) == oracle(U[far])) > 0.99
    assert -0.1 < bm.d_ft < 0.1 and 0.0 < bm.width < 0.2


def test_save_load_roundtrip_and_new_sigma(model, tmp_path):
    path = tmp_path / "mm.json"
    model.save(path)
    assert [p.name for p in tmp_path.iterdir()] == ["mm.json"]  # no temp file left behind
    loaded = MetaModel.load(path)
    for lv in model.levels:
        assert loaded.rho(0.27, 0.11, lv.sigma_r, lv.sigma_phi) == model.rho(0.27, 0.11, lv.sigma_r, lv.sigma_phi)
    # A sigma that was not built is computed from the saved boundaries.
    r_mid = loaded.rho(0.3, 0.1, 0.005, math.radians(8))
    lo, hi = DEFAULT_LEVELS[0], DEFAULT_LEVELS[2]
    assert (
        loaded.rho(0.3, 0.1, hi.sigma_r, hi.sigma_phi) - 0.02
        <= r_mid
        <= loaded.rho(0.3, 0.1, lo.sigma_r, lo.sigma_phi) + 0.02
    )


def test_bad_input(model, tmp_path):
    with pytest.raises(ValueError, match="sigma_r"):
        model.rho(0.3, 0.1, 0.0, 0.1)
    with pytest.raises(ValueError, match="sigma_phi"):
        model.rho(0.3, 0.1, 0.01, -1.0)
    lv = DEFAULT_LEVELS[0]
    with pytest.raises(ValueError, match="S_g"):
        model.rho(0.8, 0.1, lv.sigma_r, lv.sigma_phi)
    with pytest.raises(ValueError, match="S_c"):
        model.rho_gradient(0.3, 0.3, lv.sigma_r, lv.sigma_phi)
    missing = tmp_path / "nope.json"
    with pytest.raises(FileNotFoundError, match="nope.json"):
        MetaModel.load(missing)
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(ValueError, match="meta-model"):
        MetaModel.load(bad)
    assert not os.path.exists(missing)


def test_closing_speed_monotonicity_follows_the_part(tmp_path):
    """Free labels from the lower-S_c boundary and an S_c-monotone surface only for parts whose
    success is monotone in the closing speed (Part.closing_monotone)."""
    from dataclasses import replace as dc_replace

    from pickplan.pickup.metamodel.parts import get_part

    cfg = BuildConfig(
        sg_grid=(0.1, 0.5),
        sc_grid=(0.05, 0.1, 0.15),
        n_queries=3000,
        surface_degree=(1, 2),
        active=ActiveConfig(n_init=20, n_holdout=20, batch_size=15, budget=60, select_every=100),
    )
    assert get_part("box").closing_monotone and not get_part("cylinder").closing_monotone
    mono = build_metamodel("box", cfg, seed=1, label_fn_factory=oracle_factory)
    free = build_metamodel(
        dc_replace(get_part("box"), closing_monotone=False), cfg, seed=1, label_fn_factory=oracle_factory
    )
    assert sum((~bm.simulated).sum() for bm in mono.boundaries.values()) > 0
    assert all(bm.simulated.all() for bm in free.boundaries.values())  # every label simulated
    assert mono.monotone_sc and not free.monotone_sc
    free.save(tmp_path / "m.json")
    assert not MetaModel.load(tmp_path / "m.json").monotone_sc
