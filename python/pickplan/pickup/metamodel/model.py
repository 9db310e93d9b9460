"""Success-probability meta-model rho_sigma(S_g, S_c) (Sec. IV-B of Thakar et al.).

For each (S_g, S_c) on a grid, a GSB is learned actively (active.py) from simulations
(sim.py). The success depth SD of a pose is its (first-order) distance, in the normalized pose
space, from the GSB into the success region; D_FT and the width of the noisy band are fitted
to out-of-fold depths (calibration.py), and the SVM kernel has a metric learned from the
successful samples (kernel.py). The probability of success for a pose uncertainty sigma is
the mean P(success) of Monte-Carlo poses from N(0, sigma), minus z standard errors. By
default P(success) comes from Gaussian-process classification of the same labelled samples
(gpc.py, rho_model="gp"), whose posterior also gives the standard error; rho_model="svm"
uses the calibrated SVM depth and the jackknife of its fold classifiers instead. The grid
of probabilities is turned into a conservative analytic surface (surface.py), saved to
JSON with all samples.
"""

from __future__ import annotations

import json
import logging
import math
import os
from dataclasses import asdict, dataclass, field
from typing import Optional

import numpy as np

from pickplan.core.io import write_text
from pickplan.pickup.metamodel.active import ActiveConfig, PoseDomain, RhoModel, fit_svm
from pickplan.pickup.metamodel.calibration import calibrate, gaussian_queries, svm_depth
from pickplan.pickup.metamodel.gpc import GPConfig, GPSuccessModel
from pickplan.pickup.metamodel.sim import SimConfig
from pickplan.pickup.metamodel.surface import RhoSurface, fit_rho_surface

log = logging.getLogger(__name__)

FORMAT = "pickplan.pickup.metamodel"
VERSION = 5  # 2: calibrated probability (D_FT, width, jackknife), conservative_z;
# 3: kernel metric (svm_metric) and noise band local to each sigma (local_kappa, local_floor);
# 4: rho_model and gp_theta per boundary (GP classification for rho, gpc.py);
# 5: the part's lapse rate (gpc.lapse_rate; older files read as 0)
READABLE_VERSIONS = (2, 3, 4, 5)  # a version-2 file reads as the isotropic kernel


@dataclass(frozen=True)
class SigmaLevel:
    name: str
    sigma_r: float  # m, standard deviation in x and y
    sigma_phi: float  # rad


DEFAULT_LEVELS = (
    SigmaLevel("low", 0.002, math.radians(5)),
    SigmaLevel("medium", 0.007, math.radians(10)),
    SigmaLevel("high", 0.012, math.radians(15)),
)


def check_sigma(sigma_r: float, sigma_phi: float) -> None:
    for name, s in (("sigma_r", sigma_r), ("sigma_phi", sigma_phi)):
        if not (isinstance(s, (int, float, np.floating)) and math.isfinite(s) and s > 0):
            raise ValueError(f"{name} must be a finite number > 0, got {s!r}")


class BoundaryModel:
    """One GSB: the labelled samples, the SVM refitted from them and its calibration
    (calibration.py): D_FT (the success depth at which success and failure are equally
    likely), the width w of the noisy band and the fold classifiers for the jackknife."""

    def __init__(
        self,
        s_g,
        s_c,
        X,
        y,
        simulated,
        svm_c,
        svm_gamma,
        history=None,
        converged=False,
        calib_folds=5,
        calib_seed=0,
        svm_metric=None,
        local_kappa=3.0,
        local_floor=1.0,
        rho_model=RhoModel.svm,
        gp_theta=None,
    ):
        self.s_g, self.s_c = float(s_g), float(s_c)
        self.X = np.asarray(X, float).reshape(-1, 3)
        self.y = np.asarray(y, bool)
        self.simulated = np.asarray(simulated, bool)
        self.svm_c, self.svm_gamma = float(svm_c), float(svm_gamma)
        self.history = list(history or [])
        self.converged = bool(converged)
        self.svm_metric = np.eye(3) if svm_metric is None else np.asarray(svm_metric, float).reshape(3, 3)
        self.calib_folds, self.calib_seed = int(calib_folds), int(calib_seed)
        self.local_kappa, self.local_floor = float(local_kappa), float(local_floor)
        self.calibration = calibrate(
            self.X,
            self.y,
            self.simulated,
            lambda A, b: fit_svm(A, b, self.svm_c, self.svm_gamma, self.svm_metric),
            self.calib_folds,
            self.calib_seed,
            local_kappa=self.local_kappa,
            local_floor=self.local_floor,
        )
        self.model = self.calibration.model
        self.rho_model = rho_model = RhoModel.parse(rho_model, "rho_model")
        # rho_model "gp": P(success) and rho from GP classification of the same samples
        # (gpc.py); gp_theta reuses saved hyperparameters instead of optimizing them.
        self.gp = (
            GPSuccessModel(self.X, self.y, theta=gp_theta, seed=self.calib_seed, config=GPConfig(restarts=0))
            if rho_model is RhoModel.gp
            else None
        )

    @property
    def n_simulations(self) -> int:
        return int(self.simulated.sum())

    @property
    def d_ft(self) -> float:
        return self.calibration.d_ft

    @property
    def width(self) -> float:
        return self.calibration.width

    def decision(self, U) -> np.ndarray:
        return self.model.decision_function(np.asarray(U, float))

    def success_depth(self, U) -> np.ndarray:
        """Signed distance (first order) to the GSB in normalized pose space: > 0 inside
        the success region, < 0 in the failure region."""
        return svm_depth(self.model, U)

    def probability(self, U, sigma=None) -> np.ndarray:
        """Calibrated P(success) of normalized poses (0 outside the domain); with sigma
        (normalized standard deviations) the noise band local to that query Gaussian; with
        the GP rho model, the GP's predictive probability."""
        if self.gp is not None:
            return self.gp.probability(U)
        return self.calibration.probability(U, sigma=sigma)

    def rho(self, U, sigma=None, ceiling: float = 1.0) -> tuple:
        """(rho_hat, standard error) for the Monte-Carlo poses U ~ N(0, sigma); with the GP
        rho model each pose's probability is capped at ceiling (1 - the part's lapse rate)."""
        if self.gp is not None:
            return self.gp.rho(U, self.calib_seed, ceiling)
        return self.calibration.rho(U, sigma)

    def to_dict(self) -> dict:
        return {
            "s_g": self.s_g,
            "s_c": self.s_c,
            "X": self.X.tolist(),
            "y": self.y.astype(int).tolist(),
            "simulated": self.simulated.astype(int).tolist(),
            "svm_c": self.svm_c,
            "svm_gamma": self.svm_gamma,
            "d_ft": self.d_ft,
            "width": self.width,
            "converged": self.converged,
            "history": self.history,
            "calib_folds": self.calib_folds,
            "calib_seed": self.calib_seed,
            "svm_metric": self.svm_metric.tolist(),
            "local_kappa": self.local_kappa,
            "local_floor": self.local_floor,
            "rho_model": self.rho_model,
            "gp_theta": None if self.gp is None else self.gp.theta,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "BoundaryModel":
        return cls(
            d["s_g"],
            d["s_c"],
            d["X"],
            d["y"],
            d["simulated"],
            d["svm_c"],
            d["svm_gamma"],
            history=d.get("history"),
            converged=d.get("converged", False),
            calib_folds=d.get("calib_folds", 5),
            calib_seed=d.get("calib_seed", 0),
            svm_metric=d.get("svm_metric"),
            local_kappa=d.get("local_kappa", 0.0),
            local_floor=d.get("local_floor", 1.0),
            rho_model=d.get("rho_model", RhoModel.svm),
            gp_theta=d.get("gp_theta"),
        )


def success_probability(
    bm: BoundaryModel,
    sigma_r: float,
    sigma_phi: float,
    domain: PoseDomain = PoseDomain(),
    n_queries: int = 20000,
    seed: int = 0,
    z: float = 1.0,
    details: bool = False,
    lapse: float = 0.0,
):
    """Conservative P(success) for poses from N(0, diag(sigma_r, sigma_r, sigma_phi)):
    rho_hat - z * se, clipped to [0, 1], where rho_hat is the mean calibrated probability of
    n_queries Monte-Carlo poses (outside the modelled domain: failure; with the GP rho model
    capped at 1 - lapse) and se the standard error of the boundary's estimate.
    details=True returns (rho, rho_hat, se)."""
    check_sigma(sigma_r, sigma_phi)
    if n_queries < 1:
        raise ValueError(f"n_queries must be >= 1, got {n_queries}")
    if not 0.0 <= lapse < 1.0:
        raise ValueError(f"lapse must be in [0, 1), got {lapse!r}")
    sigma = domain.to_normalized(np.array([sigma_r, sigma_r, sigma_phi]))
    U = gaussian_queries(n_queries, seed) * sigma
    rho_hat, se = bm.rho(U, sigma, 1.0 - lapse)
    rho = float(np.clip(rho_hat - z * se, 0.0, 1.0))
    return (rho, rho_hat, se) if details else rho


@dataclass
class BuildConfig:
    sg_grid: tuple = (0.1, 0.2, 0.3, 0.4, 0.5, 0.7, 0.9, 1.2)  # to 1.2 m/s: Table IV at low uncertainty is not capped
    sc_grid: tuple = (0.05, 0.1, 0.15)
    levels: tuple = DEFAULT_LEVELS
    active: ActiveConfig = field(default_factory=ActiveConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    domain: PoseDomain = field(default_factory=PoseDomain)
    n_queries: int = 20000
    use_sc_monotonicity: Optional[bool] = None  # None: the part's closing_monotone
    conservative_z: float = 0.0  # rho = rho_hat - z * se (the surface is a lower bound anyway)
    # rho per boundary (``RhoModel``). Against 2,000 direct simulations per pair the GP is the
    # more accurate (bench/README.md).
    rho_model: RhoModel = RhoModel.gp
    # rho_model "gp": cap each pose's probability at 1 - the part's lapse rate, the failures
    # no pose explains (gpc.lapse_rate). Without it the cylinder's rho is 1.000 where 2,000
    # direct simulations give 0.973.
    lapse_ceiling: bool = True
    surface_degree: tuple = (3, 2)

    @classmethod
    def quick(cls) -> "BuildConfig":
        """A few minutes of CPU at most: 2 x 2 grid, small budgets."""
        return cls(
            sg_grid=(0.1, 0.5),
            sc_grid=(0.05, 0.15),
            active=ActiveConfig(n_init=16, n_holdout=16, batch_size=12, budget=80),
            n_queries=4000,
        )

    @classmethod
    def smoke(cls) -> "BuildConfig":
        """Tests: the smallest build that runs every step (2 x 2 grid, 30 simulations per boundary);
        its rho is rough."""
        return cls(
            sg_grid=(0.1, 0.5),
            sc_grid=(0.05, 0.15),
            n_queries=2000,
            active=ActiveConfig(n_init=12, n_holdout=12, batch_size=10, budget=30),
        )


class MetaModel:
    """The meta-model of one part and grasping strategy: GSBs on the speed grid, the
    probability grids and surfaces for the built sigma levels. Query with rho()."""

    def __init__(
        self,
        part_name,
        sg_grid,
        sc_grid,
        boundaries,
        levels,
        rho_grids,
        surfaces,
        domain=PoseDomain(),
        n_queries=20000,
        surface_degree=(3, 2),
        info=None,
        conservative_z=1.0,
        monotone_sc=True,
        lapse=0.0,
    ):
        self.part_name = part_name
        self.sg_grid = tuple(float(s) for s in sg_grid)
        self.sc_grid = tuple(float(s) for s in sc_grid)
        self.boundaries = boundaries  # {(i, j): BoundaryModel}
        self.levels = list(levels)
        self.rho_grids = dict(rho_grids)  # level name -> (n_g, n_c)
        self.surfaces = dict(surfaces)  # level name -> RhoSurface
        self.domain = domain
        self.n_queries = int(n_queries)
        self.surface_degree = tuple(surface_degree)
        self.info = dict(info or {})
        self.conservative_z = float(conservative_z)
        self.monotone_sc = bool(monotone_sc)  # the surfaces are non-decreasing in S_c
        self.lapse = float(lapse)  # rho caps each pose's probability at 1 - lapse (GP model)

    def level(self, sigma_r: float, sigma_phi: float):
        return next((lv for lv in self.levels if _same_sigma(lv, sigma_r, sigma_phi)), None)

    def surface(self, sigma_r: float, sigma_phi: float) -> RhoSurface:
        """The surface for this sigma; built (and cached) from the GSBs if new."""
        check_sigma(sigma_r, sigma_phi)
        lv = self.level(sigma_r, sigma_phi)
        if lv is None:
            lv = SigmaLevel(f"sigma_{sigma_r:g}_{sigma_phi:g}", float(sigma_r), float(sigma_phi))
            self.rho_grids[lv.name] = self.probability_grid(sigma_r, sigma_phi)
            self.surfaces[lv.name] = fit_rho_surface(
                self.sg_grid, self.sc_grid, self.rho_grids[lv.name], self.surface_degree, self.monotone_sc
            )
            self.levels.append(lv)
        return self.surfaces[lv.name]

    def probability_grid(self, sigma_r: float, sigma_phi: float) -> np.ndarray:
        """Monte-Carlo success probabilities on the speed grid (common random numbers)."""
        out = np.zeros((len(self.sg_grid), len(self.sc_grid)))
        for (i, j), bm in self.boundaries.items():
            out[i, j] = success_probability(
                bm, sigma_r, sigma_phi, self.domain, self.n_queries, z=self.conservative_z, lapse=self.lapse
            )
        return out

    def rho(self, s_g, s_c, sigma_r: float, sigma_phi: float):
        return self.surface(sigma_r, sigma_phi)(s_g, s_c)

    def rho_gradient(self, s_g, s_c, sigma_r: float, sigma_phi: float):
        return self.surface(sigma_r, sigma_phi).gradient(s_g, s_c)

    def to_dict(self) -> dict:
        return {
            "format": FORMAT,
            "version": VERSION,
            "part": self.part_name,
            "sg_grid": list(self.sg_grid),
            "sc_grid": list(self.sc_grid),
            "domain": asdict(self.domain),
            "n_queries": self.n_queries,
            "surface_degree": list(self.surface_degree),
            "info": self.info,
            "conservative_z": self.conservative_z,
            "surface_monotone_sc": self.monotone_sc,
            "lapse": self.lapse,
            "levels": [
                {
                    **asdict(lv),
                    "rho_grid": np.asarray(self.rho_grids[lv.name]).tolist(),
                    "surface": self.surfaces[lv.name].to_dict(),
                }
                for lv in self.levels
            ],
            "boundaries": [{"i": i, "j": j, **bm.to_dict()} for (i, j), bm in sorted(self.boundaries.items())],
        }

    @classmethod
    def from_dict(cls, d: dict) -> "MetaModel":
        _check_format(d)
        if d.get("version") not in READABLE_VERSIONS:
            raise ValueError(f"unsupported meta-model version {d.get('version')!r}")
        levels, grids, surfaces = [], {}, {}
        for stored, (lv, surface) in zip(d["levels"], _stored_levels(d)):
            levels.append(lv)
            grids[lv.name] = np.asarray(stored["rho_grid"], float)
            surfaces[lv.name] = surface
        bounds = {(b["i"], b["j"]): BoundaryModel.from_dict(b) for b in d["boundaries"]}
        return cls(
            d["part"],
            d["sg_grid"],
            d["sc_grid"],
            bounds,
            levels,
            grids,
            surfaces,
            PoseDomain(**d["domain"]),
            d["n_queries"],
            tuple(d["surface_degree"]),
            d.get("info"),
            d.get("conservative_z", 1.0),
            d.get("surface_monotone_sc", True),
            d.get("lapse", 0.0),
        )

    def save(self, path) -> None:
        """Write JSON atomically (pickplan.core.io: a temp file, then a rename)."""
        write_text(path, json.dumps(self.to_dict()))

    @classmethod
    def load(cls, path) -> "MetaModel":
        return cls.from_dict(read_metamodel_file(path))


def _same_sigma(level: SigmaLevel, sigma_r: float, sigma_phi: float) -> bool:
    return math.isclose(level.sigma_r, sigma_r, rel_tol=1e-9) and math.isclose(level.sigma_phi, sigma_phi, rel_tol=1e-9)


def _check_format(d) -> None:
    found = d.get("format") if isinstance(d, dict) else type(d).__name__
    if found != FORMAT:
        raise ValueError(f"not a pickplan meta-model (format={found!r})")


def _stored_levels(d: dict) -> list:
    """(SigmaLevel, RhoSurface) of every level a meta-model dict stores."""
    return [
        (SigmaLevel(lv["name"], lv["sigma_r"], lv["sigma_phi"]), RhoSurface.from_dict(lv["surface"]))
        for lv in d.get("levels", [])
    ]


def read_metamodel_file(path) -> dict:
    """The JSON of a meta-model file, checked to be one (the one reader of these files)."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"meta-model file not found: {path}")
    with open(path, "r", encoding="utf-8") as f:
        try:
            d = json.load(f)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{path}: not a pickplan meta-model (not JSON: {exc})") from None
    try:
        _check_format(d)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return d


def load_surface(path, sigma_r: float, sigma_phi: float) -> RhoSurface:
    """rho_sigma from a meta-model file: a level the file stores is read as it is (the boundaries
    are not refitted); another sigma is built from the file's boundaries."""
    d = read_metamodel_file(path)
    for level, surface in _stored_levels(d):
        if _same_sigma(level, sigma_r, sigma_phi):
            return surface
    return MetaModel.from_dict(d).surface(sigma_r, sigma_phi)
