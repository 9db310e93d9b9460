"""One way to run many independent jobs: in this process, over a local process pool, or on Ray.

``Runner.map(fn, jobs)`` calls the picklable, module-level ``fn`` on every job and yields
``(job, result)`` pairs, in job order or as they finish (for sweeps that save each result at once
and resume after an interrupt). Workers are started with ``spawn``: a clean interpreter each, no
inherited PyBullet clients or Ipopt state. A job that raises stops the map, or, with
``errors=OnError.RECORD``, comes back as a ``JobFailure`` so the caller can record it and go on;
interrupts (KeyboardInterrupt) always stop it. Progress goes through tqdm, with the time left.

>>> with Runner(workers=2) as runner:
...     sizes = [r for _, r in runner.map(abs, [-3, 1, -2])]   # [3, 1, 2]
"""

from __future__ import annotations

import contextlib
import enum
import logging
import sys
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass
from multiprocessing import get_context
from typing import Any, Callable, Iterable, Iterator, List, Optional, Sequence, TextIO, Tuple

from tqdm import tqdm

RAY_LOCAL = "local"  # the ``ray`` value that starts Ray on this machine instead of joining a cluster


class Order(enum.Enum):
    """The order ``Runner.map`` yields results in."""

    JOBS = "jobs"  # the order of the jobs given
    COMPLETION = "completion"  # as each finishes (save at once, resume later)


class OnError(enum.Enum):
    """What a job that raises does to the map."""

    RAISE = "raise"  # the exception stops the map (pending jobs are cancelled)
    RECORD = "record"  # the job's result is a JobFailure and the map goes on


@dataclass(frozen=True)
class JobFailure:
    """The result of a job that raised (with ``OnError.RECORD``): ``"TypeName: message"``."""

    error: str


def progress_bar(
    total: int,
    label: str = "",
    enabled: Optional[bool] = None,
    stream: Optional[TextIO] = None,
    done: int = 0,
    unit: str = "it",
    delay: float = 0.0,
) -> tqdm:
    """A tqdm bar on ``stream`` (default: the current stderr) with elapsed and remaining time.
    ``enabled``: True shows it, False hides it, None shows it only when the stream is a terminal and
    the ``pickplan`` logger is not set above INFO (``pickplan --quiet`` sets it to WARNING).
    ``delay``: seconds before it appears (work done sooner shows nothing)."""
    if enabled is None and logging.getLogger("pickplan").level > logging.INFO:
        enabled = False
    return tqdm(
        total=total,
        initial=done,
        desc=label,
        unit=unit,
        file=stream if stream is not None else sys.stderr,
        disable=None if enabled is None else not enabled,
        dynamic_ncols=True,
        mininterval=0.25,
        delay=delay,
    )


def _call(fn: Callable[[Any], Any], job: Any, errors: OnError) -> Any:
    if errors is OnError.RAISE:
        return fn(job)
    try:
        return fn(job)
    except Exception as exc:  # noqa: BLE001 - the caller asked for failures as data
        return JobFailure(f"{type(exc).__name__}: {exc}")


def _run_chunk(fn: Callable[[Any], Any], chunk: Sequence[Any], errors: OnError) -> List[Any]:
    """Worker entry point: one task runs a few jobs, which keeps the pickling overhead down."""
    return [_call(fn, job, errors) for job in chunk]


class Runner:
    """Runs jobs serially (``workers <= 1``), over ``workers`` spawned processes, or as Ray tasks
    (``ray`` = ``RAY_LOCAL`` or a cluster address). Use as a context manager: the pool (created
    on first need, reused across maps) is shut down and a Ray it started is stopped on exit."""

    def __init__(self, workers: int = 1, ray: Optional[str] = None):
        if int(workers) != workers:
            raise ValueError(f"workers: expected an integer, got {workers!r}")
        if ray is not None and (not isinstance(ray, str) or not ray):
            raise ValueError(f"ray: expected {RAY_LOCAL!r} or a cluster address, got {ray!r}")
        self.workers = int(workers)
        self.ray = ray
        self._pool: Optional[ProcessPoolExecutor] = None
        self._ray_started = False

    def __enter__(self) -> "Runner":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._ray_started:
            import ray

            ray.shutdown()
            self._ray_started = False

    def map(
        self,
        fn: Callable[[Any], Any],
        jobs: Iterable[Any],
        order: Order = Order.JOBS,
        errors: OnError = OnError.RAISE,
        chunksize: int = 1,
        progress: Optional[bool] = False,
        label: str = "",
        stream: Optional[TextIO] = None,
        done: int = 0,
        total: Optional[int] = None,
    ) -> Iterator[Tuple[Any, Any]]:
        """Yield ``(job, fn(job))`` for every job. ``chunksize`` jobs travel to a worker together
        (results do not depend on it). The bar counts jobs; ``done`` of ``total`` count as
        finished already (a resumed sweep)."""
        if not isinstance(order, Order) or not isinstance(errors, OnError):
            raise TypeError("order and errors must be pickplan.core.runner.Order and OnError members")
        if int(chunksize) < 1:
            raise ValueError(f"chunksize: expected >= 1, got {chunksize}")
        jobs = list(jobs)
        chunks = [jobs[i : i + int(chunksize)] for i in range(0, len(jobs), int(chunksize))]
        return self._map(
            fn,
            chunks,
            order,
            errors,
            progress_bar(len(jobs) + done if total is None else total, label, progress, stream, done),
        )

    def _map(self, fn, chunks: List[list], order: Order, errors: OnError, bar: tqdm) -> Iterator[Tuple[Any, Any]]:
        try:
            if not chunks:
                return
            if self.ray is not None:
                finished = self._ray_chunks(fn, chunks, errors, order)
            elif self.workers <= 1 or len(chunks) == 1:
                finished = ((chunk, _run_chunk(fn, chunk, errors)) for chunk in chunks)
            else:
                finished = self._pool_chunks(fn, chunks, errors, order)
            with contextlib.closing(finished):  # stopped early: pending jobs are cancelled now
                for chunk, results in finished:
                    for job, result in zip(chunk, results):
                        yield job, result
                    bar.update(len(chunk))
        finally:
            bar.close()

    def _pool_chunks(self, fn, chunks, errors: OnError, order: Order) -> Iterator[Tuple[list, list]]:
        if self._pool is None:
            self._pool = ProcessPoolExecutor(max_workers=self.workers, mp_context=get_context("spawn"))
        futures = [self._pool.submit(_run_chunk, fn, chunk, errors) for chunk in chunks]
        pending = dict(zip(futures, chunks))
        try:
            if order is Order.JOBS:
                for fut in futures:
                    yield pending.pop(fut), fut.result()
            rank = {fut: i for i, fut in enumerate(futures)}
            while pending:
                finished, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in sorted(finished, key=rank.get):  # finished together: in job order
                    yield pending.pop(fut), fut.result()
        finally:  # an error or an interrupt: drop what has not started
            for fut in pending:
                fut.cancel()

    def _ray_chunks(self, fn, chunks, errors: OnError, order: Order) -> Iterator[Tuple[list, list]]:
        try:
            import ray
        except ImportError as exc:
            raise ImportError("running on Ray needs Ray: pip install ray") from exc
        if not ray.is_initialized():
            if self.ray == RAY_LOCAL:  # Ray's default (every core) unless a worker count is given
                ray.init(
                    num_cpus=self.workers if self.workers > 1 else None, include_dashboard=False, log_to_driver=False
                )
            else:
                ray.init(address=self.ray, log_to_driver=False)
            self._ray_started = True
        # A task whose worker process dies (killed, out of memory) is re-run by Ray up to twice; the
        # caller sees only the retry's result (tests/python/test_sweep_faults.py kills one).
        remote = ray.remote(num_cpus=1, max_retries=2)(_run_chunk)
        refs = [remote.remote(fn, chunk, errors) for chunk in chunks]
        pending = dict(zip(refs, chunks))
        try:
            if order is Order.JOBS:
                for ref in refs:
                    yield pending.pop(ref), ray.get(ref)
            while pending:
                finished, _ = ray.wait(list(pending), num_returns=1)
                for ref in finished:
                    yield pending.pop(ref), ray.get(ref)
        finally:
            for ref in pending:
                ray.cancel(ref)


def run_jobs(
    fn: Callable[[Any], Any],
    jobs: Iterable[Any],
    workers: int = 1,
    ray: Optional[str] = None,
    errors: OnError = OnError.RAISE,
    chunksize: int = 1,
    progress: Optional[bool] = False,
    label: str = "",
) -> List[Any]:
    """``fn`` over ``jobs`` with a runner of its own; the results in job order."""
    with Runner(workers, ray) as runner:
        return [result for _, result in runner.map(fn, jobs, Order.JOBS, errors, chunksize, progress, label)]
