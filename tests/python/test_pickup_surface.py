"""The conservative monotone rho surface."""

import numpy as np
import pytest

from pickplan.pickup.metamodel.surface import RhoSurface, fit_rho_surface

SG = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
SC = np.array([0.05, 0.1, 0.15])


def _truth(sg, sc):
    return 1.0 / (1.0 + np.exp(12 * (sg - 0.2 - 1.5 * sc)))


def _noisy_grid(seed=0, noise=0.02):
    G, C = np.meshgrid(SG, SC, indexing="ij")
    rng = np.random.default_rng(seed)
    return np.clip(_truth(G, C) + rng.normal(0, noise, G.shape), 0, 1)


def test_lower_bound_monotone_and_in_unit_interval():
    r = _noisy_grid()
    s = fit_rho_surface(SG, SC, r)
    G, C = np.meshgrid(SG, SC, indexing="ij")
    assert np.all(s(G, C) <= r + 1e-9)  # conservative at every grid point
    assert np.max(r - s(G, C)) < 0.2  # but not uselessly so
    sg = np.linspace(0.1, 0.5, 41)
    sc = np.linspace(0.05, 0.15, 21)
    D = s(*np.meshgrid(sg, sc, indexing="ij"))
    assert D.min() >= 0 and D.max() <= 1
    assert np.all(np.diff(D, axis=0) <= 1e-12)  # non-increasing in S_g
    assert np.all(np.diff(D, axis=1) >= -1e-12)  # non-decreasing in S_c


def test_gradient_matches_finite_differences():
    s = fit_rho_surface(SG, SC, _noisy_grid(1))
    h = 1e-6
    for sg, sc in [(0.17, 0.07), (0.33, 0.12), (0.45, 0.09)]:
        g = s.gradient(sg, sc)
        fd = [(s(sg + h, sc) - s(sg - h, sc)) / (2 * h), (s(sg, sc + h) - s(sg, sc - h)) / (2 * h)]
        np.testing.assert_allclose(g, fd, rtol=1e-5, atol=1e-7)
    assert abs(s.gradient(0.3, 0.1)[0]) > 0.1  # a real slope, not a flat surface


def test_roundtrip_and_bad_input():
    s = fit_rho_surface(SG, SC, _noisy_grid(2))
    s2 = RhoSurface.from_dict(s.to_dict())
    assert s2(0.27, 0.11) == s(0.27, 0.11)
    with pytest.raises(ValueError, match="S_g"):
        s(0.6, 0.1)
    with pytest.raises(ValueError, match="S_c"):
        s.gradient(0.3, 0.01)
    with pytest.raises(ValueError, match="shape"):
        fit_rho_surface(SG, SC, np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"\[0, 1\]"):
        fit_rho_surface(SG, SC, np.full((5, 3), 1.5))


def test_without_sc_monotonicity_a_peaked_closing_speed_is_kept():
    # Success that peaks at the middle closing speed (as the cylinder's): forcing monotonicity in
    # S_c drags the whole surface down to the fast-closing column; without it the surface stays
    # a lower bound, monotone in S_g, and close to the grid.
    G, C = np.meshgrid(SG, SC, indexing="ij")
    r = np.clip(0.95 - 1.2 * (G - 0.1) ** 1.2 - 8.0 * (C - 0.1) ** 2 - 0.25 * (C > 0.12), 0, 1)
    forced = fit_rho_surface(SG, SC, r)
    free = fit_rho_surface(SG, SC, r, monotone_sc=False)
    assert np.all(free(G, C) <= r + 1e-9)
    gap_forced, gap_free = np.max(r - forced(G, C)), np.max(r - free(G, C))
    assert gap_forced > 0.2 and gap_free < 0.1
    D = free(*np.meshgrid(np.linspace(0.1, 0.5, 41), np.linspace(0.05, 0.15, 21), indexing="ij"))
    assert np.all(np.diff(D, axis=0) <= 1e-12) and D.min() >= 0 and D.max() <= 1
    assert np.any(np.diff(D, axis=1) < -1e-3)  # it does fall towards fast closing
