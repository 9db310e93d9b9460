"""Benchmark scene sets: ``n`` seeded scenes written to a folder (scene_XXXX.json plus index.json)."""

from __future__ import annotations

import os
import time
from typing import List, Optional, TextIO, Tuple

import numpy as np

from pickplan.core import objects as objects_mod
from pickplan.core.io import write_json
from pickplan.core.runner import progress_bar
from pickplan.sim.layouts import Layout, LayoutSettings, generate_layout
from pickplan.sim.scenes import SceneSettings, generate_scene


def scene_seeds(seed: int, n: int) -> List[int]:
    """Independent per-scene seeds derived from the set's seed (scene i is reproducible on its own)."""
    return [int(s) for s in np.random.SeedSequence(int(seed)).generate_state(n, dtype=np.uint32)]


def write_scene_set(
    n: int,
    seed: int,
    out: str,
    objects: Optional[str] = None,
    progress: Optional[bool] = True,
    stream: Optional[TextIO] = None,
    orientation: str = "upright",
    clutter: Tuple[int, int] = (SceneSettings.min_objects, SceneSettings.max_objects),
    robot: str = "panda",
    layout: Layout = Layout.table,
) -> dict:
    """Generate ``n`` scenes into ``out`` (scene_0000.json, ...) and return the index it writes.

    ``clutter`` = (fewest, most) objects per scene; ``robot``: the robot they are made for (SceneSettings.robot).
    ``layout``: the tabletop, or a shelf, bin or cabinet (``sim.layouts``; clutter and orientation are the
    tabletop's). The progress bar goes to ``stream`` (default: the current ``sys.stderr``); ``progress``
    None shows it only when that is a terminal, False never.
    """
    layout = Layout.parse(layout, "layout")
    if n < 1:
        raise ValueError(f"--n must be >= 1, got {n}")
    lib = objects_mod.library(objects)  # None: $PICKPLAN_YCB_DIR, else the built-ins
    settings = SceneSettings(
        orientation=orientation, min_objects=int(clutter[0]), max_objects=int(clutter[1]), robot=robot
    )
    os.makedirs(out, exist_ok=True)
    started = time.perf_counter()
    entries = []
    with progress_bar(n, "scenes", progress, stream, unit="scene") as bar:
        for i, s in enumerate(scene_seeds(seed, n)):
            t0 = time.perf_counter()
            scene = (
                generate_scene(s, lib, settings)
                if layout is Layout.table
                else generate_layout(layout, s, lib, LayoutSettings(robot=robot))
            )
            fname = f"scene_{i:04d}.json"
            scene.save(os.path.join(out, fname))
            entries.append(
                {
                    "file": fname,
                    "seed": s,
                    "target": scene.target,
                    "objects": [o.name for o in scene.objects],
                    "seconds": round(time.perf_counter() - t0, 4),
                }
            )
            bar.update()
    index = {
        "count": n,
        "seed": seed,
        "objects": lib.source,
        "orientation": orientation,
        "clutter": [settings.min_objects, settings.max_objects],
        "scenes": entries,
        **({} if robot == "panda" else {"robot": robot}),
        **({} if layout is Layout.table else {"layout": layout.value}),
        "seconds": round(time.perf_counter() - started, 3),
    }
    write_json(os.path.join(out, "index.json"), index)
    return index
