"""The OMG paper's "Simulated" grasp set (after Eppner et al. [12]): antipodal candidates that hold in
``physics.shake_test``, cached on disk by the hash of everything they depend on
(``$PICKPLAN_CACHE_DIR/grasps``) and shipped with pickplan for the built-in objects (``omg.shipped``,
read through ``core.io.cache_entry``, checked by SHA-256)."""

from __future__ import annotations

import hashlib
import json
import logging
import math
import warnings
from dataclasses import asdict
from typing import Optional

import numpy as np

from pickplan.core import io
from pickplan.core.description import RobotInfo
from pickplan.core.io import atomic_open
from pickplan.core.panda import PANDA
from pickplan.core.runner import Runner
from pickplan.omg.grasps.generators import AntipodalSettings
from pickplan.omg.grasps.physics import SimObject, SimSettings, _chunksize, _shake_job, shake_candidates
from pickplan.omg.grasps.sets import GraspSet, _check_count

log = logging.getLogger(__name__)
CACHE_VERSION = 2  # 2: the shake test's turns and rotation check; coupled fingers


CACHE_FOLDER = "grasps"


def _request(n, seed, settings, antipodal, oversample, max_rounds) -> dict:
    return {
        "sim": asdict(settings),
        "antipodal": asdict(antipodal),
        "n": int(n),
        "seed": int(seed),
        "oversample": float(oversample),
        "rounds": int(max_rounds),
    }


def cache_name(
    model,
    n,
    seed,
    settings=SimSettings(),
    antipodal=AntipodalSettings(),
    oversample=3.0,
    max_rounds=4,
    gripper: RobotInfo = PANDA,
) -> str:
    """The entry's file name in the cache's ``grasps`` folder (and in the shipped one): the hash of
    everything the set depends on, the generator's version (``CACHE_VERSION``) and the object's mesh,
    collision parts and mass included."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(model.mesh.vertices, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(model.mesh.faces, dtype=np.int64).tobytes())
    with open(model.collision_obj_path(), "rb") as f:
        h.update(f.read())
    request = _request(n, seed, settings, antipodal, oversample, max_rounds)
    h.update(json.dumps({"v": CACHE_VERSION, "mass": float(model.mass), **request}, sort_keys=True).encode())
    if gripper.key != PANDA.key:  # the Panda's entries keep their names
        h.update(repr(gripper.key).encode())
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in model.name)
    return f"{safe}-simulated-{h.hexdigest()[:24]}.npz"


def entry_label(
    model,
    n,
    seed,
    settings=SimSettings(),
    antipodal=AntipodalSettings(),
    oversample=3.0,
    max_rounds=4,
    gripper: RobotInfo = PANDA,
) -> str:
    """What an entry is of (``io.cache_entry``'s label): the object's name, the gripper and the request
    (count, seed, settings), not the generator's version or the object's geometry; a shipped entry of
    the same label under another name was made by another version."""
    request = json.dumps(_request(n, seed, settings, antipodal, oversample, max_rounds), sort_keys=True)
    return f"{model.name} / {gripper.name} / {hashlib.sha256(request.encode()).hexdigest()[:12]}"


def read_grasp_file(path: str, object_name: str) -> GraspSet:
    with np.load(path) as z:
        info = {k[5:]: z[k] for k in z.files if k.startswith("info_")}
        return GraspSet("simulated", z["poses"], object_name, scores=z["scores"], info=info)


def write_grasp_file(path: str, gs: GraspSet) -> None:
    with atomic_open(path, "wb") as f:
        np.savez_compressed(f, poses=gs.poses, scores=gs.scores, **{f"info_{k}": v for k, v in gs.info.items()})


def simulated_grasps(
    model,
    n: int = 100,
    seed: int = 0,
    workers: int = 1,
    settings: SimSettings = SimSettings(),
    antipodal: AntipodalSettings = AntipodalSettings(),
    oversample: float = 3.0,
    max_rounds: int = 4,
    progress: Optional[bool] = None,
    cache: bool = True,
    gripper: RobotInfo = PANDA,
) -> GraspSet:
    """The "Simulated" set: antipodal candidates (``ceil(n * oversample)`` per round, seeded per
    round) that hold in the shake test, first ``n`` in candidate order; fewer (with a warning)
    when ``max_rounds`` rounds do not give ``n``. ``workers`` > 1 runs worker processes (spawn);
    the result does not depend on it. ``scores`` = 1 - drift / max_drift; ``info`` carries the
    antipodal contacts, normals, widths and drifts, plus "tested" (candidates simulated, 0-d).
    Cached in ``$PICKPLAN_CACHE_DIR/grasps`` (default ``~/.cache/pickplan/grasps``). Poses of
    ``gripper``'s hand link, simulated with that gripper."""
    _check_count(n, seed)
    if int(workers) < 1:
        raise ValueError(f"workers: expected >= 1, got {workers}")
    request = (model, n, seed, settings, antipodal, oversample, max_rounds, gripper)
    name = cache_name(*request) if cache else None
    found = io.cache_entry(CACHE_FOLDER, name, label=entry_label(*request)) if name else None
    if found:
        return read_grasp_file(found, model.name)
    m = int(math.ceil(n * oversample))
    log.info(
        f"{model.name}: simulating grasps on first use (up to {max_rounds} rounds of {m} shake tests, "
        f"{'cached after' if cache else 'not cached'})"
    )
    obj = SimObject(model)
    keep = {k: [] for k in ("poses", "scores", "contacts", "normals", "width", "drift")}
    tested = 0
    with Runner(int(workers)) as runner:  # one pool for every round
        for rnd in range(max_rounds):
            cand, seeds = shake_candidates(model, m, seed, rnd, antipodal, gripper)
            if len(cand) == 0:
                break
            jobs = [(obj, T, sd, settings, gripper) for T, sd in zip(cand.poses, seeds)]
            results = [
                r
                for _, r in runner.map(
                    _shake_job,
                    jobs,
                    chunksize=_chunksize(len(jobs), workers),
                    progress=progress,
                    label=f"{model.name} shake round {rnd + 1}",
                )
            ]
            tested += len(cand)
            for i, r in enumerate(results):
                if r["held"]:
                    keep["poses"].append(cand.poses[i])
                    keep["scores"].append(1.0 - r["drift"] / settings.max_drift)
                    for k in ("contacts", "normals", "width"):
                        keep[k].append(cand.info[k][i])
                    keep["drift"].append(r["drift"])
            if len(keep["poses"]) >= n:
                break
    got = min(n, len(keep["poses"]))
    if got < n:
        warnings.warn(f"{model.name}: only {got} of {n} simulated grasps held ({tested} tested)", stacklevel=2)
    arr = {k: np.asarray(v[:got], dtype=float) for k, v in keep.items()}
    if got == 0:
        arr["poses"] = np.zeros((0, 4, 4))
    info = {k: arr[k] for k in ("contacts", "normals", "width", "drift")}
    info["tested"] = np.asarray(tested)
    gs = GraspSet("simulated", arr["poses"], model.name, scores=arr["scores"], info=info)
    if name:
        write_grasp_file(io.cache_dir(CACHE_FOLDER, name), gs)
    return gs
