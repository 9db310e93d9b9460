"""Batch simulation: many seeded grasp samples in worker processes (or on Ray).

Each sample carries its own seed, so a batch gives the same labels whatever the number of
workers or the chunking. Each simulation opens and closes its own PyBullet DIRECT client,
which is what makes worker processes safe.
"""
from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

from pickplan.pickup.metamodel.parts import get_part
from pickplan.pickup.metamodel.sim import SimConfig, check_speeds, simulate_grasp


def sample_seeds(seed: int, start: int, n: int) -> np.ndarray:
    """Per-sample seeds for samples start..start+n-1 of a stream identified by `seed`."""
    return np.array(
        [np.random.SeedSequence([int(seed), start + i]).generate_state(1)[0] for i in range(n)],
        dtype=np.uint64,
    )


class Progress:
    """A tiny progress bar on stderr (no tqdm dependency)."""

    def __init__(self, total: int, desc: str = "", enabled: bool = True, width: int = 30):
        self.total, self.desc, self.enabled, self.width = max(total, 1), desc, enabled, width
        self.count = 0
        self.t0 = time.perf_counter()
        self._last = -1.0

    def update(self, n: int = 1) -> None:
        self.count += n
        if not self.enabled:
            return
        now = time.perf_counter()
        if self.count < self.total and now - self._last < 0.25:  # throttle redraws
            return
        self._last = now
        frac = min(self.count / self.total, 1.0)
        bar = "#" * int(frac * self.width)
        rate = self.count / max(time.perf_counter() - self.t0, 1e-9)
        sys.stderr.write(f"\r{self.desc} [{bar:<{self.width}}] {self.count}/{self.total} "
                         f"{rate:.1f}/s")
        if self.count >= self.total:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _simulate_chunk(part_name, offsets, s_g, s_c, config, seeds):
    """Worker entry point: returns (successes, wall times) for one chunk."""
    ok, wall = [], []
    for off, sd in zip(offsets, seeds):
        out = simulate_grasp(part_name, off, s_g, s_c, config, seed=int(sd))
        ok.append(out.success)
        wall.append(out.wall_time)
    return ok, wall


class SimRunner:
    """Runs batches of simulations for one part. Use as a context manager so the worker
    pool (created once, reused across batches) is shut down.

    workers <= 1 runs in-process; use_ray=True sends chunks to Ray (ray is imported only
    then, and must be installed)."""

    def __init__(self, part, config: SimConfig = SimConfig(), workers: int = 1,
                 use_ray: bool = False, progress: bool = False, chunk_size: int = 4):
        self.part = get_part(part)
        self.config = config
        self.workers = max(int(workers), 1)
        self.use_ray = use_ray
        self.progress = progress
        self.chunk_size = max(int(chunk_size), 1)
        self.n_simulations = 0
        self.wall_times: list[float] = []
        self._pool = None
        self._ray_fn = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True)
            self._pool = None

    def _ensure_backend(self):
        if self.use_ray and self._ray_fn is None:
            import ray  # optional dependency

            if not ray.is_initialized():
                ray.init(ignore_reinit_error=True, log_to_driver=False)
            self._ray_fn = ray.remote(_simulate_chunk)
        elif not self.use_ray and self.workers > 1 and self._pool is None:
            # spawn: a clean interpreter per worker, no inherited PyBullet state.
            self._pool = ProcessPoolExecutor(self.workers, mp_context=get_context("spawn"))

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
        bar = Progress(n, desc or f"{self.part.name} S_g={s_g:.2f} S_c={s_c:.2f}", self.progress)
        name = self.part.name
        chunks = [(offsets[i:i + self.chunk_size], seeds[i:i + self.chunk_size])
                  for i in range(0, n, self.chunk_size)]
        results = []
        if self.workers <= 1 and not self.use_ray:
            for off, sd in chunks:
                results.append(_simulate_chunk(name, off, s_g, s_c, self.config, sd))
                bar.update(len(off))
        else:
            self._ensure_backend()
            if self.use_ray:
                import ray

                refs = [self._ray_fn.remote(name, off, s_g, s_c, self.config, sd)
                        for off, sd in chunks]
                for ref, (off, _) in zip(refs, chunks):
                    results.append(ray.get(ref))
                    bar.update(len(off))
            else:
                futs = [self._pool.submit(_simulate_chunk, name, off, s_g, s_c, self.config, sd)
                        for off, sd in chunks]
                for fut, (off, _) in zip(futs, chunks):
                    results.append(fut.result())
                    bar.update(len(off))
        ok = np.concatenate([np.asarray(r[0], dtype=bool) for r in results])
        for r in results:
            self.wall_times.extend(r[1])
        self.n_simulations += n
        return ok


def run_batch(part, offsets, s_g: float, s_c: float, config: SimConfig = SimConfig(),
              seed: int = 0, workers: int = 1, use_ray: bool = False,
              progress: bool = False) -> np.ndarray:
    """One-shot batch: simulate every offset (n, 3); sample i uses sample_seeds(seed, 0, n)[i]."""
    offsets = np.asarray(offsets, dtype=float)
    if offsets.ndim != 2 or offsets.shape[1] != 3:
        raise ValueError(f"expected offsets of shape (n, 3), got {offsets.shape}")
    seeds = sample_seeds(seed, 0, len(offsets))
    with SimRunner(part, config, workers, use_ray, progress) as runner:
        return runner.run(offsets, s_g, s_c, seeds)
