"""Many plans at once: scenes or targets planned in parallel threads. The native stages (goal set,
CHOMP steps, goal costs, ISF, the success test, the merged grid's bricks) release the GIL, so
threads run them on separate cores; worlds share one ``ModelCache``.

>>> results = plan_many([PlanJob(scene) for scene in scenes], OMGSettings(), workers=2)

Each result is what ``OMGPlanner(None, scene, settings).plan(...)`` returns for that job, in the
jobs' order, whatever the number of workers (every plan is deterministic for its seed).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import List, Optional, Sequence, Union

import numpy as np

from pickplan.omg.model_cache import ModelCache
from pickplan.omg.planner import OMGPlanner, OMGSettings, PlanResult
from pickplan.omg.world import World
from pickplan.sim.scenes import Scene


@dataclass(frozen=True)
class PlanJob:
    """One plan: a scene, and optionally its target, start, grasps and a world already built for it."""

    scene: Scene
    target: Optional[str] = None
    start: Optional[np.ndarray] = None
    grasps: Optional[Union[np.ndarray, str]] = None
    world: Optional[World] = None


def _check_workers(workers) -> int:
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"plan_many: workers must be an integer >= 1, got {workers!r}")
    return int(workers)


def plan_many(
    jobs: Sequence[Union[PlanJob, Scene]],
    settings: OMGSettings = OMGSettings(),
    workers: int = 2,
    cache: Optional[ModelCache] = None,
) -> List[PlanResult]:
    """Plan every job (a ``PlanJob`` or a bare ``Scene``) on ``workers`` threads; results in order.
    Worlds not given are built with ``cache`` (None: one cache shared by this call's worlds)."""
    workers = _check_workers(workers)
    jobs = [j if isinstance(j, PlanJob) else PlanJob(j) for j in jobs]
    for i, job in enumerate(jobs):
        if not isinstance(job.scene, Scene):
            raise ValueError(f"plan_many: job {i}: expected a Scene, got {type(job.scene).__name__}")
    cache = ModelCache() if cache is None else cache

    def run(job: PlanJob) -> PlanResult:
        world = job.world
        if world is None:
            target = job.target or job.scene.target
            world = World(
                job.scene if target == job.scene.target else _retarget(job.scene, target), settings.world, cache=cache
            )
        return OMGPlanner(None, job.scene, settings, world=world).plan(job.start, job.target, job.grasps)

    if workers == 1 or len(jobs) <= 1:
        return [run(j) for j in jobs]
    with ThreadPoolExecutor(max_workers=min(workers, len(jobs)), thread_name_prefix="plan_many") as pool:
        return list(pool.map(run, jobs))


def _retarget(scene: Scene, target: str) -> Scene:
    scene.object(target)  # a clear KeyError for an unknown target
    return replace(scene, target=target)
