"""Batch simulation: many seeded grasp samples in worker processes (or on Ray).

Each sample carries its own seed, so a batch gives the same labels whatever the number of
workers or the chunking. Each simulation opens and closes its own PyBullet DIRECT client,
which is what makes worker processes safe.
"""

from __future__ import annotations

import numpy as np

from pickplan.core.runner import RAY_LOCAL, Runner
from pickplan.pickup.metamodel.parts import get_part
from pickplan.pickup.metamodel.sim import SimConfig, check_speeds, simulate_grasp


def sample_seeds(seed: int, start: int, n: int) -> np.ndarray:
    """Per-sample seeds for samples start..start+n-1 of a stream identified by `seed`."""
    return np.array(
        [np.random.SeedSequence([int(seed), start + i]).generate_state(1)[0] for i in range(n)], dtype=np.uint64
    )


def _simulate_one(job):
    """Worker entry point: (success, wall time) of one seeded simulation."""
    part, offset, s_g, s_c, config, seed = job  # the Part itself: a mesh part has no registry name
    out = simulate_grasp(part, offset, s_g, s_c, config, seed=int(seed))
    return out.success, out.wall_time


class SimRunner:
    """Runs batches of simulations for one part. Use as a context manager so the worker
    pool (created once, reused across batches) is shut down.

    workers <= 1 runs in-process; use_ray=True sends chunks to a local Ray (ray is imported
    only then, and must be installed)."""

    def __init__(
        self,
        part,
        config: SimConfig = SimConfig(),
        workers: int = 1,
        use_ray: bool = False,
        progress: bool = False,
        chunk_size: int = 4,
    ):
        self.part = get_part(part)
        self.config = config
        self.workers = max(int(workers), 1)
        self.use_ray = use_ray
        self.progress = progress
        self.chunk_size = max(int(chunk_size), 1)
        self.n_simulations = 0
        self.wall_times: list[float] = []
        self._runner = Runner(self.workers, RAY_LOCAL if use_ray else None)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        self._runner.close()

    def run(self, offsets, s_g: float, s_c: float, seeds, desc: str = "") -> np.ndarray:
        """Simulate each offset (n, 3) with its seed; returns a bool array of successes."""
        offsets = np.asarray(offsets, dtype=float)
        if offsets.ndim != 2 or offsets.shape[1] != 3:
            raise ValueError(f"expected offsets of shape (n, 3), got {offsets.shape}")
        seeds = np.asarray(seeds)
        if seeds.shape != (len(offsets),):
            raise ValueError(f"expected {len(offsets)} seeds, got shape {seeds.shape}")
        check_speeds(s_g, s_c, self.config)
        n = len(offsets)
        if n == 0:
            return np.zeros(0, dtype=bool)
        jobs = [(self.part, off, s_g, s_c, self.config, sd) for off, sd in zip(offsets, seeds)]
        results = [
            r
            for _, r in self._runner.map(
                _simulate_one,
                jobs,
                chunksize=self.chunk_size,
                progress=self.progress,
                label=desc or f"{self.part.name} S_g={s_g:.2f} S_c={s_c:.2f}",
            )
        ]
        self.wall_times.extend(wall for _, wall in results)
        self.n_simulations += n
        return np.array([ok for ok, _ in results], dtype=bool)


def run_batch(
    part,
    offsets,
    s_g: float,
    s_c: float,
    config: SimConfig = SimConfig(),
    seed: int = 0,
    workers: int = 1,
    use_ray: bool = False,
    progress: bool = False,
) -> np.ndarray:
    """One-shot batch: simulate every offset (n, 3); sample i uses sample_seeds(seed, 0, n)[i]."""
    offsets = np.asarray(offsets, dtype=float)
    if offsets.ndim != 2 or offsets.shape[1] != 3:
        raise ValueError(f"expected offsets of shape (n, 3), got {offsets.shape}")
    seeds = sample_seeds(seed, 0, len(offsets))
    with SimRunner(part, config, workers, use_ray, progress) as runner:
        return runner.run(offsets, s_g, s_c, seeds)
