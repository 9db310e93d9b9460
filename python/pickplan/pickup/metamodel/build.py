"""Building a meta-model (paper Sec. III): a grasp-success boundary learnt by active learning on every
(S_g, S_c) of the grid from simulated pick-ups, then the rho surfaces of the asked uncertainty levels."""

from __future__ import annotations

import logging
from dataclasses import asdict, replace

import numpy as np

from pickplan.pickup.metamodel.active import PoseDomain, RhoModel, known_from_lower_sc, learn_boundary
from pickplan.pickup.metamodel.gpc import lapse_rate
from pickplan.pickup.metamodel.model import BoundaryModel, BuildConfig, MetaModel
from pickplan.pickup.metamodel.parallel import SimRunner, sample_seeds
from pickplan.pickup.metamodel.parts import get_part
from pickplan.pickup.metamodel.surface import fit_rho_surface

log = logging.getLogger(__name__)


def build_metamodel(
    part,
    config: BuildConfig = BuildConfig(),
    seed: int = 0,
    workers: int = 1,
    use_ray: bool = False,
    progress: bool = False,
    label_fn_factory=None,
) -> MetaModel:
    """Learn a GSB for every (S_g, S_c) on the grid and the surfaces for config.levels.

    S_c is processed in ascending order for each S_g so that, where success is monotone in S_c
    (config.use_sc_monotonicity, by default the part's closing_monotone), poses deep in the
    previous (lower S_c) success region are labelled success for free.
    label_fn_factory(s_g, s_c, seed) -> label_fn replaces the simulation (tests)."""
    part = get_part(part)
    sc_monotone = part.closing_monotone if config.use_sc_monotonicity is None else config.use_sc_monotonicity
    sg_grid = sorted(float(s) for s in config.sg_grid)
    sc_grid = sorted(float(s) for s in config.sc_grid)
    boundaries = {}
    # The learner's stopping rule watches rho at the levels being built.
    active = replace(
        config.active,
        query_sigmas=tuple(
            tuple(float(v) for v in config.domain.to_normalized([lv.sigma_r, lv.sigma_r, lv.sigma_phi]))
            for lv in config.levels
        ),
    )
    with SimRunner(part, config.sim, workers, use_ray, progress=False) as runner:
        for i, s_g in enumerate(sg_grid):
            prev = None
            for j, s_c in enumerate(sc_grid):
                pair_seed = int(np.random.SeedSequence([seed, i, j]).generate_state(1)[0])
                if label_fn_factory is not None:
                    label_fn = label_fn_factory(s_g, s_c, pair_seed)
                else:
                    label_fn = _sim_label_fn(runner, config.domain, s_g, s_c, pair_seed)
                known = None
                if sc_monotone and prev is not None:
                    known = known_from_lower_sc(prev.model, config.active.known_margin)
                res = learn_boundary(label_fn, active, seed=pair_seed, known_fn=known)
                bm = BoundaryModel(
                    s_g,
                    s_c,
                    res.X,
                    res.y,
                    res.simulated,
                    res.svm_c,
                    res.svm_gamma,
                    history=res.history,
                    converged=res.converged,
                    calib_folds=config.active.calib_folds,
                    calib_seed=pair_seed,
                    svm_metric=res.svm_metric,
                    local_kappa=config.active.local_kappa,
                    local_floor=config.active.local_floor,
                    rho_model=config.rho_model,
                )
                boundaries[(i, j)] = bm
                prev = bm
                if progress:
                    log.info(
                        f"{part.name}: S_g={s_g:.2f} S_c={s_c:.2f} {bm.n_simulations} sims, "
                        f"{res.n_free} free, D_FT={bm.d_ft:.3f}, converged={res.converged}"
                    )
    mm = MetaModel(
        part.name,
        sg_grid,
        sc_grid,
        boundaries,
        [],
        {},
        {},
        config.domain,
        config.n_queries,
        config.surface_degree,
        conservative_z=config.conservative_z,
        monotone_sc=sc_monotone,
        info={
            "seed": seed,
            "sim": asdict(config.sim),
            "active": asdict(config.active),
            "use_sc_monotonicity": sc_monotone,
            "rho_model": config.rho_model,
            "lapse_ceiling": config.lapse_ceiling,
        },
    )
    if RhoModel.parse(config.rho_model, "rho_model") is RhoModel.gp and config.lapse_ceiling:
        mm.lapse = lapse_rate((bm.gp, bm.simulated) for bm in boundaries.values())
    for lv in config.levels:
        mm.rho_grids[lv.name] = mm.probability_grid(lv.sigma_r, lv.sigma_phi)
        mm.surfaces[lv.name] = fit_rho_surface(
            sg_grid, sc_grid, mm.rho_grids[lv.name], config.surface_degree, sc_monotone
        )
        mm.levels.append(lv)
    return mm


def _sim_label_fn(runner: SimRunner, domain: PoseDomain, s_g: float, s_c: float, seed: int):
    count = [0]

    def label(U):
        seeds = sample_seeds(seed, count[0], len(U))
        count[0] += len(U)
        return runner.run(domain.to_offsets(U), s_g, s_c, seeds)

    return label
