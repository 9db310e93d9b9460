"""Meta-model vs extensive sampling (Fig. 3 of Thakar et al.).

For each sigma level and (S_g, S_c) pair, `n_samples` poses from N(0, sigma) are simulated
directly (the paper: ~2000 per pair) and the success fraction is compared with the
active-learning probability on the grid and with the fitted surface rho_sigma.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
from dataclasses import asdict, dataclass

import numpy as np

from pickplan.core.io import atomic_open, write_text
from pickplan.pickup.metamodel.model import MetaModel, check_sigma
from pickplan.pickup.metamodel.parallel import SimRunner, sample_seeds
from pickplan.pickup.metamodel.sim import SimConfig


@dataclass(frozen=True)
class ComparisonRow:
    level: str
    sigma_r: float
    sigma_phi: float
    s_g: float
    s_c: float
    rho_extensive: float
    stderr_extensive: float
    n_extensive: int
    rho_active: float  # the meta-model's Monte-Carlo probability on the grid
    rho_surface: float  # the fitted conservative surface

    @property
    def error_active(self) -> float:
        return self.rho_active - self.rho_extensive

    @property
    def error_surface(self) -> float:
        return self.rho_surface - self.rho_extensive


def extensive_sampling(
    runner: SimRunner,
    s_g: float,
    s_c: float,
    sigma_r: float,
    sigma_phi: float,
    n_samples: int,
    seed: int = 0,
    cache_dir=None,
):
    """Direct simulation of n_samples poses ~ N(0, sigma): (probability, standard error).

    With cache_dir, the labels are stored in <cache_dir>/<key>.json, the key hashing every
    input that changes them (part, simulation settings, speeds, sigma, n, seed), so a rerun
    costs nothing. The standard error is the binomial sqrt(p (1 - p) / n)."""
    check_sigma(sigma_r, sigma_phi)
    if n_samples < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples}")
    path = None
    if cache_dir is not None:
        path = reference_cache_path(
            cache_dir, runner.part.name, runner.config, s_g, s_c, sigma_r, sigma_phi, n_samples, seed
        )
        ok = load_cached_labels(path)
        if ok is not None:
            return _binomial(ok)
    z = np.random.default_rng(seed).standard_normal((n_samples, 3))
    offsets = z * np.array([sigma_r, sigma_r, sigma_phi])
    ok = runner.run(offsets, s_g, s_c, sample_seeds(seed, 0, n_samples))
    if path is not None:
        write_text(path, json.dumps({"labels": ok.astype(int).tolist()}))
    return _binomial(ok)


def reference_cache_path(
    cache_dir, part_name: str, sim_config: SimConfig, s_g, s_c, sigma_r, sigma_phi, n_samples: int, seed: int
) -> str:
    """Cache file of one extensive-sampling run: the key hashes every input that changes
    the labels."""
    key = json.dumps(
        {
            "part": part_name,
            "sim": asdict(sim_config),
            "s_g": float(s_g),
            "s_c": float(s_c),
            "sigma_r": float(sigma_r),
            "sigma_phi": float(sigma_phi),
            "n": int(n_samples),
            "seed": int(seed),
        },
        sort_keys=True,
    )
    digest = hashlib.sha256(key.encode()).hexdigest()[:24]
    return os.path.join(os.fspath(cache_dir), f"ext_{part_name}_{digest}.json")


def load_cached_labels(path):
    """The cached labels (bool array), or None when the file does not exist."""
    if not os.path.exists(path):
        return None
    with open(path, encoding="utf-8") as f:
        return np.asarray(json.load(f)["labels"], bool)


def reference_seed(seed: int, s_g: float, s_c: float, sigma_r: float, sigma_phi: float) -> int:
    """Seed of the extensive-sampling stream for one (S_g, S_c, sigma)."""
    vals = [int(seed)] + [int(round(v * 1e6)) for v in (s_g, s_c, sigma_r, sigma_phi)]
    return int(np.random.SeedSequence(vals).generate_state(1)[0])


def _binomial(ok) -> tuple:
    p = float(np.mean(ok))
    return p, float(np.sqrt(max(p * (1 - p), 1e-12) / len(ok)))


def compare(
    model: MetaModel,
    n_samples: int = 2000,
    pairs=None,
    seed: int = 0,
    workers: int = 1,
    use_ray: bool = False,
    progress: bool = False,
    sim_config: SimConfig | None = None,
    cache_dir=None,
) -> list:
    """Rows for every level of the model and every grid pair (or `pairs`, a list of
    (S_g, S_c) grid points). The extensive-sampling seed depends on the speeds and sigma
    values (reference_seed), not on grid indices, so cached references are reused across
    grids."""
    if sim_config is None:
        sim_config = SimConfig(
            **{k: tuple(v) if isinstance(v, list) else v for k, v in model.info.get("sim", {}).items()}
        )
    grid = [(i, j) for i in range(len(model.sg_grid)) for j in range(len(model.sc_grid))]
    if pairs is not None:
        wanted = {(round(float(a), 9), round(float(b), 9)) for a, b in pairs}
        grid = [(i, j) for i, j in grid if (round(model.sg_grid[i], 9), round(model.sc_grid[j], 9)) in wanted]
        if not grid:
            raise ValueError(f"none of the pairs {sorted(wanted)} is on the model's grid")
    rows = []
    with SimRunner(model.part_name, sim_config, workers, use_ray, progress) as runner:
        for lv in model.levels:
            surf = model.surfaces[lv.name]
            for i, j in grid:
                s_g, s_c = model.sg_grid[i], model.sc_grid[j]
                p, se = extensive_sampling(
                    runner,
                    s_g,
                    s_c,
                    lv.sigma_r,
                    lv.sigma_phi,
                    n_samples,
                    reference_seed(seed, s_g, s_c, lv.sigma_r, lv.sigma_phi),
                    cache_dir,
                )
                rows.append(
                    ComparisonRow(
                        lv.name,
                        lv.sigma_r,
                        lv.sigma_phi,
                        s_g,
                        s_c,
                        p,
                        se,
                        n_samples,
                        float(model.rho_grids[lv.name][i, j]),
                        float(surf(s_g, s_c)),
                    )
                )
    return rows


def summarize(rows) -> dict:
    """Per level: mean |error|, worst under- and over-estimate of the grid and surface
    values, pairs within 5 %, and the pairs whose grid value is above the reference by more
    than 1 % + 2 reference standard errors (an over-estimate the reference's own binomial
    noise cannot explain)."""
    out = {}
    for lv in dict.fromkeys(r.level for r in rows):
        rs = [r for r in rows if r.level == lv]
        ea = np.array([r.error_active for r in rs])
        es = np.array([r.error_surface for r in rs])
        out[lv] = {
            "pairs": len(rs),
            "mean_abs_error_active": float(np.abs(ea).mean()),
            "max_abs_error_active": float(np.abs(ea).max()),
            "max_over_active": float(ea.max()),
            "max_under_active": float(ea.min()),
            "within_5pct_active": int(np.sum(np.abs(ea) <= 0.05)),
            "over_significant_active": int(sum(r.error_active > 0.01 + 2 * r.stderr_extensive for r in rs)),
            "mean_abs_error_surface": float(np.abs(es).mean()),
            "max_abs_error_surface": float(np.abs(es).max()),
            "max_over_surface": float(es.max()),
        }
    return out


def table_markdown(rows, part: str = "") -> str:
    lines = [
        f"Meta-model vs extensive sampling{' (' + part + ')' if part else ''}",
        "",
        "| level | sigma_r [mm] | sigma_phi [deg] | S_g | S_c | extensive (+-se) | "
        "active | surface | active - ext | surface - ext |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r.level} | {r.sigma_r * 1000:.0f} | {np.degrees(r.sigma_phi):.0f} | "
            f"{r.s_g:.2f} | {r.s_c:.2f} | {r.rho_extensive:.3f} "
            f"(+-{r.stderr_extensive:.3f}) | {r.rho_active:.3f} | "
            f"{r.rho_surface:.3f} | {r.error_active:+.3f} | {r.error_surface:+.3f} |"
        )
    return "\n".join(lines) + "\n"


def table_csv(rows) -> str:
    buf = io.StringIO()
    names = list(asdict(rows[0]).keys()) + ["error_active", "error_surface"] if rows else []
    w = csv.writer(buf)
    w.writerow(names)
    for r in rows:
        w.writerow(list(asdict(r).values()) + [r.error_active, r.error_surface])
    return buf.getvalue()


def write_results(rows, out_dir, part: str, reference_seed: int = 0) -> dict:
    """Write <part>_comparison.{md,csv,json} atomically; returns the paths."""
    import os

    base = os.path.join(os.fspath(out_dir), f"{part}_comparison")
    write_text(base + ".md", table_markdown(rows, part))
    write_text(base + ".csv", table_csv(rows))
    write_text(
        base + ".json",
        json.dumps(
            {
                "part": part,
                "reference_seed": int(reference_seed),
                "rows": [asdict(r) for r in rows],
                "summary": summarize(rows),
            },
            indent=1,
        ),
    )
    return {"md": base + ".md", "csv": base + ".csv", "json": base + ".json"}


def plot_comparison(rows, path, title: str = "") -> str:
    """Fig. 3-like 3-D bars, one panel per sigma level: light = extensive sampling,
    dark = active learning (grid); written atomically as PNG. Needs matplotlib."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = list(dict.fromkeys(r.level for r in rows))
    fig = plt.figure(figsize=(5.0 * len(levels), 4.5))
    for k, lv in enumerate(levels):
        rs = [r for r in rows if r.level == lv]
        ax = fig.add_subplot(1, len(levels), k + 1, projection="3d")
        sg = np.array([r.s_g for r in rs])
        sc = np.array([r.s_c for r in rs])
        dg = 0.3 * (np.ptp(sg) / max(len(set(sg)) - 1, 1) or 0.05)
        dc = 0.3 * (np.ptp(sc) / max(len(set(sc)) - 1, 1) or 0.02)
        z = np.zeros(len(rs))
        ax.bar3d(
            sg - dg,
            sc,
            z,
            dg,
            dc,
            [r.rho_extensive for r in rs],
            color="#9be29b",
            shade=True,
            label="extensive sampling",
        )
        ax.bar3d(sg, sc, z, dg, dc, [r.rho_active for r in rs], color="#1b7f1b", shade=True, label="active learning")
        ax.set_xlabel("S_g [m/s]")
        ax.set_ylabel("S_c [m/s]")
        ax.set_zlabel("P(success)")
        ax.set_zlim(0, 1)
        ax.set_title(
            f"{lv}: sigma_r={rs[0].sigma_r * 1000:.0f} mm, sigma_phi={np.degrees(rs[0].sigma_phi):.0f} deg", fontsize=9
        )
    if title:
        fig.suptitle(title)
    path = os.fspath(path)
    try:
        with atomic_open(path, "wb") as f:
            fig.savefig(f, format="png", dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)
    return path
