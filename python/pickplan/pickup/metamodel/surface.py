"""The analytic success-probability surface rho_sigma(S_g, S_c) (Sec. IV-B).

A tensor-product Bernstein polynomial on the modelled speed box. Its Bernstein coefficients
are fitted by least squares under linear constraints that make the surface
  * a lower bound of the grid probabilities (conservative, as in the paper),
  * non-increasing in S_g (the physics: a faster approach is harder) and, for parts where the
    physics has it (``Part.closing_monotone``), non-decreasing in S_c (faster closing is easier);
    this holds everywhere because a Bernstein polynomial with monotone coefficients is monotone,
  * inside [0, 1] everywhere (Bernstein coefficients in [0, 1] give a convex combination).
The gradient is analytic, for the trajectory NLP.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import comb

import numpy as np
from scipy.optimize import minimize


def _bernstein(t: np.ndarray, n: int) -> np.ndarray:
    """Bernstein basis B_k^n(t), shape (len(t), n + 1)."""
    t = np.asarray(t, dtype=float)[:, None]
    k = np.arange(n + 1)[None, :]
    c = np.array([comb(n, i) for i in range(n + 1)], dtype=float)[None, :]
    return c * t**k * (1.0 - t) ** (n - k)


def _bernstein_deriv(t: np.ndarray, n: int) -> np.ndarray:
    """d/dt of the basis as a matrix mapping coefficients to the derivative."""
    if n == 0:
        return np.zeros((len(np.atleast_1d(t)), 1))
    b = _bernstein(t, n - 1)  # (m, n)
    d = np.zeros((b.shape[0], n + 1))
    d[:, 1:] += n * b
    d[:, :-1] -= n * b
    return d


@dataclass
class RhoSurface:
    """rho(S_g, S_c) = sum_ij coeffs[i, j] B_i(u) B_j(v), u, v the speeds scaled to [0, 1].
    Speeds outside [sg_range] x [sc_range] raise ValueError (no extrapolation)."""

    coeffs: np.ndarray  # (deg_g + 1, deg_c + 1)
    sg_range: tuple
    sc_range: tuple

    def _uv(self, s_g, s_c):
        s_g, s_c = np.broadcast_arrays(np.asarray(s_g, float), np.asarray(s_c, float))
        for name, s, (lo, hi) in (("S_g", s_g, self.sg_range), ("S_c", s_c, self.sc_range)):
            if not np.all(np.isfinite(s)):
                raise ValueError(f"{name} must be finite")
            if np.any(s < lo - 1e-12) or np.any(s > hi + 1e-12):
                raise ValueError(f"{name}={s.ravel().tolist()} outside the modelled range [{lo}, {hi}] m/s")
        u = (s_g - self.sg_range[0]) / (self.sg_range[1] - self.sg_range[0])
        v = (s_c - self.sc_range[0]) / (self.sc_range[1] - self.sc_range[0])
        return np.clip(u, 0, 1), np.clip(v, 0, 1)

    def __call__(self, s_g, s_c):
        """Success probability; scalar in, float out; arrays broadcast."""
        u, v = self._uv(s_g, s_c)
        m, n = np.array(self.coeffs.shape) - 1
        bu, bv = _bernstein(u.ravel(), m), _bernstein(v.ravel(), n)
        val = np.einsum("ki,ij,kj->k", bu, self.coeffs, bv).reshape(u.shape)
        return float(val) if val.ndim == 0 else val

    def gradient(self, s_g, s_c):
        """(d rho / d S_g, d rho / d S_c); scalars in, a length-2 array out."""
        u, v = self._uv(s_g, s_c)
        m, n = np.array(self.coeffs.shape) - 1
        uu, vv = u.ravel(), v.ravel()
        du = np.einsum("ki,ij,kj->k", _bernstein_deriv(uu, m), self.coeffs, _bernstein(vv, n))
        dv = np.einsum("ki,ij,kj->k", _bernstein(uu, m), self.coeffs, _bernstein_deriv(vv, n))
        du = du / (self.sg_range[1] - self.sg_range[0])
        dv = dv / (self.sc_range[1] - self.sc_range[0])
        g = np.stack([du.reshape(u.shape), dv.reshape(u.shape)])
        return g

    def to_dict(self) -> dict:
        return {"coeffs": self.coeffs.tolist(), "sg_range": list(self.sg_range), "sc_range": list(self.sc_range)}

    @classmethod
    def from_dict(cls, d: dict) -> "RhoSurface":
        c = np.asarray(d["coeffs"], dtype=float)
        if c.ndim != 2:
            raise ValueError(f"expected 2-D surface coefficients, got shape {c.shape}")
        return cls(c, tuple(d["sg_range"]), tuple(d["sc_range"]))


def fit_rho_surface(sg_grid, sc_grid, rho_grid, degree=(3, 2), monotone_sc: bool = True) -> RhoSurface:
    """Fit the conservative monotone surface to rho_grid[i, j] = rho(sg_grid[i], sc_grid[j]);
    monotone in S_c too only with monotone_sc."""
    sg, sc = np.asarray(sg_grid, float), np.asarray(sc_grid, float)
    r = np.asarray(rho_grid, float)
    if r.shape != (len(sg), len(sc)):
        raise ValueError(f"expected rho_grid of shape {(len(sg), len(sc))}, got {r.shape}")
    if len(sg) < 2 or len(sc) < 2:
        raise ValueError("need at least two speeds in each grid direction")
    if np.any(r < 0) or np.any(r > 1) or not np.all(np.isfinite(r)):
        raise ValueError("grid probabilities must lie in [0, 1]")
    m = min(degree[0], len(sg) - 1)
    n = min(degree[1], len(sc) - 1)
    sg_range, sc_range = (sg.min(), sg.max()), (sc.min(), sc.max())
    U, V = np.meshgrid((sg - sg_range[0]) / np.ptp(sg), (sc - sc_range[0]) / np.ptp(sc), indexing="ij")
    bu, bv = _bernstein(U.ravel(), m), _bernstein(V.ravel(), n)
    A = np.einsum("ki,kj->kij", bu, bv).reshape(len(U.ravel()), -1)  # point x coefficient
    b = r.ravel()
    nc = (m + 1) * (n + 1)
    idx = np.arange(nc).reshape(m + 1, n + 1)
    rows = []  # G c >= 0 rows: monotone in S_g (down) and, with monotone_sc, S_c (up)
    for i in range(m):
        for j in range(n + 1):
            g = np.zeros(nc)
            g[idx[i, j]], g[idx[i + 1, j]] = 1.0, -1.0
            rows.append(g)
    for i in range(m + 1 if monotone_sc else 0):
        for j in range(n):
            g = np.zeros(nc)
            g[idx[i, j + 1]], g[idx[i, j]] = 1.0, -1.0
            rows.append(g)
    G = np.array(rows) if rows else np.zeros((0, nc))
    cons = [{"type": "ineq", "fun": lambda c: b - A @ c, "jac": lambda c: -A}]
    if len(G):
        cons.append({"type": "ineq", "fun": lambda c: G @ c, "jac": lambda c: G})
    res = minimize(
        lambda c: 0.5 * np.sum((A @ c - b) ** 2),
        np.zeros(nc),
        jac=lambda c: A.T @ (A @ c - b),
        bounds=[(0.0, 1.0)] * nc,
        constraints=cons,
        method="SLSQP",
        options={"maxiter": 500, "ftol": 1e-12},
    )
    c = np.clip(res.x, 0.0, 1.0)
    # SLSQP meets constraints to ~1e-9; enforce the lower bound exactly by a final shift.
    excess = max(0.0, float(np.max(A @ c - b)))
    c = np.clip(c - excess, 0.0, 1.0)
    return RhoSurface(c.reshape(m + 1, n + 1), sg_range, sc_range)
